"""Reduced transfer-matrix model: the equations on the basis, their propagator and the periodic
steady state by shooting (the basis is :mod:`tmm_core.reduced`).

With ``q = T(theta) eta`` the Galerkin equations in the coordinates ``eta`` (r of them) are::

    M_r eta'' + C_r eta' + K_r eta + N(eta, eta') = f_r
    M_r = T^T M T
    C_r = T^T (2 M T' theta' + (D + C_K + G_c) T)
    K_r = W^T F W + T^T (M (T'' theta'^2 + T' theta'') + (D + C_K + G_c) T' theta' + K_c T)
    N   = sum_s P_s T^T E_s^T G_s E_s T eta + F_s (T_end,u - T_start,u)          (second order)
    f_r = T^T f(theta, theta', theta'')

(symbols as in :mod:`tmm_core.reduced`; all of them at the crank state of the instant). ``N`` is
the second-order beam of the full model's default (``axial_force = 'dynamic'``): the segment
axial force ``P_s = EA/L (e + beta e') + F_s`` from the elongation ``e`` of the segment's nodes
and the shortening force ``F_s = EA/L (Delta + beta Delta')``, ``Delta = 1/2 d^T G d``, i.e. the
geometric stiffness is linear in the axial force and the axial force is the step's own (the
quasi-static part is in the static correction, so it needs no separate estimate). With
``axial_force = 'none'`` (linear theory) ``N = 0`` and the model is linear time-periodic.

Propagator: the 3-stage Radau IIA collocation (order 5, L-stable: the stiff axial content of the
static correction is damped as generalized-alpha damps it in the full model), at a fixed number of
steps per revolution chosen for accuracy; each step solves its stage equations by Newton with
the exact Jacobian. The step's Jacobian with respect to the state is exact too, so the product
over a revolution is the monodromy matrix of the discrete map. Periodic shooting: the linear
part gives the first guess in one linear solve ``(I - Phi) x0 = c``; Newton on ``x_N(x0) = x0``
(state ``x = (eta, eta')``, 2r) then handles the axial-force term.

The revolutions run in the compiled kernel :mod:`tmm_core.compiled.reduced_periodic` (numba) unless
the model's backend is 'numpy' (default: the backend of the full model); the numpy code here is the
reference it is tested against. FE rig, r = 23, 360 steps, one thread: a periodic solve about
0.3 s compiled against 2.8 s in numpy (the set-up of the stage matrices included).

Outputs per step: gauge bending and axial strain [-] (the axial strain with the shortening from
bending, as the full model reports it) and the drive torque [N m, CCW +] from the loads on the
instantaneous structure (D'Alembert, elastic inertia, rotating-frame and mass-proportional
damping terms; the second-order terms' share of the reactions is left out).

Owns: the reduced model's equations, Radau IIA propagation and periodic shooting. Boundaries:
the basis is tmm_core.reduced, the compiled revolution tmm_core.compiled.reduced_periodic; the full
model's step is not used.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from scipy.linalg import lu_factor, lu_solve

from .compiled import binding as kernel_binding, reduced_periodic as compiled_reduced_periodic
from .backend import choose_backend
from .discretization import Discretization, HoldsModel, as_model
from .anderson import AndersonOptions, anderson, block_weights, residual_of
from .errors import ConvergenceError, InputError
from .ked import CrankMotion
from .periodic import PeriodicResult
from .reduced import ReducedBasis, ReducedOptions, build_basis, segment_links
from .reduced_stages import StageCoefficients, stage_terms
from .second_order import chord_lag, corotational_node_forces, geometric_matrices, segment_dofs

_S6 = math.sqrt(6.0)
#: Radau IIA, 3 stages: Butcher matrix and nodes.
RADAU_A = np.array([[(88 - 7 * _S6) / 360, (296 - 169 * _S6) / 1800, (-2 + 3 * _S6) / 225],
                    [(296 + 169 * _S6) / 1800, (88 + 7 * _S6) / 360, (-2 - 3 * _S6) / 225],
                    [(16 - _S6) / 36, (16 + _S6) / 36, 1.0 / 9.0]])
CHORD_RATE = 0.25      # keep the monodromy while the shooting residual falls at least this fast
RADAU_C = np.array([(4 - _S6) / 10, (4 + _S6) / 10, 1.0])


def stage_points(crank: CrankMotion):
    """Times [s], crank angles [rad], speeds [rad/s] and accelerations [rad/s^2] at the three
    Radau IIA stage points of every step of ``crank`` (N + 1 samples): Hermite interpolation of the
    samples, exact for constant speed."""
    h = crank.dt
    t = np.asarray(crank.t) - crank.t[0]
    ts = (t[:-1, None] + RADAU_C[None, :] * h).ravel()
    th = CubicHermiteSpline(t, crank.angle, crank.speed)(ts)
    w = CubicHermiteSpline(t, crank.speed, crank.acceleration)(ts)
    al = np.interp(ts, t, crank.acceleration)
    return crank.t[0] + ts, th, w, al


class ReducedModel:
    """The reduced equations at the stage points of a crank history (one period).

    ``source``: the model whose physics is reduced (mass model, damping, coupling, axial-force
    model, gravity, gauges): a :class:`tmm_core.discretization.Discretization`, or the one a
    :class:`tmm_core.TimeDomain` holds (kept as ``model``). ``crank``: one period of the crank history
    (N + 1 samples, the last one revolution after the first). ``basis``: from
    :func:`tmm_core.reduced.build_basis` (geometry only: it may serve every speed).
    ``backend``: 'compiled' marches revolutions in the compiled kernel
    (:mod:`tmm_core.compiled.reduced_periodic`), 'numpy' in this module's numpy path (the
    reference); default the model's backend. ``stages``: :class:`tmm_core.reduced_stages.StageCoefficients` of the
    model and
    ``basis`` to combine for this crank history when its stage angles are theirs (else, and by
    default, the stage matrices are built directly)."""

    def __init__(self, source: Discretization | HoldsModel, crank: CrankMotion, basis: ReducedBasis,
                 backend: str | None = None, stages: StageCoefficients | None = None):
        model = as_model(source)
        if any(link.viscoelastic is not None for link in model.links):
            raise InputError("the reduced model does not carry viscoelastic (standard-linear-solid) links; use "
                             "solver.tmm.model = 'full'")
        if model.axial_force == "quasi_static":
            raise InputError("the reduced model carries the step's own axial force (axial_force 'dynamic', the "
                             "default) or none (beam_column = false); axial_force 'quasi_static' needs "
                             "solver.tmm.model = 'full'")
        if model.axial_force == "dynamic" and set(model.dynamic_terms) not in ({"shortening", "axial_force"},
                                                                              {"shortening", "axial_force",
                                                                               "corotational"}):
            raise InputError("the reduced model carries both second-order terms or neither, with the second-order "
                             f"or the co-rotational strain (dynamic_terms {model.dynamic_terms!r})")
        self.model, self.basis = model, basis
        self.backend = model.backend if backend is None else choose_backend(backend)
        if basis.axial == "link" and self.backend == "compiled":
            raise InputError("the reduced model with one axial coordinate per link (ReducedOptions(axial='link'), a "
                             "prototype) has no compiled revolution yet; pass backend='numpy'")
        #: Compiled path: chord Newton iterations in the revolutions without the monodromy (see
        #: tmm_core.compiled.reduced_periodic); False refactorizes every iteration, as the numpy path does.
        self.chord = True
        self._kernel_args = self._factors = None
        self.counts = np.zeros(2, dtype=np.int64)   # last compiled revolution: Newton iterations, LUs
        self.nonlinear = model.axial_force == "dynamic"
        N = len(crank.t) - 1
        self.N, self.h = N, crank.dt
        self.stage_time, th, w, al = stage_points(crank)
        self.stage_angle = th
        terms = stages.at(model, th, w, al) if stages is not None and stages.matches(th) else \
            stage_terms(model, basis, th, w, al)
        self.T, self.Td, self.Tdd, self.Mr, self.Cr, self.Kr = terms.T, terms.Td, terms.Tdd, terms.Mr, terms.Cr, \
            terms.Kr
        self.f, self.om, self.alpha = terms.f, terms.om, terms.alpha
        self.fr = (terms.f[:, None, :] @ terms.T)[:, 0]
        # Drive torque at the stage points: the reaction part per unit load, the rigid crank's part.
        self.torque_map, self.torque_offset = terms.torque_map, terms.torque_offset
        self.strains = terms.strains           # gauge strains per unit coordinate (P, n_g, 2, r)
        seg = model.segments
        self.k, self.beta, self.G = seg.stiffness, seg.beta, geometric_matrices(seg.length)
        if basis.axial == "link":
            # Link level: the segments of each link (S_l), its axial compliance sum L/EA [m/N] and
            # its damping time (one per link: every segment of a link carries the link's).
            self.links_of = segment_links(model)
            self.compliance = self.links_of @ (1.0 / self.k)
            self.link_beta = self.links_of @ self.beta / self.links_of.sum(axis=1)
        self._segment_maps = None              # built on first use (numpy path only)
        self.A2 = RADAU_A @ RADAU_A
        self.stage_acc = None                  # stage accelerations of the last revolution (guesses)

    # -- the second-order term -----------------------------------------------------------------
    def second_order(self, P, eta, v, jacobian=True):
        """``N``, ``dN/deta``, ``dN/deta'`` at the stage points ``P`` (k,) for ``eta, v`` (k, r), and
        ``(P_s, Delta)`` per segment (k, n_seg): batched matrix products over the stages."""
        if self.model.strain_measure == "corotational":
            return self._second_order_corotational(P, eta, v, jacobian)
        if self._segment_maps is None:
            # Segment DOFs per unit coordinate at every stage point: bending (w0, theta0, w1,
            # theta1) ``Ed``, their rates ``Edd``, ``G Ed``, elongation ``a`` and its rate ``ad``.
            seg, T, Td = self.model.segments, self.T, self.Td
            wdofs = np.stack([seg.start + 1, seg.start + 2, seg.end + 1, seg.end + 2], axis=1)
            Ed = T[:, wdofs]                                                 # (P, n_seg, 4, r)
            self._segment_maps = (Ed, self.G[None] @ Ed, Td[:, wdofs], T[:, seg.end] - T[:, seg.start],
                                  Td[:, seg.end] - Td[:, seg.start])
        Ed, GEd, Edd, a, ad = (x[P] for x in self._segment_maps)
        if self.basis.axial == "link":
            return self._second_order_links(Ed, GEd, Edd, a, ad, eta, v, jacobian)
        k, beta = self.k, self.beta
        d, dd, Gd, b = _bending(Ed, GEd, Edd, eta, v)
        delta = 0.5 * np.sum(d * Gd, axis=-1)                         # (k, s)
        rate = np.sum(dd * Gd, axis=-1)
        F = k * (delta + beta * rate)
        e = (a @ eta[:, :, None])[..., 0]
        ed = (a @ v[:, :, None] + ad @ eta[:, :, None])[..., 0]
        Pax = k * (e + beta * ed) + F
        aT = np.swapaxes(a, 1, 2)
        N = (np.swapaxes(b, 1, 2) @ Pax[..., None] + aT @ F[..., None])[..., 0]
        if not jacobian:
            return N, None, None, Pax, delta
        F_eta = k[:, None] * (b + beta[:, None] * _shortening_rate_jacobian(GEd, Edd, dd, Gd))
        F_v = (k * beta)[:, None] * b
        P_eta = k[:, None] * (a + beta[:, None] * ad) + F_eta
        P_v = (k * beta)[:, None] * a + F_v
        bT = np.swapaxes(b, 1, 2)
        return N, bT @ P_eta + _geometric_stiffness(Ed, GEd, Pax) + aT @ F_eta, bT @ P_v + aT @ F_v, Pax, delta

    def _second_order_corotational(self, P, eta, v, jacobian):
        """:meth:`second_order` of co-rotational segments
        (:func:`tmm_core.second_order.corotational_node_forces`): ``N = T^T g`` with ``g`` the
        segments' internal forces beyond the linear ones that ``Kr`` and ``Cr`` carry, at ``q = T
        eta``, ``q' = T eta' + T' eta``; ``dN/deta = T^T (g_q T + g_v T')``, ``dN/deta' = T^T g_v
        T`` (per segment, on its six dofs). ``Delta`` is ``L (e - a)``."""
        dofs = segment_dofs(self.model.segments)
        Ts, Tds = self.T[P][:, dofs], self.Td[P][:, dofs]                    # (k, n_seg, 6, r)
        col = lambda x: x[:, None, :, None]  # noqa: E731  (k, r) against (k, n_seg, 6, r)
        zl = (Ts @ col(eta))[..., 0]
        vl = (Ts @ col(v) + Tds @ col(eta))[..., 0]
        out = corotational_node_forces(self.model.segments, zl, vl, jacobian)
        g, Ps, delta = out[:3]
        TsT = np.swapaxes(Ts, -1, -2)
        N = np.sum(TsT @ g[..., None], axis=1)[..., 0]
        if not jacobian:
            return N, None, None, Ps, delta
        g_z, g_v = out[3:]
        N_eta = np.sum(TsT @ (g_z @ Ts + g_v @ Tds), axis=1)
        N_v = np.sum(TsT @ (g_v @ Ts), axis=1)
        return N, N_eta, N_v, Ps, delta

    def _second_order_links(self, Ed, GEd, Edd, a, ad, eta, v, jacobian):
        """:meth:`second_order` with the axial force uniform along each link (``ReducedOptions.axial
        = 'link'``): ``P_l = (e_l + beta e_l' + Delta_l + beta Delta_l') / c_l`` with the link's
        chord elongation ``e_l``, the sum of its segments' shortenings ``Delta_l`` and its axial
        compliance ``c_l = sum L/EA``; ``N = sum_l P_l dDelta_l/deta + F_l de_l/deta``, ``F_l =
        (Delta_l + beta Delta_l') / c_l``. Returns the segments' ``P_s = P_l`` and, in place of
        their shortening, ``Delta_l / (c_l k_s)`` (the gauge's axial strain adds it over the
        segment's length, as the per-segment model adds its shortening: with one segment per link
        the two are the same)."""
        S, c, beta = self.links_of, self.compliance, self.link_beta
        d, dd, Gd, b_s = _bending(Ed, GEd, Edd, eta, v)               # b_s: dDelta_s/deta (k, s, r)
        delta = S @ (0.5 * np.sum(d * Gd, axis=-1))[..., None]        # (k, l, 1): per link
        rate = S @ np.sum(dd * Gd, axis=-1)[..., None]
        F = (delta + beta[:, None] * rate)[..., 0] / c               # (k, l)
        al, ald = S @ a, S @ ad                                       # link chords de/deta (k, l, r)
        e = (al @ eta[:, :, None])[..., 0]
        ed = (al @ v[:, :, None] + ald @ eta[:, :, None])[..., 0]
        Pl = (e + beta * ed) / c + F
        b = S @ b_s                                                   # (k, l, r)
        aT, bT = np.swapaxes(al, 1, 2), np.swapaxes(b, 1, 2)
        N = (bT @ Pl[..., None] + aT @ F[..., None])[..., 0]
        Ps = Pl @ S                                                   # (k, s): each segment its link's
        strain_length = ((delta[..., 0] / c) @ S) / self.k            # Delta_l / (c_l k_s)
        if not jacobian:
            return N, None, None, Ps, strain_length
        rate_eta = S @ _shortening_rate_jacobian(GEd, Edd, dd, Gd)
        F_eta = (b + beta[:, None] * rate_eta) / c[:, None]
        F_v = (beta / c)[:, None] * b
        P_eta = (al + beta[:, None] * ald) / c[:, None] + F_eta
        P_v = (beta / c)[:, None] * al + F_v
        return N, bT @ P_eta + _geometric_stiffness(Ed, GEd, Ps) + aT @ F_eta, bT @ P_v + aT @ F_v, Ps, strain_length

    # -- one step ----------------------------------------------------------------------------
    def step(self, n, eta, v, acc, nonlinear, jacobian=True, tol=compiled_reduced_periodic.STAGE_TOL,
             iterations=compiled_reduced_periodic.STAGE_ITERATIONS, scale=0.0):
        """Radau IIA step ``n`` from ``(eta, eta')`` with a guess ``acc`` (3, r) of the stage
        accelerations: ``(eta, eta')`` at its end, the stage accelerations and the step's Jacobian
        ``S`` (2r, 2r) with respect to ``(eta, eta')`` (from the last Newton matrix; None unless
        ``jacobian``)."""
        r = len(eta)
        h, A, A2, c = self.h, RADAU_A, self.A2, RADAU_C
        P = 3 * n + np.arange(3)
        Mr, Cr, Kr, fr = self.Mr[P], self.Cr[P], self.Kr[P], self.fr[P]
        prev = None             # the last update's size (compiled_reduced_periodic.STALL_FACTOR)
        for it in range(iterations):
            vs = v[None] + h * A @ acc
            es = eta[None] + h * c[:, None] * v[None] + h * h * A2 @ acc
            res = (Mr @ acc[..., None] + Cr @ vs[..., None] + Kr @ es[..., None])[..., 0] - fr
            Ce, Ke = Cr, Kr
            if nonlinear:
                Nn, N_e, N_v, _, _ = self.second_order(P, es, vs)
                res, Ce, Ke = res + Nn, Cr + N_v, Kr + N_e
            J = (h * A[:, :, None, None] * Ce[:, None] + h * h * A2[:, :, None, None] * Ke[:, None])
            J[np.arange(3), np.arange(3)] += Mr
            lu = lu_factor(J.transpose(0, 2, 1, 3).reshape(3 * r, 3 * r), check_finite=False)
            dacc = lu_solve(lu, -res.ravel(), check_finite=False).reshape(3, r)
            acc = acc + dacc
            # Relative to the step's own accelerations or ``scale`` (the largest of the steps before
            # it in the revolution): where all of them pass near zero the step's own scale sits
            # below the round-off floor of the update (seen at 120 rpm on the FE rig).
            dmax, limit = float(np.max(np.abs(dacc))), tol * (max(float(np.max(np.abs(acc))), scale) + 1e-300)
            if not nonlinear or dmax <= limit:
                break
            # An update that stopped shrinking near the tolerance: the round-off floor.
            if prev is not None and dmax <= compiled_reduced_periodic.STALL_FACTOR * limit and dmax >= 0.5 * prev:
                break
            prev = dmax
        else:
            raise ConvergenceError(f"reduced model: the stage equations of step {n} did not converge "
                                   f"(crank angle {math.degrees(float(self.stage_angle[3 * n + 2])):.6g} deg)")
        eta1, v1 = eta + h * v + h * h * A2[2] @ acc, v + h * A[2] @ acc
        if not jacobian:
            return eta1, v1, acc, None
        R = np.concatenate([Ke, Ce + h * c[:, None, None] * Ke], axis=2).reshape(3 * r, 2 * r)
        dA = -lu_solve(lu, R, check_finite=False).reshape(3, r, 2 * r)
        S = np.zeros((2 * r, 2 * r))
        S[:r, :r] = np.eye(r)
        S[:r, r:] = h * np.eye(r)
        S[r:, r:] = np.eye(r)
        S[:r] += h * h * np.tensordot(A2[2], dA, 1)
        S[r:] += h * np.tensordot(A[2], dA, 1)
        return eta1, v1, acc, S

    def revolution(self, x0, nonlinear, outputs=False, jacobian=True):
        """March one period from ``x0 = (eta, eta')``: ``(x_N, monodromy or None, outputs or None)``."""
        if self.compiled:
            return self._revolution_compiled(x0, nonlinear, outputs, jacobian)
        r = len(x0) // 2
        eta, v = x0[:r].copy(), x0[r:].copy()
        guess = self.stage_acc
        if guess is None:
            guess = np.zeros((self.N, 3, r))
            guess[0] = np.linalg.solve(self.Mr[0], self.fr[0] - self.Cr[0] @ v - self.Kr[0] @ eta)
        mono = np.eye(2 * r) if jacobian else None
        outs = np.zeros((self.N, 3, 1 + 2 * len(self.model.gauges))) if outputs else None
        h, A, A2 = self.h, RADAU_A, self.A2
        accs = np.empty((self.N, 3, r))
        scale = 0.0             # the largest stage acceleration so far (the Newton tolerance's floor)
        for n in range(self.N):
            start = guess[n] if self.stage_acc is not None or n == 0 else np.repeat(accs[n - 1][2:], 3, 0)
            eta0, v0 = eta, v
            eta, v, accs[n], S = self.step(n, eta, v, start, nonlinear, jacobian, scale=scale)
            scale = max(scale, float(np.max(np.abs(accs[n]))))
            if outputs:
                # Dense output: the collocation solution at the three stage points of the step.
                vs = v0[None] + h * A @ accs[n]
                es = eta0[None] + h * RADAU_C[:, None] * v0[None] + h * h * A2 @ accs[n]
                for i in range(3):
                    outs[n, i] = self.outputs(3 * n + i, es[i], vs[i], accs[n][i], nonlinear)
            if jacobian:
                mono = S @ mono
        self.stage_acc = accs
        return np.concatenate([eta, v]), mono, None if outs is None else outs.reshape(3 * self.N, -1)

    @property
    def compiled(self) -> bool:
        """Whether the revolutions run in the compiled kernel (the backend, as a flag)."""
        return self.backend == "compiled"

    def _revolution_compiled(self, x0, nonlinear, outputs, jacobian):
        """:meth:`revolution` in the compiled kernel (same guesses, same Newton tolerance)."""
        r = len(x0) // 2
        x0 = np.ascontiguousarray(x0, dtype=float)
        if self.stage_acc is None:
            guess = np.zeros((1, 3, r))
            guess[0] = np.linalg.solve(self.Mr[0], self.fr[0] - self.Cr[0] @ x0[r:] - self.Kr[0] @ x0[:r])
        else:
            guess = self.stage_acc
        x_end, mono, accs = np.empty(2 * r), np.empty((2 * r, 2 * r)), np.empty((self.N, 3, r))
        outs = np.empty((3 * self.N if outputs else 0, 1 + 2 * len(self.model.gauges)))
        if self._factors is None:
            # Every step's last Newton matrix (LU), kept for the next revolution's chord
            # iterations: 8 (3r)^2 N bytes (14 MB at r = 23, 360 steps).
            self._factors = (np.empty((self.N, 3 * r, 3 * r)), np.empty((self.N, 3 * r), dtype=np.int64),
                             np.zeros(self.N, dtype=np.bool_))
        counts = np.zeros(2, dtype=np.int64)
        stages, segments, output_maps = self._kernel_data()
        options = (bool(nonlinear), bool(jacobian), bool(outputs), self.stage_acc is not None, self.chord,
                   compiled_reduced_periodic.CHORD_START, compiled_reduced_periodic.CHORD_CONTRACTION,
                   self.model.strain_measure == "corotational")
        newton = (compiled_reduced_periodic.STAGE_TOL, compiled_reduced_periodic.STAGE_ITERATIONS)
        failed = kernel_binding.reduced_revolution()(
            x0, guess, options, (self.h, RADAU_A, self.A2, RADAU_C), stages, segments, output_maps, newton,
            self._factors, (x_end, mono, outs, accs, counts))
        self.counts = counts
        if failed >= 0:
            raise ConvergenceError(f"reduced model: the stage equations of step {failed} did not converge (crank "
                                   f"angle {math.degrees(float(self.stage_angle[3 * failed + 2])):.6g} deg)")
        self.stage_acc = accs
        return x_end, mono if jacobian else None, outs if outputs else None

    def _kernel_data(self):
        """The records the compiled revolution reads (built once): ``(stages, segments,
        output_maps)``, the stage matrices and basis ``(Mr, Cr, Kr, fr, T, Td)``, the segment data
        ``(seg_w, seg_u, G, k, beta)`` and the output maps (:meth:`output_maps`) with the gauges'
        sampling (:meth:`tmm_core.discretization.Discretization.gauge_reading`)."""
        if self._kernel_args is None:
            seg = self.model.segments
            c = np.ascontiguousarray
            stages = (c(self.Mr), c(self.Cr), c(self.Kr), c(self.fr), c(self.T), c(self.Td))
            K = self.model.seg_blocks
            # The co-rotational segments' record: start and (L, EA, beta, 4EI/L, 2EI/L, 4EI/L).
            sections = (seg.start.astype(np.int64), c(np.stack([seg.length, seg.EA, seg.beta, K[:, 2, 2], K[:, 2, 5],
                                                               K[:, 5, 5]], axis=1), dtype=float))
            segments = (np.stack([seg.start + 1, seg.start + 2, seg.end + 1, seg.end + 2], axis=1).astype(np.int64),
                        np.stack([seg.start, seg.end], axis=1).astype(np.int64), c(self.G, dtype=float),
                        c(self.k, dtype=float), c(self.beta, dtype=float), sections)
            output_maps = (*self.output_maps(), *self.model.gauge_reading())
            self._kernel_args = (stages, segments, output_maps)
        return self._kernel_args

    def output_maps(self):
        """The outputs of :meth:`outputs` but the shortening term, as maps of the stage state:
        ``out = O0 + Oe eta + Ov eta' + Oa eta''`` at every stage point, ``O0`` (P, n_out) and
        ``Oe, Ov, Oa`` (P, n_out, r). Torque: the loads are linear in ``(q, q', q'')`` and those
        in ``(eta, eta', eta'')`` (``q' = T eta' + T' eta``, ``q'' = T eta'' + 2 T' eta' + T'' eta``)."""
        model, cp = self.model, self.model.coupling
        w, m = self.torque_map, model.m_vec
        iu = np.arange(0, model.n_dof, 3)
        g_acc = -w * m                                  # torque per unit q'' [N m s^2 / m]
        g_vel = g_acc * model.aM_vec
        g_pos = np.zeros_like(w)
        if cp.coriolis:
            cw = w * 2.0 * m * self.om
            g_vel[:, iu + 1] += cw[:, iu]
            g_vel[:, iu] -= cw[:, iu + 1]
        if cp.centrifugal:
            g_pos += w * m * self.om ** 2
        if cp.angular_acceleration:
            cw = w * m * self.alpha
            g_pos[:, iu + 1] += cw[:, iu]
            g_pos[:, iu] -= cw[:, iu + 1]
        T, Td, Tdd = self.T, self.Td, self.Tdd
        n_g = len(model.gauges)
        O0 = np.zeros((len(T), 1 + 2 * n_g))
        Oe, Ov, Oa = (np.zeros((len(T), 1 + 2 * n_g, T.shape[-1])) for _ in range(3))
        # Batched products (matmul per stage point): numpy's einsum of these shapes was 2.5-7x
        # slower (~4.5 ms of a sweep point at r = 23, 1080 stage points).
        row = lambda g, X: np.matmul(g[:, None, :], X)[:, 0]   # noqa: E731  (P, n) . (P, n, r) -> (P, r)
        O0[:, 0] = np.einsum("pn,pn->p", w, self.f) + self.torque_offset
        Oe[:, 0] = row(g_pos, T) + row(g_vel, Td) + row(g_acc, Tdd)
        Ov[:, 0] = row(g_vel, T) + 2.0 * row(g_acc, Td)
        Oa[:, 0] = row(g_acc, T)
        if n_g:
            Oe[:, 1:] = self.strains.reshape(len(T), 2 * n_g, -1)
        return O0, Oe, Ov, Oa

    def outputs(self, p, eta, v, acc, nonlinear):
        """Drive torque and gauge strains at stage point ``p`` (step ``p // 3``)."""
        model = self.model
        T, Td, Tdd = self.T[p], self.Td[p], self.Tdd[p]
        q, qd, qdd = T @ eta, T @ v + Td @ eta, T @ acc + 2 * Td @ v + Tdd @ eta
        m = model.m_vec
        load = self.f[p] - m * (qdd + model.aM_vec * qd)
        cp, iu = model.coupling, np.arange(0, model.n_dof, 3)
        if cp.coriolis:
            c = 2.0 * m * self.om[p]
            load[iu] += c[iu] * qd[iu + 1]
            load[iu + 1] -= c[iu + 1] * qd[iu]
        if cp.centrifugal:
            load = load + m * self.om[p] ** 2 * q
        if cp.angular_acceleration:
            c = m * self.alpha[p]
            load[iu] += c[iu] * q[iu + 1]
            load[iu + 1] -= c[iu + 1] * q[iu]
        strains = self.strains[p] @ eta                              # (n_g, 2)
        if nonlinear and len(model.gauges):
            _, _, _, _, delta = self.second_order(np.array([p]), eta[None], v[None], jacobian=False)
            strains[:, 1] += model.gauge_shortening_strain(delta[0])
            if model.strain_measure == "corotational":
                strains[:, 0] += model.gauge_lag_strain(chord_lag(model.segments, q))
        return np.concatenate([[self.torque_map[p] @ load + self.torque_offset[p]], strains.ravel()])


def periodic_steady_state_reduced(source: Discretization | HoldsModel, speed_rad_s: float | None = None, *,
                                  crank: CrankMotion | None = None,
                                  start_angle: float = 0.0, options: ReducedOptions = ReducedOptions(),
                                  basis: ReducedBasis | None = None, newton_tolerance: float = 1e-9,
                                  newton_iterations: int = 20, backend: str | None = None,
                                  stages: StageCoefficients | None = None,
                                  initial_state: np.ndarray | None = None) -> PeriodicResult:
    """Periodic steady revolution of the reduced model of ``source`` (a
    :class:`tmm_core.discretization.Discretization` or the one a :class:`tmm_core.TimeDomain`
    holds) at constant ``speed_rad_s`` [rad/s]
    (``options.steps`` steps per revolution) or over one period of a periodic ``crank`` history
    (N + 1 samples; its samples are the steps). Returns a :class:`tmm_core.periodic.PeriodicResult`
    (outputs at the 3 collocation points of each step, 3N samples: the continuous solution, so that
    sampling does not clip sharp peaks; Floquet multipliers of the reduced model, the residual of a
    revolution marched from the periodic state, the periodic ``state`` ``(eta, eta')``). ``basis``:
    reuse one (it depends on the geometry only); else built from ``options``. ``backend``,
    ``stages``: see :class:`ReducedModel`. ``initial_state``: a guess of the periodic state
    ``(eta, eta')`` (2r; e.g. a nearby speed's with the same basis): the nonlinear model then
    iterates Anderson-accelerated revolutions from it (:mod:`tmm_core.anderson`) instead of the
    linear pass, falling back to Newton shooting from their best iterate when they stall; the
    tolerance is the same, and the multipliers are those of the full (2r x 2r) monodromy at the
    converged orbit."""
    full = as_model(source)
    if crank is None:
        if not speed_rad_s:
            raise InputError("reduced model: give a non-zero crank speed or a crank history")
        crank = CrankMotion.constant_speed(speed_rad_s, step_deg=360.0 / options.steps, revolutions=1.0,
                                           start_angle=start_angle)
    else:
        turn = abs(crank.angle[-1] - crank.angle[0])
        if abs(turn - 2 * math.pi) > 1e-9 * 2 * math.pi:
            raise InputError("reduced model: the crank history must span exactly one revolution")
    if basis is None:
        basis = build_basis(full, float(crank.angle[0]), options)
    model = ReducedModel(full, crank, basis, backend, stages)
    r = basis.size
    info = {"model": "reduced", "size": r, "modes": basis.n_modes, "static": basis.n_static, "steps_per_revolution":
            model.N, "dt_s": model.h}
    solved = fp = None
    if model.nonlinear and initial_state is not None:
        fp, solved = _reduced_from_guess(model, np.asarray(initial_state, dtype=float), newton_tolerance, info)
    if solved is None:
        x_lin, mono, _ = model.revolution(np.zeros(2 * r), False)
        x0 = np.linalg.solve(np.eye(2 * r) - mono, x_lin)
        if model.nonlinear:
            try:
                solved = _reduced_newton(model, x0, mono, newton_tolerance, newton_iterations)
            except ConvergenceError as exc:
                solved = _past_newton(model, x0, fp, newton_tolerance, newton_iterations, info, exc)
            info["newton_iterations"] = solved[-1]
        else:
            xN, _, outs = model.revolution(x0, False, outputs=True, jacobian=False)
            solved = (x0, xN, mono, outs, 0)
    x0, xN, mono, outs, _ = solved
    residual = residual_of(x0, xN)
    mult = np.linalg.eigvals(mono)
    mult = mult[np.argsort(-np.abs(mult))]
    return PeriodicResult(model.stage_time, model.stage_angle, full.outputs.torque(outs), full.outputs.split(outs),
                          mult, residual, info, x0)


def _bending(Ed, GEd, Edd, eta, v):
    """Per segment at the stages (``Ed``, ``GEd``, ``Edd`` (k, s, 4, r) as
    :meth:`ReducedModel.second_order` reads them; ``eta``, ``v`` (k, r)): the bending DOFs ``d``,
    their rates ``dd`` and ``G d`` (k, s, 4), and the shortening's derivative ``dDelta/deta = Ed^T
    G d`` (k, s, r)."""
    col = lambda x: x[:, None, :, None]  # noqa: E731  (k, r) -> (k, 1, r, 1) against (k, s, 4, r)
    d = (Ed @ col(eta))[..., 0]
    dd = (Ed @ col(v) + Edd @ col(eta))[..., 0]
    Gd = (GEd @ col(eta))[..., 0]
    return d, dd, Gd, (np.swapaxes(GEd, -1, -2) @ d[..., None])[..., 0]


def _shortening_rate_jacobian(GEd, Edd, dd, Gd):
    """``dDelta'/deta = Edd^T G d + Ed^T G dd`` per segment (k, s, r) (``G dd = GEd v + G Edd
    eta``), from :func:`_bending`'s ``dd`` and ``G d``."""
    return (np.swapaxes(Edd, -1, -2) @ Gd[..., None])[..., 0] + (np.swapaxes(GEd, -1, -2) @ dd[..., None])[..., 0]


def _geometric_stiffness(Ed, GEd, P):
    """``sum_s P_s Ed_s^T G Ed_s`` (k, r, r): the second-order term's stiffness at the segments'
    axial forces ``P`` (k, s) [N]."""
    k, ns, r = len(Ed), Ed.shape[1], Ed.shape[-1]
    return np.swapaxes((Ed * P[..., None, None]).reshape(k, 4 * ns, r), 1, 2) @ GEd.reshape(k, 4 * ns, r)


def _past_newton(model: ReducedModel, x_lin, fp, tolerance, iterations, info, error):
    """Where Newton from the linear start ``x_lin`` finds no orbit (``error``): without a guess,
    Anderson-accelerated revolutions from ``x_lin`` (a march over revolutions, which settles on a
    stable orbit: Newton's first updates near a resonance left the stage equations' range on the
    FE rig at 1 % damping, on its flexible crank, on Bahgat-Willmert's rig and on Shin's
    multiloop linkage, whose full models solve); with a guess, Newton from its stalled
    revolutions' best iterate ``fp`` (the branch carried on; tried second, so that where the
    linear start finds an orbit the answer is a solve's without a guess; see
    tmm_core.periodic._past_linear_start). Returns ``solved`` as :func:`_reduced_newton`, or
    raises ``error``."""
    if fp is None:
        _, solved = _reduced_from_guess(model, x_lin, tolerance, info)
        if solved is None:
            raise error
        info["start"] = "linear, revolutions"
        return solved
    if fp.residual == np.inf:
        raise error
    try:
        solved = _reduced_newton(model, fp.x, None, tolerance, iterations)
    except ConvergenceError:
        raise error from None
    info["start"] = "guess, Newton"
    return solved


def _reduced_newton(model: ReducedModel, x0, jac, tolerance, iterations):
    """Newton shooting from ``x0`` with the Jacobian ``jac`` (the monodromy; None: computed at
    ``x0``); the monodromy (the dear part: a multi-column solve per step) is kept while the
    residual falls by a factor 4 per iteration (chord steps) and recomputed otherwise. Returns
    ``(x0, x_N, monodromy at x0, outputs, iterations)``."""
    n = len(x0)
    fresh, last, before, mono = False, math.inf, math.inf, jac
    for it in range(1, iterations + 1):
        # The monodromy also in the revolution predicted to converge (the last two residuals' rate
        # carried on): that revolution then carries the converged orbit's monodromy (its
        # multipliers) without an extra one after it.
        near = last * min(last / before, 1.0) < tolerance
        xN, m_new, outs = model.revolution(x0, True, outputs=True,
                                           jacobian=jac is None or near or (not fresh and it > 1))
        if m_new is not None:
            jac, mono, fresh = m_new, m_new, True
        if not np.all(np.isfinite(xN)):
            raise ConvergenceError("reduced model: Newton shooting left the range of the model")
        residual = residual_of(x0, xN)
        if residual < tolerance:
            if m_new is None:
                # The chord Jacobian is an earlier iterate's (or the linear model's): its
                # eigenvalues missed the converged orbit's largest multiplier by up to 0.13 near
                # buckling (FE rig, 410 rpm). The multipliers are the converged orbit's.
                _, mono, _ = model.revolution(x0, True, jacobian=True)
            return x0, xN, mono, outs, it
        if residual > CHORD_RATE * last:
            fresh = False
        before, last = last, residual
        x0 = x0 + np.linalg.solve(np.eye(n) - jac, xN - x0)
    raise ConvergenceError(f"reduced model: Newton shooting did not converge in {iterations} "
                           f"iterations (last relative residual {residual:.3g})")


def _reduced_from_guess(model: ReducedModel, guess, tolerance, info):
    """Anderson-accelerated revolutions from ``guess``, then one revolution with the monodromy and
    the outputs from the converged state. Returns ``(fixed point, solved)``: ``solved`` as
    :func:`_reduced_newton` returns it, or None when the revolutions stalled (the fixed point is
    then their best iterate)."""

    def revolve(x):
        x_end, _, _ = model.revolution(x, True, jacobian=False)
        return x_end, None

    fp = anderson(revolve, guess, block_weights(guess, 2), AndersonOptions(tolerance))
    info["anderson_revolutions"], info["start"] = fp.revolutions, "linear"
    if not fp.converged:
        return fp, None
    try:
        # The outputs and the monodromy at the converged orbit (this revolution's residual is the
        # reported one).
        xN, mono, outs = model.revolution(fp.x, True, outputs=True, jacobian=True)
    except ConvergenceError:
        return fp, None
    residual = residual_of(fp.x, xN)
    if residual >= tolerance:
        return fp, None
    info["start"], info["newton_iterations"] = "guess", 0
    return fp, (fp.x, xN, mono, outs, 0)
