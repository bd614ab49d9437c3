"""Transfer-matrix engine: :class:`tmm_core.TimeDomain` behind the engine protocol.

The transfer-matrix model is kinematically driven (the crank is clamped at its pivot in the
instantaneous structure), so it accepts a prescribed crank motion and returns the drive torque;
a motor couples to it by supplying the crank motion. When the crank turns at the scenario's
constant speed and the step divides a revolution, one revolution of factorized configurations
is prepared at reset and re-used (the fast path); any other motion is factorized step by step.
"""
from __future__ import annotations

import math

import numpy as np

from tmm_core import TimeDomain

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in


class TMMEngine:
    name = "tmm"

    def __init__(self):
        self._dt = None

    @property
    def internal_step_s(self) -> float:
        if self._dt is None:
            raise EngineError("tmm: reset() the engine before asking for its step")
        return self._dt

    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float) -> None:
        s = scenario.tmm
        self.scenario = scenario
        self.td = TimeDomain(scenario.mechanism, integrator=s.integrator, coupling=s.coupling,
                             beam_column=s.beam_column, gravity=scenario.gravity, gauges=scenario.gauges,
                             axial_force=s.axial_force)
        ref_speed = scenario.drive.speed_rad_s or speed
        if s.step_s is not None:
            self._dt = s.step_s
        elif ref_speed:
            self._dt = s.step_rad / abs(ref_speed)
        else:
            raise EngineError("tmm: a crank-angle step needs a non-zero drive speed; give solver.tmm.step in s")
        self.t0, self.k = t0, 0
        self.march = self.td.begin(self._dt, angle, speed, 0.0, start=s.start)
        self.cache = None
        N = 2 * math.pi / (abs(ref_speed) * self._dt) if ref_speed else 0.0
        if ref_speed and abs(N - round(N)) < 1e-6 and round(N) >= 4:
            N = int(round(N))
            j = np.arange(N)
            angles = angle + ref_speed * self._dt * j
            self.cache = (N, ref_speed, angles, self.td._configurations(angles, np.full(N, ref_speed), np.zeros(N),
                                                                         self._dt))
        self.links = self.td.links
        self._frames = {}     # id(configuration batch) -> per link (rigid node positions, cos, sin)

    def _frame(self, cfg):
        """Rigid node positions and link orientation of every configuration of a batch."""
        key = id(cfg)
        if key not in self._frames:
            if len(self._frames) > 4:
                self._frames.clear()
            out = {}
            for link in self.links:
                lm = cfg["motion"].link(link.name)
                out[link.name] = (lm.point(link.stations)[0], np.cos(lm.angle), np.sin(lm.angle))
            self._frames[key] = (cfg, out)
        return self._frames[key][1]

    def _config(self, angle, speed, accel):
        """(configuration batch, index) for the next step: the cached revolution if it applies."""
        if self.cache is not None:
            N, w, angles, cfg = self.cache
            idx = (self.k + 1) % N
            d = (angle - angles[idx] + math.pi) % (2 * math.pi) - math.pi
            if abs(d) < 1e-9 and speed == w and accel == 0.0:
                return cfg, idx
        cfg = self.td._configurations(np.array([angle]), np.array([speed]), np.array([accel]), self._dt, maps=False)
        return cfg, 0

    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput:
        if drive.prescribed is None:
            raise EngineError("tmm: the transfer-matrix model is kinematically driven (crank clamped at its pivot); "
                              "couple it to a motor that supplies the crank motion, not a torque")
        t_start = self.t0 + self.k * self._dt
        n = steps_in(t_start, t_next, self._dt, "tmm")
        ks = self.k + 1 + np.arange(n)
        t = self.t0 + ks * self._dt          # integer step count, never accumulated
        angle, speed, accel = (np.asarray(x, dtype=float) for x in drive.prescribed(t))
        outs, zs, frames = [], [], {l.name: ([], [], []) for l in self.links}
        for i in range(n):
            cfg, idx = self._config(float(angle[i]), float(speed[i]), float(accel[i]))
            self.k += 1
            z, out = self.march.step_with(cfg, idx)
            outs.append(out)
            zs.append(z)
            for name, (rigid, c, s) in self._frame(cfg).items():
                frames[name][0].append(rigid[idx])
                frames[name][1].append(c[idx])
                frames[name][2].append(s[idx])
        outs = np.array(outs)
        local = self.td.unstack(np.array(zs))
        nodes = {}
        for name, (rigid, c, s) in frames.items():
            c, s = np.array(c)[:, None], np.array(s)[:, None]
            u, w = local[name][..., 0], local[name][..., 1]
            nodes[name] = np.array(rigid) + np.stack([c * u - s * w, s * u + c * w], -1)
        if not np.all(np.isfinite(outs)):
            raise EngineError(f"tmm: non-finite response before t = {t_next:.6g} s")
        gauges = {g.name: (outs[:, 1 + 2 * i], outs[:, 2 + 2 * i]) for i, g in enumerate(self.td.gauges)}
        return EngineOutput(t, angle, speed, outs[:, 0], gauges, nodes)
