"""Transfer-matrix engine: :class:`tmm_core.TimeDomain` behind the engine protocol.

The transfer-matrix model is kinematically driven (the crank is clamped at its pivot in the
instantaneous structure), so it accepts a prescribed crank motion and returns the drive torque;
a motor couples to it by supplying the crank motion. When the crank turns at the scenario's
constant speed and the step divides a revolution, one revolution of factorized configurations
is prepared at reset and re-used (the fast path); any other motion is factorized step by step.
When the drive says its crank history holds beyond the macro step (``DriveInput.ahead``: a
prescribed-speed run), the engine marches ahead in compiled blocks of a few hundred steps and
serves the macro steps from them; a save for a coupling iteration rewinds to the steps served.

Owns: the transfer-matrix engine behind the protocol. Boundaries: no time step of its own: it
calls tmm_core's public step API.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from tmm_core.revolution import Revolution

from ..scenario import Scenario
from .base import DriveInput, EngineError, EngineOutput, steps_in


# Steps marched ahead in one call under a prescribed crank history (see TMMEngine._serve): a
# revolution of the FE rig at its 0.5 deg default is 720 steps; 256 keeps the work wasted at the
# end of a run (a steady stop) to a fraction of a revolution.
LOOKAHEAD_STEPS = 256


class LookAhead(NamedTuple):
    """Steps marched ahead of the master: steps ``first .. first + len(idx) - 1`` on the cached
    revolution's configurations ``idx``, their :class:`EngineOutput` (times, crank states,
    outputs and deformed node positions ({link: (k, n_nodes, 2)} [m])), the first step whose
    outputs are not finite (``len(idx)`` if none), the march state before the first (to rewind
    to), and the crank history it followed (a ``DriveInput.prescribed``)."""
    first: int
    idx: np.ndarray
    out: EngineOutput
    bad: int
    start: tuple
    profile: object

    def covers(self, ks, profile) -> bool:
        """Whether steps ``ks`` of the crank history ``profile`` are in this block."""
        return profile is self.profile and self.first <= ks[0] and ks[-1] < self.first + len(self.idx)

    def rows(self, k0: int, n: int) -> EngineOutput:
        """Steps ``k0 .. k0 + n - 1`` (views of the block's arrays: a macro step served from a
        block costs a few slices, where building its output cost ~40 us)."""
        a = k0 - self.first
        b = slice(a, a + n)
        o = self.out
        return EngineOutput(o.t[b], o.crank_angle[b], o.crank_speed[b], o.drive_torque[b],
                            {g: (bend[b], ax[b]) for g, (bend, ax) in o.gauges.items()},
                            {name: v[b] for name, v in o.nodes.items()})


class TMMEngine:
    name = "tmm"
    kinematic = True      # takes a crank motion, returns the drive torque

    def __init__(self, backend: str | None = None):
        """``backend``: the time domain's computing backend (:mod:`tmm_core.backend`; None: its
        default, compiled where numba is installed)."""
        self.backend = backend
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
        self.td = scenario.time_domain(backend=self.backend)
        # The step and the cached revolution are the scenario's (its set-point speed); ``speed`` is
        # only the crank's state at t0 (a motor run may start from rest).
        set_speed = scenario.drive.speed_rad_s
        if s.step_s is None and not set_speed:
            raise EngineError("tmm: a crank-angle step needs a non-zero drive speed; give solver.tmm.step in s")
        self._dt = scenario.engine_step_s("tmm")
        self.t0, self.k = t0, 0
        self._angle0, self._speed0 = angle, speed
        self.march = self.td.begin(self._dt, angle, speed, 0.0, start=s.start)
        self.cache = None        # a tmm_core.revolution.Revolution at the scenario's speed
        N = scenario.revolution_period_s / self._dt if set_speed else 0.0
        if set_speed and abs(N - round(N)) < 1e-6 and round(N) >= 4:
            N = int(round(N))
            j = np.arange(N)
            angles = angle + set_speed * self._dt * j
            self.cache = Revolution.build(self.td.model, angles, np.full(N, set_speed), np.zeros(N), self._dt)
        self.links = self.td.links                          # elastic links (their DOFs)
        self.drawn = scenario.mechanism.links()             # every link, rigid ones too
        self._frames = {}     # id(configuration batch) -> per link (rigid node positions, cos, sin)
        self._ahead = None    # a LookAhead: steps marched ahead of self.k (see _serve)

    def _frame(self, cfg):
        """Rigid node positions and link orientation of every configuration of a batch."""
        key = id(cfg)
        if key not in self._frames:
            if len(self._frames) > 4:
                self._frames.clear()
            out = {}
            for link in self.drawn:
                lm = cfg.motion.link(link.name)
                out[link.name] = (lm.point(link.stations)[0], np.cos(lm.angle), np.sin(lm.angle))
            self._frames[key] = (cfg, out)
        return self._frames[key][1]

    def _cache_indices(self, ks, angle, speed, accel):
        """Index into the cached revolution of each step ``ks`` whose crank state matches it, else -1."""
        if self.cache is None:
            return np.full(len(ks), -1, dtype=np.int64)
        return self.cache.indices(ks, angle, speed, accel)

    def node_stations(self) -> dict:
        """Local x [m] of the nodes this engine reports, per link."""
        return {link.name: link.stations for link in self.drawn}

    def reflected_inertia(self, angles) -> np.ndarray:
        """Rigid-body inertia of this engine's (lumped) mass model seen at the crank [kg m^2]: the
        master's interface Jacobian, dT_drive/d(crank acceleration)."""
        return self.td.mech.crank_inertia(angles, lumped=True)[0]

    def initial_output(self) -> EngineOutput:
        """The state at reset: drive torque and gauge strains of the start (quasi-static or rest)."""
        return self._output(np.array([self.t0]), np.array([self._angle0]), np.array([self._speed0]),
                            self.march.out[None, :].copy(), {})

    def _output(self, t, angle, speed, outs, nodes) -> EngineOutput:
        """The :class:`EngineOutput` of steps at times ``t`` [s] with crank ``angle`` [rad] and
        ``speed`` [rad/s], output rows ``outs`` (drive torque and gauges by the model's layout)
        and deformed ``nodes``."""
        layout = self.td.outputs
        return EngineOutput(t, angle, speed, layout.torque(outs), layout.split(outs), nodes)

    def save(self):
        """Snapshot for a coupling iteration (the march state is replaced, never mutated, per step)."""
        self._rewind()
        return self._state()

    def _state(self):
        m = self.march
        return (self.k, m.state, m.z, m.out, m.q_sls, m.axial)

    def restore(self, token) -> None:
        self._ahead = None
        m = self.march
        self.k, m.state, m.z, m.out, m.q_sls, m.axial = token

    def _rewind(self) -> None:
        """Bring the march back from its look-ahead to step ``self.k`` (re-marching the served
        steps of the block from its start: the march is deterministic)."""
        if self._ahead is None:
            return
        block, k = self._ahead, self.k
        if k == block.first + len(block.idx) - 1:       # the block is used up: the march is at step k
            self._ahead = None
            return
        self.restore(block.start)
        if k >= block.first:
            self.march.step_many(self.cache.batch, block.idx[:k - block.first + 1], record_z=False)
        self.k = k

    def _serve(self, ks, drive) -> EngineOutput:
        """Steps ``ks`` of a prescribed crank history on the cached revolution, marched ahead in
        blocks of LOOKAHEAD_STEPS or more (a whole number of macro steps; none past the run's
        end, ``drive.until``, when the drive gives it): the compiled march's
        call (numba's dispatch of its ~40 arrays, ~50-90 us), the outputs' and node positions'
        bookkeeping and the crank history's evaluation then cost per block, not per macro step."""
        a = self._ahead
        if a is None or not a.covers(ks, drive.prescribed):
            self._rewind()
            # A whole number of macro steps of this length: the next ones then never straddle two
            # blocks; none past the run's end (the last block of a 3-revolution run at 1 deg was
            # 220 of its 1300 steps).
            n_ahead = len(ks) * -(-LOOKAHEAD_STEPS // len(ks))
            if drive.until is not None:
                left = steps_in(self.t0 + self.k * self._dt, drive.until, self._dt, "tmm")
                n_ahead = max(len(ks), min(n_ahead, left))
            kk = self.k + 1 + np.arange(n_ahead)
            t = self.t0 + kk * self._dt          # integer step count, never accumulated
            angle, speed, accel = (np.asarray(x, dtype=float) * np.ones(len(kk)) for x in drive.prescribed(t))
            idx = self._cache_indices(kk, angle, speed, accel)
            # Stop the block where the history leaves the cached revolution (ks itself is on it).
            miss = np.flatnonzero(idx < 0)
            n = miss[0] if len(miss) and miss[0] >= len(ks) else len(kk)
            idx = idx[:n]
            start = self._state()
            zs, outs = self.march.step_many(self.cache.batch, idx)
            finite = np.all(np.isfinite(outs), axis=1)
            out = self._output(t[:n], angle[:n], speed[:n], outs, self._nodes([(self.cache.batch, idx, zs)]))
            a = self._ahead = LookAhead(int(kk[0]), idx, out, int(np.argmin(finite)) if not finite.all() else n,
                                        start, drive.prescribed)
        self.k = int(ks[-1])
        if a.bad <= ks[-1] - a.first:
            raise EngineError(f"tmm: non-finite response before t = {self.t0 + ks[-1] * self._dt:.6g} s")
        return a.rows(int(ks[0]), len(ks))

    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput:
        if drive.prescribed is None:
            raise EngineError("tmm: the transfer-matrix model is kinematically driven (crank clamped at its pivot); "
                              "couple it to a motor that supplies the crank motion, not a torque")
        t_start = self.t0 + self.k * self._dt
        n = steps_in(t_start, t_next, self._dt, "tmm")
        ks = self.k + 1 + np.arange(n)
        # Steps of the block marched ahead were matched with the cached revolution when it was made.
        if drive.ahead and self._ahead is not None and self._ahead.covers(ks, drive.prescribed):
            return self._serve(ks, drive)
        t = self.t0 + ks * self._dt          # integer step count, never accumulated
        angle, speed, accel = (np.asarray(x, dtype=float) * np.ones(n) for x in drive.prescribed(t))
        hit = self._cache_indices(ks, angle, speed, accel)
        if drive.ahead and np.all(hit >= 0):
            return self._serve(ks, drive)
        self._rewind()
        runs = self._march(hit, angle, speed, accel)
        outs = np.concatenate([r[3] for r in runs])
        nodes = self._nodes([r[:3] for r in runs])
        if not np.all(np.isfinite(outs)):
            raise EngineError(f"tmm: non-finite response before t = {t_next:.6g} s")
        return self._output(t, angle, speed, outs, nodes)

    def _march(self, hit, angle, speed, accel):
        """Steps one by one in blocks: runs of consecutive steps on the same configuration batch
        (the cached revolution where ``hit`` >= 0, else the steps factorized in one vectorised
        batch). Returns ``[(batch, indices, zs, outs)]``."""
        n = len(hit)
        batch = None
        rest = np.flatnonzero(hit < 0)
        if len(rest):
            batch = self.td.configurations(angle[rest], speed[rest], accel[rest], self._dt, maps="factors")
            position = np.full(n, -1, dtype=np.int64)
            position[rest] = np.arange(len(rest))
        runs, i = [], 0
        while i < n:
            use_cache = hit[i] >= 0
            j = i
            while j < n and (hit[j] >= 0) == use_cache:
                j += 1
            cfg, idx = (self.cache.batch, hit[i:j]) if use_cache else (batch, position[i:j])
            zs, outs = self.march.step_many(cfg, idx)
            self.k += len(idx)
            runs.append((cfg, idx, zs, outs))
            i = j
        return runs

    def _nodes(self, runs):
        """Deformed node positions [m], global, per drawn link, of the steps of ``runs``
        (``[(batch, indices, zs)]``): rigid-body positions plus the elastic displacements."""
        per_link = {link.name: [] for link in self.drawn}
        for cfg, idx, zs in runs:
            local = self.td.unstack(zs)
            for name, (rigid, c, s) in self._frame(cfg).items():
                if name not in local:           # a rigid link: its rigid-body positions
                    per_link[name].append(rigid[idx])
                    continue
                c, s = c[idx][:, None], s[idx][:, None]
                u, w = local[name][..., 0], local[name][..., 1]
                per_link[name].append(rigid[idx] + np.stack([c * u - s * w, s * u + c * w], -1))
        return {name: np.concatenate(parts) for name, parts in per_link.items()}
