"""Incremental time-domain march of a :class:`tmm_core.TimeDomain` (one step or a block of steps).

Owns the integrator state of a march (displacements, velocities, accelerations, the viscoelastic
Maxwell stresses and the last step's axial forces); the state is replaced, never mutated, so an
engine can save and restore it for a coupling iteration.
"""
from __future__ import annotations

import numpy as np

from .compiled import binding as kernel_binding, march as compiled_march
from .errors import InputError
from .ked import quasi_static
from .time_step import ANDERSON_DEPTH, AXIAL_FORCE_TOLERANCE

class March:
    """Incremental time-domain march of a :class:`TimeDomain` (one step at a time).

    Built by :meth:`TimeDomain.begin` at a crank state; :meth:`advance` takes the crank state at
    the end of the next step. ``z`` holds the current nodal displacements (stacked, local) and
    ``out`` the current outputs (drive torque [N m], then bending and axial strain per gauge).
    """

    def __init__(self, td, dt, angle, speed, accel, start, initial):
        if start not in ("rest", "quasi_static"):
            raise InputError(f"start must be 'rest' or 'quasi_static', got {start!r}")
        if initial is not None:
            for key in ("d", "v", "a"):
                if np.shape(initial.get(key)) != (td.n_dof,):
                    raise InputError(f"initial['{key}'] must have shape ({td.n_dof},)")
        self.td, self.dt = td, dt
        integ = td.integrator
        c_a, c_v = integ.coefficients(dt)
        _, visco = td.link_factor(c_v, dt)
        a1 = np.array([angle])
        d0 = v0 = np.zeros(td.n_dof)
        previous = (d0, d0)
        if initial is not None:
            d0, v0, a0 = (np.asarray(initial[k], dtype=float) for k in ("d", "v", "a"))
            previous = initial.get("previous", (d0, d0))
        elif start == "quasi_static":
            d0, v0, a0, previous, out = td.quasi_static_start(angle, speed, accel, dt)
        else:
            # Consistent initial acceleration from rest: M a0 = F(t0) (Newmark and generalized-alpha
            # are only first order otherwise; Houbolt does not use it).
            first = td.configurations(a1, np.array([speed]), np.array([accel]), dt, maps=False)
            a0 = td.rest_acceleration(first.rigid[0], first.motion)
        self.state = integ.initial(d0, v0, a0, previous)
        # Outputs of step 0: the quasi-static state for a quasi-static start; from rest the links
        # are undeformed (zero strain) and the drive torque is the rigid-body one.
        if start != "quasi_static" or initial is not None:
            qs0 = quasi_static(td.mech, a1, speed, accel, beam_column=td.beam_column, gravity=td.gravity,
                               gauges=td.gauges, backend=td.backend)
            out = np.concatenate([qs0.drive_torque] + [np.r_[b, a] for b, a in qs0.gauges.values()])
            if start == "rest" and initial is None:
                out[1:] = 0.0
        self.out, self.z = out, d0
        self.n_out = len(out)
        self.decay = np.ones(6 * td.n_seg)
        self.gain = np.zeros(6 * td.n_seg)
        off = 0
        for link in td.links:
            if link.name in visco:
                decay, g = visco[link.name]
                sel = slice(off, off + 6 * link.total_segments)
                self.decay[sel] = np.where(td.seg_E1[sel] > 0, decay, 1.0)
                self.gain[sel] = g * td.seg_E1[sel]
            off += 6 * link.total_segments
        self.has_visco = bool(visco)
        self.q_sls = np.zeros(6 * td.n_seg)
        if self.has_visco and (start == "quasi_static" or initial is not None):
            # Instantaneous elastic state: the Maxwell arms carry (E_0 - E_inf)/E * K d_0.
            self.q_sls = td.seg_E1 * (td.seg_K @ (td.gather @ d0))
        #: Segment axial forces of the last step [N] (the next step's starting guess).
        self.axial = None

    def advance(self, angle: float, speed: float, acceleration: float = 0.0):
        """One step to the crank state (angle [rad], speed [rad/s], acceleration [rad/s^2]) at
        the end of the step. Returns ``(z, out)``."""
        args = (np.array([angle], dtype=float), np.array([speed], dtype=float), np.array([acceleration], dtype=float),
                self.dt)
        return self.step_with(self.td.configurations(*args, maps=False), 0)

    def step_with(self, cfg, idx):
        """One step using configuration ``idx`` of a precomputed batch (see TimeDomain.configurations)."""
        td = self.td
        h_a, h_v = td.integrator.history(self.state, self.dt)
        loads = td.step_loads(cfg, idx, h_a, h_v, viscous=(self.q_sls, self.decay, self.gain, self.state["d"])
                              if self.has_visco else None)
        z, out, P = td.solve_step(cfg, idx, loads, self.state, self.dt, self.axial)
        self.axial = P
        return self._commit(z, out)

    def step_many(self, cfg, indices, record_z: bool = True, record_axial: bool = False):
        """Steps through configurations ``indices`` of a batch, compiled when the batch has
        cached maps or stored factorizations (:mod:`tmm_core.compiled.march`), else one by one in numpy.
        Returns ``(zs, outs)``: displacements ``(k, n_dof)`` (None unless ``record_z``) and outputs ``(k, n_out)``; with
        ``record_axial`` also the segment axial forces ``(k, n_seg)`` of the 'dynamic' step."""
        indices = np.asarray(indices, dtype=np.int64)
        td = self.td
        if td.compiled and (cfg.maps is not None or cfg.factors is not None) and not self.has_visco \
                and td.integrator.name in compiled_march.INTEGRATOR_CODES:
            return self._compiled(cfg, indices, record_z, record_axial)
        zs = np.empty((len(indices), td.n_dof)) if record_z else None
        outs = np.empty((len(indices), self.n_out))
        Ps = np.empty((len(indices), len(td.segments.length))) if record_axial else None
        for j, i in enumerate(indices):
            z, outs[j] = self.step_with(cfg, int(i))
            if record_z:
                zs[j] = z
            if record_axial:
                Ps[j] = self.axial
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _compiled(self, cfg, indices, record_z, record_axial=False):
        td, n, integ = self.td, self.td.n_dof, self.td.integrator
        data = td.kernel_data(cfg)
        code = compiled_march.INTEGRATOR_CODES[integ.name]
        params = np.array(integ.parameters if code == compiled_march.GENERALIZED_ALPHA else (0.0, 0.0, 0.0, 0.0), float)
        c_a, c_v = integ.coefficients(self.dt)
        st = self.state
        zero = np.zeros(n)
        arrays = [np.array(st.get(key, zero), dtype=float) for key in ("d", "v", "a", "acc", "d1", "d2")]
        seg = td.segments
        dynamic = td.axial_force == "dynamic"
        P = np.array(self.axial if self.axial is not None else
                     (cfg.P0[indices[0]] if dynamic else np.zeros(len(seg.length))), dtype=float)
        outs = np.empty((len(indices), self.n_out))
        zs = np.empty((len(indices), n)) if record_z else np.empty((0, n))
        Ps = np.empty((len(indices), len(seg.length))) if record_axial else np.empty((0, len(seg.length)))
        iterations = np.zeros(len(indices), dtype=np.int64)
        # The compiled march's records (tmm_core.compiled.march.march).
        integrator = (code, params, self.dt, c_a, c_v)
        model = td.kernel_model()
        settings = (td.coupling.coriolis, td.has_kv, dynamic, "shortening" in td.dynamic_terms,
                    "axial_force" in td.dynamic_terms, td.axial_tolerance, AXIAL_FORCE_TOLERANCE, td.axial_iterations,
                    ANDERSON_DEPTH)
        j = 0
        while j < len(indices):
            recorded = (outs[j:], zs[j:] if record_z else zs, Ps[j:] if record_axial else Ps, iterations[j:])
            done = kernel_binding.march()(integrator, indices[j:], data[:6], data[6:], model, settings,
                                          (*arrays, P), recorded)
            self.state = {key: arr.copy() for key, arr in zip(("d", "v", "a", "acc", "d1", "d2"), arrays) if key in st}
            self.axial = P.copy() if dynamic else self.axial
            j += done
            if j < len(indices):
                # A step the kernel hands back: the numpy path refactorizes it at its own axial forces.
                z, outs[j] = self.step_with(cfg, int(indices[j]))
                if record_z:
                    zs[j] = z
                if record_axial:
                    Ps[j] = self.axial
                arrays = [np.array(self.state.get(key, zero), dtype=float) for key in ("d", "v", "a", "acc", "d1", "d2")]
                P = np.array(self.axial, dtype=float) if dynamic else P
                j += 1
        self.z = self.state["d"]
        self.out = outs[-1]
        #: Iterations of each compiled second-order step of the last block (0: solved in numpy).
        self.iterations = iterations
        zs = zs if record_z else None
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _commit(self, z, out):
        td = self.td
        if self.has_visco:
            self.q_sls = self.decay * self.q_sls + self.gain * (td.seg_K @ (td.gather @ (z - self.state["d"])))
        self.state = td.integrator.advance(self.state, z, self.dt)
        self.z, self.out = z, out
        return z, out
