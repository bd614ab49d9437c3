"""The compiled time step's loads, the factorizations kept per configuration, and a step's solve
on them (numba): what the compiled march (:mod:`tmm_core.compiled.march`) and the periodic
solver's linearized revolutions (:mod:`tmm_core.compiled.periodic`) share of a step.

A step's loads linear in the integrator history (inertia, Coriolis and Kelvin-Voigt history:
:func:`history_loads`) are written here once, for M columns of states, and mirror
:func:`tmm_core.time_step.step_loads`; the march adds the configuration's rigid-body loads.

The load-to-response maps of :mod:`tmm_core.step_data` cost ``n_dof + 1`` solves per
configuration to build and ``O(n_dof^2)`` memory and work per step: quadratic in the segments.
Here every configuration's factorization (:func:`tmm_core.compiled.riccati.factor_configuration`:
the members' Riccati factors, the joint stiffness and its LU factors) is stored as it is, and a
step's iteration solves its loads on it (:func:`tmm_core.compiled.structure.solve_loads`: the load
sweep, the joint solve and the back-substitution): ``O(segments)`` memory and work, linear in
the segments. The outputs (drive torque, gauge strains) are affine in the joint reactions and the
gauges' station states; their coefficients per configuration come from the Python side
(:func:`tmm_core.step_data.compiled_factors`).

Owns: a step's history loads (:func:`history_loads`), the co-rotational segment's pseudo-loads
(:func:`corotational_segment`), the stored factorizations (:func:`factor_range`,
a range of a batch's configurations) and the solve of one set of node loads on one of them
(:func:`factored_solve`). Boundaries: the factorization and
the load solve themselves are :mod:`tmm_core.compiled.riccati` and :mod:`tmm_core.compiled.structure`.
"""
from __future__ import annotations

import numpy as np

from . import riccati, structure

factor_configuration = riccati.factor_configuration
factor_scratch = riccati.factor_scratch
solve_loads = structure.solve_loads

#: The stored arrays of a batch (name: dimensions, the batch axis included), in the order of the
#: tuple the march reads; :data:`INTEGER` ones are int64, the others float64.
STORED = {"lead": 5, "prefix": 5, "lcol": 3, "B0": 4, "T220": 4, "SP": 4, "TL": 4, "Gis": 5, "Xs": 5, "BGis": 5,
          "HGis": 5, "Cs": 5, "Ds": 5, "Af": 4, "Bf": 4, "firsts": 2, "Kfull": 3, "lu": 3, "piv": 2}
INTEGER = ("firsts", "piv")


def history_loads(k, h_a, h_v, model, omega, flags, L):
    """The loads [N, N m] of a step at configuration ``k`` that are linear in the integrator
    history ``h_a, h_v``, into ``L``: the inertia history with mass damping, the Coriolis terms
    and the Kelvin-Voigt history; :func:`tmm_core.time_step.step_loads` with ``rigid=False``.
    For M columns of states at once, ``h_a``, ``h_v`` and ``L`` hold n_dof rows of M values,
    flattened (value ``(i, r)`` at ``i M + r``; M = 1 for a march). ``model`` is the model record
    (:meth:`tmm_core.discretization.Discretization.kernel_model`), ``omega`` (B, n_dof) each DOF's
    link speed [rad/s] per configuration, ``flags = (coriolis, has_kv)``."""
    m, aM, beta_node, seg_start, _end, _length, _EA, _beta, seg_K, _gauge_reading = model
    coriolis, has_kv = flags
    n = m.shape[0]
    M = h_a.shape[0] // n
    for i in range(n):
        for r in range(i * M, (i + 1) * M):
            L[r] = -m[i] * (h_a[r] + aM[i] * h_v[r])
    if coriolis:
        # At u rows the w-velocity history of the same node, at w rows the u-velocity one.
        for node in range(n // 3):
            u, w = 3 * node, 3 * node + 1
            cu, cw = 2.0 * m[u] * omega[k, u], 2.0 * m[w] * omega[k, w]
            for r in range(M):
                L[u * M + r] += cu * h_v[w * M + r]
                L[w * M + r] -= cw * h_v[u * M + r]
    if has_kv:
        # Column by column, a segment's 6x6 block times its history velocities: a march (M = 1)
        # runs the tight inner loops it needs per step.
        for r in range(M):
            for s in range(seg_start.shape[0]):
                i0 = seg_start[s]
                for p in range(6):
                    acc = 0.0
                    for q in range(6):
                        acc += seg_K[s, p, q] * h_v[(i0 + q) * M + r]
                    L[(i0 + p) * M + r] -= beta_node[i0 + p] * acc


def corotational_segment(section, z, v, P, P0):
    """One co-rotational segment's pseudo-loads on its ``(u0, w0, theta0, u1, w1, theta1)``, its
    shortening force ``F`` [N] and ``L (e - a)`` [m] (an 8-tuple), from its six displacements
    ``z`` and velocities ``v``, its axial force ``P`` and the factorization's ``P0`` [N];
    ``section = (L, EA, beta, k00, k01, k11)`` with the bending stiffness on the end rotations
    (4EI/L, 2EI/L, 4EI/L). :func:`tmm_core.second_order.corotational_pseudo_loads` is the
    reference (its formulas, term by term)."""
    L, EA, beta, k00, k01, k11 = section
    du, dw, q0, q1 = z[3] - z[0], z[4] - z[1], z[2], z[5]
    dud, dwd = v[3] - v[0], v[4] - v[1]
    x = L + du
    l = np.sqrt(x * x + dw * dw)
    if l == 0.0 or not np.isfinite(l):
        # A diverging iterate (the chord collapsed or overflowed): non-finite forces, which the
        # march reports as the step's divergence, rather than a division by zero in the kernel.
        nan = np.nan
        return nan, nan, nan, nan, nan, nan, nan, nan
    c, sn = x / l, dw / l
    b = np.arctan2(dw, x)
    bd = (c * dwd - sn * dud) / l
    t0, t1 = q0 - b, q1 - b
    t0d, t1d = v[2] - bd, v[5] - bd
    # l - x without cancellation where the chord points forward (x > 0); folded back, l - x itself.
    chord = dw * dw / (l + x) if x > 0.0 else l - x
    excess = chord + L / 60.0 * (4.0 * t0 * t0 - 2.0 * t0 * t1 + 4.0 * t1 * t1)
    rate = (c - 1.0) * dud + sn * dwd + L / 30.0 * ((4.0 * t0 - t1) * t0d + (4.0 * t1 - t0) * t1d)
    F = EA / L * (excess + beta * rate)
    g = P * L / 30.0
    r0, r1 = t0 + beta * t0d, t1 + beta * t1d
    m0 = k00 * r0 + k01 * r1 + g * (4.0 * t0 - t1)
    m1 = k01 * r0 + k11 * r1 + g * (4.0 * t1 - t0)
    # The solver's bending forces: K (d + beta d') (the chord's angle linearized) and P0 G d.
    e0 = q0 - dw / L + beta * (v[2] - dwd / L)
    e1 = q1 - dw / L + beta * (v[5] - dwd / L)
    kb0, kb1 = k00 * e0 + k01 * e1, k01 * e0 + k11 * e1
    g0 = (-36.0 * dw + 3.0 * L * (q0 + q1)) / (30.0 * L)
    g1 = (-3.0 * dw + L * (4.0 * q0 - q1)) / 30.0
    g3 = (-3.0 * dw + L * (4.0 * q1 - q0)) / 30.0
    axial = P * c + (m0 + m1) * sn / l - (P - F)
    shear = P * sn - (m0 + m1) * c / l - (-(kb0 + kb1) / L - P0 * g0)
    return axial, shear, -(m0 - kb0 - P0 * g1), -axial, -shear, -(m1 - kb1 - P0 * g3), F, excess


def corotational_tangent(section, z, v, P, own, P0, jz, jv, jp, Fz, Fv):
    """The derivatives of one co-rotational segment's pseudo-loads (:func:`corotational_segment`)
    by its six displacements ``z`` and six velocities ``v`` into ``jz``, ``jv`` (6, 6), by its
    axial force ``P`` [N] into ``jp`` (6,), and of its shortening force into ``Fz``, ``Fv`` (6,).
    ``own``: ``P`` is the state's own axial force, ``EA/L ((u1 - u0) + beta (u1 - u0)') + F``
    (:func:`tmm_core.compiled.reduced_periodic.corotational_forces` returns it), whose dependence
    on the state is then in the derivatives (and ``jp`` is zero). Forward mode, one direction at a
    time over ``(x, y, q0, q1, x', y', q0', q1', P)`` (``x = L + u1 - u0``, ``y = w1 - w0``), scalar
    by scalar; :func:`tmm_core.second_order._corotational_tangent` is the reference (its formulas,
    term by term)."""
    L, EA, beta, k00, k01, k11 = section
    x, y, q0, q1 = L + z[3] - z[0], z[4] - z[1], z[2], z[5]
    xd, yd = v[3] - v[0], v[4] - v[1]
    l2 = x * x + y * y
    l = np.sqrt(l2)
    c, s = x / l, y / l
    b = np.arctan2(y, x)
    bd = (x * yd - y * xd) / l2
    t0, t1 = q0 - b, q1 - b
    t0d, t1d = v[2] - bd, v[5] - bd
    h0, h1 = L / 30.0 * (4.0 * t0 - t1), L / 30.0 * (4.0 * t1 - t0)
    m0 = k00 * (t0 + beta * t0d) + k01 * (t1 + beta * t1d) + P * h0
    m1 = k01 * (t0 + beta * t0d) + k11 * (t1 + beta * t1d) + P * h1
    M = m0 + m1
    for i in range(9):
        dx, dy, dq0, dq1 = 1.0 * (i == 0), 1.0 * (i == 1), 1.0 * (i == 2), 1.0 * (i == 3)
        dxd, dyd, dq0d, dq1d, dP = 1.0 * (i == 4), 1.0 * (i == 5), 1.0 * (i == 6), 1.0 * (i == 7), 1.0 * (i == 8)
        db = (-y * dx + x * dy) / l2
        dbd = ((yd - 2.0 * x * bd) * dx + (-xd - 2.0 * y * bd) * dy - y * dxd + x * dyd) / l2
        dt0, dt1, dt0d, dt1d = dq0 - db, dq1 - db, dq0d - dbd, dq1d - dbd
        dh0, dh1 = L / 30.0 * (4.0 * dt0 - dt1), L / 30.0 * (4.0 * dt1 - dt0)
        dexcess = (c - 1.0) * dx + s * dy + h0 * dt0 + h1 * dt1
        drate = (-s * bd * dx + c * bd * dy + (c - 1.0) * dxd + s * dyd + h0 * dt0d + h1 * dt1d + t0d * dh0
                 + t1d * dh1)
        dF = EA / L * (dexcess + beta * drate)
        if own:
            dP = EA / L * (dx + beta * dxd) + dF
        dm0 = k00 * (dt0 + beta * dt0d) + k01 * (dt1 + beta * dt1d) + h0 * dP + P * dh0
        dm1 = k01 * (dt0 + beta * dt0d) + k11 * (dt1 + beta * dt1d) + h1 * dP + P * dh1
        dM = dm0 + dm1
        dc, ds = (s * s * dx - c * s * dy) / l, (-c * s * dx + c * c * dy) / l
        dsl = (-2.0 * c * s * dx + (c * c - s * s) * dy) / l2
        dcl = ((s * s - c * c) * dx - 2.0 * c * s * dy) / l2
        daxial = (c - 1.0) * dP + P * dc + s / l * dM + M * dsl + dF
        de0 = dq0 - dy / L + beta * (dq0d - dyd / L)
        de1 = dq1 - dy / L + beta * (dq1d - dyd / L)
        dkb0, dkb1 = k00 * de0 + k01 * de1, k01 * de0 + k11 * de1
        dg0 = -1.2 / L * dy + 0.1 * (dq0 + dq1)
        dg1 = -0.1 * dy + L / 30.0 * (4.0 * dq0 - dq1)
        dg3 = -0.1 * dy + L / 30.0 * (4.0 * dq1 - dq0)
        dshear = s * dP + P * ds - c / l * dM - M * dcl + (dkb0 + dkb1) / L + P0 * dg0
        dmom0 = -(dm0 - dkb0 - P0 * dg1)
        dmom1 = -(dm1 - dkb1 - P0 * dg3)
        column = (daxial, dshear, dmom0, -daxial, -dshear, dmom1)
        if i == 8:
            for p in range(6):
                jp[p] = 0.0 if own else column[p]
            continue
        # Direction i of (x, y, q0, q1) is dof (u1, w1, theta1 less u0, w0, theta0) of z or v.
        J, Fj, d = (jz, Fz, i) if i < 4 else (jv, Fv, i - 4)
        for p in range(6):
            if d < 2:
                J[p, d + 3] = column[p]
                J[p, d] = -column[p]
            else:
                J[p, 2 if d == 2 else 5] = column[p]
        if d < 2:
            Fj[d + 3] = dF
            Fj[d] = -dF
        else:
            Fj[2 if d == 2 else 5] = dF


def chord_lag(L, du, dw):
    """A segment's chord lag ``dw/L - b`` [rad] (``b`` its chord's exact angle) from its length
    ``L`` and end displacement differences ``du, dw`` [m];
    :func:`tmm_core.second_order.chord_lag` is the reference."""
    return dw / L - np.arctan2(dw, L + du)


def factor_range(b_start, b_stop, segments, configuration, joints, checks, stored):
    """Factorize the configurations ``b_start <= b < b_stop`` into ``stored`` (the arrays of
    :data:`STORED`, each with the batch axis first; the records ``segments``, ``configuration``,
    ``joints`` and ``checks`` as :func:`tmm_core.compiled.riccati.factor_configuration`)."""
    lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv = stored
    scratch = factor_scratch(lu.shape[1])
    for bi in range(b_start, b_stop):
        factors = (lead[bi], prefix[bi], lcol[bi], B0[bi], T220[bi], SP[bi], TL[bi], Gis[bi], Xs[bi], BGis[bi],
                   HGis[bi], Cs[bi], Ds[bi], Af[bi], Bf[bi], firsts[bi], Kfull[bi], lu[bi], piv[bi])
        factor_configuration(bi, segments, configuration, joints, checks, factors, scratch)


def march_arrays(factors, n_nodes: int, n_seg: int, n_out: int) -> tuple | None:
    """``(layout, stored, work, Ocx)``, what the compiled march reads of a
    :class:`tmm_core.configuration_batch.StepFactors` (and the scratch arrays of its solve); None
    for ``factors`` None (a batch with maps). The march tests its record for None, and numba
    prunes those branches when it compiles the march for the maps: a maps run does not compile the
    stored-factorization solve into the march (5 s of a first run's compilation)."""
    if factors is None:
        return None
    arrays = dict(zip(STORED, factors.stored))
    seg_off, _, _, _, _, gauge_nodes = factors.layout
    mmax = 2 * int(np.max(np.diff(seg_off))) + 1
    work = work_arrays(len(seg_off) - 1, mmax, n_nodes, n_seg, arrays["Kfull"].shape[1], arrays["lu"].shape[1],
                       len(gauge_nodes))
    return factors.layout, factors.stored, work, factors.Ocx


def work_arrays(M, mmax, Nn, S, nd, nf, G):
    """The scratch arrays of :func:`factored_solve` (allocated once per march)."""
    return (np.zeros((1, 1, Nn, 3)), np.zeros((1, 0, Nn, 2, 6)), np.zeros((1, 1, nd)), np.zeros((1, 1, nd)),
            np.zeros((1, 3 * Nn, 1)), np.zeros((1, S, 1)), np.zeros((1, G, 6, 1)),
            np.zeros((M, mmax + 1, 6)), np.zeros((M, mmax, 3)), np.zeros((M, mmax + 1, 3)), np.zeros((M, 3)),
            np.zeros(6), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(nd),
            np.zeros((nf, 1)), np.zeros(nd), np.zeros(6), np.zeros(3), np.zeros(3), np.zeros(6), np.zeros(6),
            np.zeros((mmax + 1, 3)), np.zeros((Nn, 2, 6)), np.array([0, 1, 2]), np.array([5, 4, 3]))


def factored_solve(k, f, layout, stored, work, zn, N, y):
    """Solve configuration ``k`` of the stored factorizations for the stacked local node loads
    ``f (n_dof)`` [N, N m] (the configuration's distributed loads included): node displacements
    ``zn (n_dof)`` [m, rad] (left side of each node, local frames), segment axial forces ``N (S)``
    [N, tension +] (mean of the two ends) and ``y (nd + 6 G)``: the joint reactions, then the
    right-side state of each gauge node (the inputs of the output functionals).
    ``layout = (seg_off, rigid, angle (B, M), ends, free, gauge nodes)``."""
    seg_off, rigid, angle, ends, free, gnode = layout
    lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv = stored
    (Fn, states, q_out, reaction, zout, nout, gstate, pcol, ys, cs, af, t6, t1, t2, a, c, yv, v3, rfull, xf, qv,
     zl, zs, ze, qe, S0, zj, stn, zi, fi) = work
    Nn = Fn.shape[2]
    for node in range(Nn):
        for r in range(3):
            Fn[0, 0, node, r] = f[3 * node + r]
    nd = Kfull.shape[1]
    # Entry 0 of a one-entry batch: read from the shape, not written as a constant, so that numba
    # compiles solve_loads once (a constant would be typed as a literal and compile a second,
    # specialised solve_loads).
    entry = Fn.shape[0] - 1
    factors = (lead[k], prefix[k], lcol[k], B0[k], T220[k], SP[k], TL[k], Gis[k], Xs[k], BGis[k], HGis[k], Cs[k],
               Ds[k], Af[k], Bf[k], firsts[k], Kfull[k], lu[k], piv[k])
    joints = (seg_off, rigid, angle[k:k + 1], ends, free)
    outputs = (states, q_out, reaction, zout, nout, gnode, gstate)
    load_work = (pcol, ys, cs, af, t6, t1, t2, a, c, yv, v3, rfull, xf, qv, zl, zs, ze, qe, S0, zj, stn, zi, fi)
    solve_loads(entry, Fn, joints, outputs, factors, load_work)
    for i in range(3 * Nn):
        zn[i] = zout[0, i, 0]
    for s in range(N.shape[0]):
        N[s] = nout[0, s, 0]
    for i in range(nd):
        y[i] = reaction[0, 0, i]
    for g in range(gnode.shape[0]):
        for r in range(6):
            y[nd + 6 * g + r] = gstate[0, g, r, 0]
