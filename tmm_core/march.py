"""Incremental time-domain march of a model (:class:`tmm_core.discretization.Discretization`;
one step or a block of steps), and its start.

Owns the integrator state of a march (displacements, velocities, accelerations, the viscoelastic
Maxwell stresses and the last step's axial forces); the state is replaced, never mutated, so an
engine can save and restore it for a coupling iteration. Also the initial states of a march:
from rest (:func:`rest_acceleration`) or quasi-static (:func:`quasi_static_start`).
"""
from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

from .batches import configurations, with_maps
from .compiled import binding as kernel_binding
from .discretization import Discretization
from .errors import InputError, require_positive
from .ked import Coupling, quasi_static
from .integrators import linear_maps
from .time_step import ANDERSON_DEPTH, AXIAL_FORCE_TOLERANCE, kernel_data, solve_step, step_loads

class March:
    """Incremental time-domain march of a model (one step at a time).

    Built at a crank state (:meth:`tmm_core.TimeDomain.begin`) for the model ``model``, step
    ``dt`` [s], the crank state (angle [rad], speed [rad/s], acceleration [rad/s^2]) and the start
    ('rest' or 'quasi_static') or an ``initial`` state; :meth:`advance` takes the crank state at
    the end of the next step. ``z`` holds the current nodal displacements (stacked, local) and
    ``out`` the current outputs (drive torque [N m], then bending and axial strain per gauge).
    ``outputs_at_start`` False: the outputs at the start from rest or an ``initial`` state are
    not computed (NaN): a periodic revolution reads those of its steps only, and the quasi-static
    solve they take was a third of a revolution's time.
    """

    def __init__(self, model: Discretization, dt, angle, speed, accel, start, initial, outputs_at_start=True):
        if start not in ("rest", "quasi_static"):
            raise InputError(f"start must be 'rest' or 'quasi_static', got {start!r}")
        if initial is not None:
            for key in ("d", "v", "a"):
                if np.shape(initial.get(key)) != (model.n_dof,):
                    raise InputError(f"initial['{key}'] must have shape ({model.n_dof},)")
        self.model, self.dt = model, dt
        if model.compiled:
            _compile_march_ahead(model, dt, angle, speed, accel)
        integ = model.integrator
        c_a, c_v = integ.coefficients(dt)
        _, visco = model.link_factor(c_v, dt)
        a1 = np.array([angle])
        d0 = v0 = np.zeros(model.n_dof)
        previous = (d0, d0)
        if initial is not None:
            d0, v0, a0 = (np.asarray(initial[k], dtype=float) for k in ("d", "v", "a"))
            previous = initial.get("previous", (d0, d0))
        elif start == "quasi_static":
            d0, v0, a0, previous, out = quasi_static_start(model, angle, speed, accel, dt)
        else:
            # Consistent initial acceleration from rest: M a0 = F(t0) (Newmark and generalized-alpha
            # are only first order otherwise; Houbolt does not use it).
            first = configurations(model, a1, np.array([speed]), np.array([accel]), dt, maps=False)
            a0 = rest_acceleration(model, first.rigid[0], first.motion)
        self.state = integ.initial(d0, v0, a0, previous)
        # Outputs of step 0: the quasi-static state for a quasi-static start; from rest the links
        # are undeformed (zero strain) and the drive torque is the rigid-body one.
        if (start != "quasi_static" or initial is not None) and not outputs_at_start:
            out = np.full(model.outputs.size, np.nan)
        elif start != "quasi_static" or initial is not None:
            qs0 = quasi_static(model.mech, a1, speed, accel, beam_column=model.beam_column, gravity=model.gravity,
                               gauges=model.gauges, backend=model.backend)
            out = np.concatenate([qs0.drive_torque] + [np.r_[b, a] for b, a in qs0.gauges.values()])
            if start == "rest" and initial is None:
                out[1:] = 0.0
        self.out, self.z = out, d0
        self.n_out = len(out)
        self.decay = np.ones(6 * model.n_seg)
        self.gain = np.zeros(6 * model.n_seg)
        off = 0
        for link in model.links:
            if link.name in visco:
                decay, g = visco[link.name]
                sel = slice(off, off + 6 * link.total_segments)
                self.decay[sel] = np.where(model.seg_E1[sel] > 0, decay, 1.0)
                self.gain[sel] = g * model.seg_E1[sel]
            off += 6 * link.total_segments
        self.has_visco = bool(visco)
        self.q_sls = np.zeros(6 * model.n_seg)
        if self.has_visco and (start == "quasi_static" or initial is not None):
            # Instantaneous elastic state: the Maxwell arms carry (E_0 - E_inf)/E * K d_0.
            self.q_sls = model.seg_E1 * (model.seg_K @ (model.gather @ d0))
        #: Segment axial forces of the last step [N] (the next step's starting guess).
        self.axial = None

    def advance(self, angle: float, speed: float, acceleration: float = 0.0):
        """One step to the crank state (angle [rad], speed [rad/s], acceleration [rad/s^2]) at
        the end of the step. Returns ``(z, out)``."""
        args = (np.array([angle], dtype=float), np.array([speed], dtype=float), np.array([acceleration], dtype=float),
                self.dt)
        return self.step_with(configurations(self.model, *args, maps=False), 0)

    def step_with(self, cfg, idx):
        """One step using configuration ``idx`` of a precomputed batch (:func:`tmm_core.batches.configurations`)."""
        model = self.model
        h_a, h_v = model.integrator.history(self.state, self.dt)
        loads = step_loads(model, cfg, idx, h_a, h_v, viscous=(self.q_sls, self.decay, self.gain, self.state["d"])
                              if self.has_visco else None)
        z, out, P = solve_step(model, cfg, idx, loads, self.state, self.dt, self.axial)
        self.axial = P
        return self._commit(z, out)

    def step_many(self, cfg, indices, record_z: bool = True, record_axial: bool = False):
        """Steps through configurations ``indices`` of a batch, compiled when the batch has
        cached maps or stored factorizations (:mod:`tmm_core.compiled.march`), else one by one in numpy.
        Returns ``(zs, outs)``: displacements ``(k, n_dof)`` (None unless ``record_z``) and outputs ``(k, n_out)``; with
        ``record_axial`` also the segment axial forces ``(k, n_seg)`` of the 'dynamic' step."""
        indices = np.asarray(indices, dtype=np.int64)
        model = self.model
        if model.compiled and (cfg.maps is not None or cfg.factors is not None) and not self.has_visco:
            return self._compiled(cfg, indices, record_z, record_axial)
        zs = np.empty((len(indices), model.n_dof)) if record_z else None
        outs = np.empty((len(indices), self.n_out))
        Ps = np.empty((len(indices), len(model.segments.length))) if record_axial else None
        for j, i in enumerate(indices):
            z, outs[j] = self.step_with(cfg, int(i))
            if record_z:
                zs[j] = z
            if record_axial:
                Ps[j] = self.axial
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _compiled(self, cfg, indices, record_z, record_axial=False):
        model = self.model
        dynamic = model.axial_force == "dynamic"
        integrator, data, on_factors, kernel, settings, slots = self._kernel_records(cfg)
        S = self._stacked_state(slots)
        seg = model.segments
        P = np.array(self.axial if self.axial is not None else
                     (cfg.P0[indices[0]] if dynamic else np.zeros(len(seg.length))), dtype=float)
        n = model.n_dof
        outs = np.empty((len(indices), self.n_out))
        zs = np.empty((len(indices), n)) if record_z else np.empty((0, n))
        Ps = np.empty((len(indices), len(seg.length))) if record_axial else np.empty((0, len(seg.length)))
        iterations = np.zeros(len(indices), dtype=np.int64)
        j = 0
        while j < len(indices):
            recorded = (outs[j:], zs[j:] if record_z else zs, Ps[j:] if record_axial else Ps, iterations[j:])
            done = kernel_binding.march()(integrator, indices[j:], data, on_factors, kernel, settings, (S, P),
                                          recorded)
            self.state = {key: S[i].copy() for i, key in enumerate(slots)}
            self.axial = P.copy() if dynamic else self.axial
            j += done
            if j < len(indices):
                # A step the kernel hands back: the numpy path refactorizes it at its own axial forces.
                z, outs[j] = self.step_with(cfg, int(indices[j]))
                if record_z:
                    zs[j] = z
                if record_axial:
                    Ps[j] = self.axial
                S = self._stacked_state(slots)
                P = np.array(self.axial, dtype=float) if dynamic else P
                j += 1
        self.z = self.state["d"]
        self.out = outs[-1]
        #: Iterations of each compiled second-order step of the last block (0: solved in numpy).
        self.iterations = iterations
        zs = zs if record_z else None
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _kernel_records(self, cfg):
        """The compiled march's records for the batch ``cfg`` that do not change from block to
        block (:func:`tmm_core.compiled.march.march`): ``(integrator, maps, on_factors, model,
        settings)``, and the integrator's state slots in the order of its stacked state."""
        model, integ = self.model, self.model.integrator
        data = kernel_data(model, cfg)
        slots, Hc, Gc, ez = linear_maps(integ, self.dt)
        _, c_v = integ.coefficients(self.dt)
        integrator = (Hc, Gc, ez, np.array([slots.index(key) for key in "dva"]), self.dt, c_v)
        settings = (model.coupling.coriolis, model.has_kv, model.axial_force == "dynamic",
                    "shortening" in model.dynamic_terms, "axial_force" in model.dynamic_terms,
                    model.strain_measure == "corotational", model.axial_tolerance, AXIAL_FORCE_TOLERANCE,
                    model.axial_iterations, ANDERSON_DEPTH)
        return integrator, data[:6], data[6], model.kernel_model(), settings, slots

    def kernel_arguments(self, cfg) -> tuple:
        """The compiled march's arguments for one step of the batch ``cfg``, as :meth:`step_many`
        passes them (nothing recorded but the outputs): what its signature is read from."""
        integrator, data, on_factors, kernel, settings, slots = self._kernel_records(cfg)
        n_seg = len(self.model.segments.length)
        recorded = (np.empty((1, self.n_out)), np.empty((0, self.model.n_dof)), np.empty((0, n_seg)),
                    np.zeros(1, dtype=np.int64))
        return (integrator, np.zeros(1, dtype=np.int64), data, on_factors, kernel, settings,
                (self._stacked_state(slots), np.zeros(n_seg)), recorded)

    def _stacked_state(self, slots):
        """The integrator's state arrays stacked ``(K, n_dof)``, as the compiled march holds them."""
        return np.stack([np.asarray(self.state[key], dtype=float) for key in slots])

    def _commit(self, z, out):
        model = self.model
        if self.has_visco:
            self.q_sls = self.decay * self.q_sls + self.gain * (model.seg_K @ (model.gather @ (z - self.state["d"])))
        self.state = model.integrator.advance(self.state, z, self.dt)
        self.z, self.out = z, out
        return z, out


def _compile_march_ahead(model: Discretization, dt, angle, speed, accel) -> None:
    """On a first run (the compiled march not in the cache), have a second process compile the
    march while this one compiles the static solve (:func:`tmm_core.compiled.binding.compile_ahead`).
    The march's signature is read off a numpy twin of the model at the crank state (one
    configuration with its maps: the arrays the compiled march reads have the same types
    whichever backend made them, :func:`tmm_core.time_step.kernel_data`). Only where the run will
    march on maps: a large model marches on stored factorizations, another signature."""
    if not (kernel_binding.ahead_pays("march") and with_maps(model, 1, "auto")):
        return
    twin = March(dataclasses.replace(model, backend="numpy"), dt, angle, speed, accel, "rest", None,
                 outputs_at_start=False)          # its start outputs are not read
    if twin.has_visco:          # the viscoelastic step is numpy's alone
        return
    cfg = configurations(twin.model, np.array([angle]), np.array([speed]), np.array([accel]), dt, maps=True)
    kernel_binding.compile_ahead("march", twin.kernel_arguments(cfg))


def begin(model: Discretization, dt: float, angle: float, speed: float, acceleration: float = 0.0, *,
          start: str = "rest", initial: Mapping[str, np.ndarray] | None = None,
          outputs_at_start: bool = True) -> March:
    """Start an incremental march of ``model`` at a crank state (angle [rad], speed [rad/s],
    acceleration [rad/s^2]) with step ``dt`` [s]; see :class:`March` (``start``, ``initial``,
    ``outputs_at_start``)."""
    return March(model, float(require_positive("time step dt_s", dt)), float(angle), float(speed),
                 float(acceleration), start, initial, outputs_at_start)


def rest_acceleration(model: Discretization, loads, motion):
    """Accelerations [m/s^2, rad/s^2] of the lumped masses of ``model`` under ``loads`` (stacked
    local [N, N m]) with the structure at rest and undeformed (``motion``: the crank state's
    rigid-body motion): each mass alone, except at joints, where all member ends share the
    translation (and, for rigid connections, the rotation); supported DOFs stay at rest."""
    m = model.m_vec
    a = np.divide(loads, m, out=np.zeros_like(loads), where=m > 0)
    structure = model.structure
    for joint in structure.joints:
        ends = []
        for link, member in zip(model.links, structure.members):
            n = link.total_segments
            if member.start == joint.name:
                ends.append((link, model.offsets[link.name], member.start_connection))
            if member.end == joint.name:
                ends.append((link, model.offsets[link.name] + 3 * n, member.end_connection))
        F, M_sum = np.zeros(2), 0.0
        for link, i, _ in ends:
            c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
            R = np.array([[c, -s_], [s_, c]])           # local -> global
            F += R @ loads[i:i + 2]
            M_sum += m[i]
        acc = F / M_sum if M_sum > 0 and joint.support == "free" else np.zeros(2)
        rigid = [e for e in ends if e[2] == "rigid"]
        J_sum = sum(m[i + 2] for _, i, _ in rigid)
        Mz = sum(loads[i + 2] for _, i, _ in rigid)
        for link, i, conn in ends:
            c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
            a[i:i + 2] = np.array([[c, s_], [-s_, c]]) @ acc
            if conn == "rigid":
                a[i + 2] = Mz / J_sum if J_sum > 0 and joint.support != "clamped" else 0.0
    return a


def quasi_static_start(model: Discretization, th, w, a, dt):
    """Elastic state of the quasi-static solution of ``model`` at the first crank positions
    (angle ``th`` [rad], speed ``w`` [rad/s], acceleration ``a`` [rad/s^2], step ``dt`` [s]):
    ``(d0, v0, a0, (d_-1, d_-2), out0)``, ``out0`` the outputs at ``th`` (drive torque [N m],
    then bending and axial strain per gauge), from the same quasi-static batch (one solve of four
    positions instead of a second one for the outputs: ~2 ms of a set-up)."""
    angles = th + np.array([-2.0, -1.0, 0.0, 1.0]) * w * dt
    qs = quasi_static(model.mech, angles, w, a, beam_column=model.beam_column, coupling=Coupling(),
                      gravity=model.gravity, gauges=model.gauges, backend=model.backend)
    z = np.concatenate([qs.solution.members[l.name].state[:, :, 0, :3].reshape(4, -1) for l in model.links], -1)
    d2, d1, d0, dp = z
    v0 = (dp - d1) / (2 * dt)
    a0 = (dp - 2 * d0 + d1) / dt**2
    out0 = np.concatenate([qs.drive_torque[2:3]] + [np.r_[b[2], a[2]] for b, a in qs.gauges.values()])
    return d0, v0, a0, (d1, d2), out0
