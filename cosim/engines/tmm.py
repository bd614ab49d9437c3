"""Transfer-matrix engine: :class:`tmm_core.TimeDomain` behind the engine protocol.

The transfer-matrix model is kinematically driven (the crank is clamped at its pivot in the
instantaneous structure), so it accepts a prescribed crank motion and returns the drive torque;
a motor couples to it by supplying the crank motion. When the crank turns at the scenario's
constant speed and the step divides a revolution, one revolution of factorized configurations
is prepared at reset and re-used (the fast path); any other motion is factorized step by step.

Owns: the transfer-matrix engine behind the protocol. Boundaries: no time step of its own: it
calls tmm_core's public step API.
"""
from __future__ import annotations

import math

import numpy as np


from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in


class TMMEngine:
    name = "tmm"
    kinematic = True      # takes a crank motion, returns the drive torque

    def __init__(self):
        self._dt = None

    @property
    def internal_step_s(self) -> float:
        if self._dt is None:
            raise EngineError("tmm: reset() the engine before asking for its step")
        return self._dt

    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float, drive_inertia_kg_m2: float = 0.0) -> None:
        """Start at crank ``angle`` [rad] and ``speed`` [rad/s] at ``t0`` [s]. The drive's inertia
        stays with the motor (the crank motion is prescribed), so ``drive_inertia_kg_m2`` is unused."""
        s = scenario.tmm
        if s.model == "reduced":
            # The reduced model (tmm_core.reduced) solves the periodic steady state; it has no
            # incremental march behind this protocol (motor drives, co-simulation, node output).
            raise EngineError("tmm: solver.tmm.model = \"reduced\" is for periodic solves (cosim sweep, uncertainty, "
                              "identify); a time-marching run needs model = \"full\" (or drop the key)")
        self.scenario = scenario
        self.td = scenario.time_domain()
        ref_speed = scenario.drive.speed_rad_s or speed
        if s.step_s is not None:
            self._dt = s.step_s
        elif ref_speed:
            self._dt = s.step_rad / abs(ref_speed)
        else:
            raise EngineError("tmm: a crank-angle step needs a non-zero drive speed; give solver.tmm.step in s")
        self.t0, self.k = t0, 0
        self._angle0, self._speed0 = angle, speed
        self.march = self.td.begin(self._dt, angle, speed, 0.0, start=s.start)
        self.cache = None
        N = 2 * math.pi / (abs(ref_speed) * self._dt) if ref_speed else 0.0
        if ref_speed and abs(N - round(N)) < 1e-6 and round(N) >= 4:
            N = int(round(N))
            j = np.arange(N)
            angles = angle + ref_speed * self._dt * j
            self.cache = (N, ref_speed, angles, self.td.configurations(angles, np.full(N, ref_speed), np.zeros(N),
                                                                         self._dt))
        self.links = self.td.links                          # elastic links (their DOFs)
        self.drawn = scenario.mechanism.links()             # every link, rigid ones too
        self._frames = {}     # id(configuration batch) -> per link (rigid node positions, cos, sin)

    def _frame(self, cfg):
        """Rigid node positions and link orientation of every configuration of a batch."""
        key = id(cfg)
        if key not in self._frames:
            if len(self._frames) > 4:
                self._frames.clear()
            out = {}
            for link in self.drawn:
                lm = cfg["motion"].link(link.name)
                out[link.name] = (lm.point(link.stations)[0], np.cos(lm.angle), np.sin(lm.angle))
            self._frames[key] = (cfg, out)
        return self._frames[key][1]

    def _cached(self, k, angle, speed, accel):
        """Index into the cached revolution for step ``k`` if the crank state matches it, else None."""
        if self.cache is None:
            return None
        N, w, angles, _ = self.cache
        idx = k % N
        d = (angle - angles[idx] + math.pi) % (2 * math.pi) - math.pi
        return idx if abs(d) < 1e-9 and speed == w and accel == 0.0 else None

    def node_stations(self) -> dict:
        """Local x [m] of the nodes this engine reports, per link."""
        return {link.name: link.stations for link in self.drawn}

    def reflected_inertia(self, angles) -> np.ndarray:
        """Rigid-body inertia of this engine's (lumped) mass model seen at the crank [kg m^2]: the
        master's interface Jacobian, dT_drive/d(crank acceleration)."""
        return self.td.mech.crank_inertia(angles, lumped=True)[0]

    def initial_output(self) -> EngineOutput:
        """The state at reset: drive torque and gauge strains of the start (quasi-static or rest)."""
        out = self.march.out
        gauges = {g.name: (out[1 + 2 * i:2 + 2 * i], out[2 + 2 * i:3 + 2 * i]) for i, g in enumerate(self.td.gauges)}
        return EngineOutput(np.array([self.t0]), np.array([self._angle0]), np.array([self._speed0]), out[:1].copy(),
                            gauges)

    def save(self):
        """Snapshot for a coupling iteration (the march state is replaced, never mutated, per step)."""
        m = self.march
        return (self.k, m.state, m.z, m.out, m.q_sls, m.axial)

    def restore(self, token) -> None:
        m = self.march
        self.k, m.state, m.z, m.out, m.q_sls, m.axial = token

    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput:
        if drive.prescribed is None:
            raise EngineError("tmm: the transfer-matrix model is kinematically driven (crank clamped at its pivot); "
                              "couple it to a motor that supplies the crank motion, not a torque")
        t_start = self.t0 + self.k * self._dt
        n = steps_in(t_start, t_next, self._dt, "tmm")
        ks = self.k + 1 + np.arange(n)
        t = self.t0 + ks * self._dt          # integer step count, never accumulated
        angle, speed, accel = (np.asarray(x, dtype=float) for x in drive.prescribed(t))
        outs, zs, frames = [], [], {l.name: ([], [], []) for l in self.drawn}
        cached = [self._cached(int(k), float(a), float(w), float(x)) for k, a, w, x in zip(ks, angle, speed, accel)]
        batch = None
        if any(c is None for c in cached):
            # Every step the cache does not cover, factorized in one vectorised batch.
            rest = [i for i, c in enumerate(cached) if c is None]
            batch = (self.td.configurations(angle[rest], speed[rest], accel[rest], self._dt, maps=False),
                     {i: j for j, i in enumerate(rest)})
        # Runs of consecutive steps on the same configuration batch are marched together (compiled
        # for the cached revolution, tmm_core.kernels).
        runs, i = [], 0
        while i < n:
            use_cache = cached[i] is not None
            j = i
            while j < n and (cached[j] is not None) == use_cache:
                j += 1
            cfg = self.cache[3] if use_cache else batch[0]
            runs.append((cfg, np.array([cached[q] if use_cache else batch[1][q] for q in range(i, j)], dtype=np.int64)))
            i = j
        for cfg, idx in runs:
            z_run, out_run = self.march.step_many(cfg, idx)
            self.k += len(idx)
            outs.extend(out_run)
            zs.extend(z_run)
            for name, (rigid, c, s) in self._frame(cfg).items():
                frames[name][0].extend(rigid[idx])
                frames[name][1].extend(c[idx])
                frames[name][2].extend(s[idx])
        outs = np.array(outs)
        local = self.td.unstack(np.array(zs))
        nodes = {}
        for name, (rigid, c, s) in frames.items():
            if name not in local:           # a rigid link: its rigid-body positions
                nodes[name] = np.array(rigid)
                continue
            c, s = np.array(c)[:, None], np.array(s)[:, None]
            u, w = local[name][..., 0], local[name][..., 1]
            nodes[name] = np.array(rigid) + np.stack([c * u - s * w, s * u + c * w], -1)
        if not np.all(np.isfinite(outs)):
            raise EngineError(f"tmm: non-finite response before t = {t_next:.6g} s")
        gauges = {g.name: (outs[:, 1 + 2 * i], outs[:, 2 + 2 * i]) for i, g in enumerate(self.td.gauges)}
        return EngineOutput(t, angle, speed, outs[:, 0], gauges, nodes)
