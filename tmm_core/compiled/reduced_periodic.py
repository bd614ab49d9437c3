"""Compiled revolution of the reduced transfer-matrix model (numba).

:class:`tmm_core.reduced_periodic.ReducedModel` (``step``, ``second_order``, ``outputs``, numpy)
is the reference; :func:`revolution` marches the same equations over one period in one compiled
loop: per step the Newton iteration on the 3-stage Radau IIA equations (3r unknowns: the stage
accelerations) with the second-order term and its Jacobian, a dense LU of the 3r x 3r Newton
matrix, the step's Jacobian ``S`` and its product into the monodromy, and the outputs at the
three collocation points. ``tests/test_reduced.py`` checks it against the numpy path.

Why compiled: the numpy path spends 0.4-1 ms per step in Python calls, small batched products and
LAPACK calls on 69 x 69 matrices. Here a step costs its arithmetic (FE rig, r = 23, CPU time): a
Newton matrix about 50 us (its LU 20 us, the second-order Jacobian 3 x 7 us), a chord iteration
about 12 us, ``S`` and its product into the monodromy 30 us.

Newton (``chord``, the nonlinear model): an iteration reuses the last factorization while the
updates shrink by ``CHORD_CONTRACTION`` or faster, and a step starts on the factorization it kept
from the previous revolution (once the shooting has nearly converged most steps need none). A
chord iteration stops on an update below ``tol`` whose error estimate (contraction times update)
is 1000x below it, a Newton iteration on an update below ``tol``: either way the stage equations
are solved to their round-off floor (about 1e-12 of the accelerations). With the monodromy a step
converged on an old factorization iterates once on a fresh one (``S`` from the solution's matrix).

The second-order term works in node space: ``q = T eta``, ``q' = T eta' + T' eta``, the segment
forces and their node loads ``g``, ``N = T^T g``; its Jacobian is ``L^T R + T^T Z`` (rank-one
terms of every segment stacked in ``L``/``R``, the geometric stiffness ``Z = P G T``): matrix
products (BLAS through ``np.dot``, single-threaded at these sizes). The outputs are linear in the
stage state (maps built once by the caller) plus the shortening of the gauge segments.

Compiled on first use and cached on disk (numba ``cache=True``, in the compiled layer's keyed
folder: an edit of any kernel file starts a fresh cache, :mod:`tmm_core.compiled.cache`).

Owns: the compiled revolution of the reduced model. Boundaries: the equations and the data (stage
matrices, output maps) come from tmm_core.reduced_periodic; no numpy fallback here.
"""
from __future__ import annotations

import numpy as np

from .dense import dot, lu_factor, lu_solve, lu_solve_many  # the compiled ones once bound (tmm_core.compiled.binding)
from .time_step import chord_lag, corotational_segment, corotational_tangent


#: Refactorize while the chord iteration contracts slower than this (update ratio).
CHORD_CONTRACTION = 0.03
#: The stage Newton iteration's tolerance (update relative to the stage accelerations) and
#: iteration limit, in the numpy path and the compiled one.
STAGE_TOL = 1e-10
STAGE_ITERATIONS = 25
#: A Newton update that no longer shrinks (at least half the last) while within this factor of the
#: tolerance is the round-off floor of an ill-conditioned Newton matrix: the step has converged
#: (Alexander-Lawrence: condition 6e10, updates stall near 2e-10 of the accelerations against a
#: tolerance of 1e-10). Used by the numpy path too.
STALL_FACTOR = 1e3
#: After a refactorization, keep the factorization for the next iteration if the relative update
#: was at most this (the chord iteration then contracts by about this factor: the Newton matrix
#: moves in proportion to the state).
CHORD_START = 0.1
def stage_states(h, A, A2, c, eta, v, acc, es, vs):
    """Collocation state at the three stages: ``eta'_i = eta' + h sum_j A_ij acc_j``,
    ``eta_i = eta + h c_i eta' + h^2 sum_j (A^2)_ij acc_j``."""
    r = eta.shape[0]
    for i in range(3):
        a1 = h * A[i, 0], h * A[i, 1], h * A[i, 2]
        a2 = h * h * A2[i, 0], h * h * A2[i, 1], h * h * A2[i, 2]
        hc = h * c[i]
        for j in range(r):
            vs[i, j] = v[j] + (a1[0] * acc[0, j] + a1[1] * acc[1, j] + a1[2] * acc[2, j])
            es[i, j] = eta[j] + hc * v[j] + (a2[0] * acc[0, j] + a2[1] * acc[1, j] + a2[2] * acc[2, j])


def node_state(Tp, Tdp, eta, v, q, dq):
    """The node displacements ``q = T eta`` and rates ``q' = T eta' + T' eta`` at one stage point
    (BLAS matrix-vector products), into ``q`` and ``dq``."""
    np.dot(Tp, eta, q)
    np.dot(Tp, v, dq)
    dq += np.dot(Tdp, eta)


def second_order(Tp, Tdp, eta, v, jac, segments, work, terms):
    """Second-order term at one stage point (basis ``Tp``, ``Tdp`` = T' theta', (n, r)) for the
    coordinates ``eta``, ``v``: ``N`` (r,) and, with ``jac``, ``Ne = dN/deta``, ``Nv = dN/deta'``
    (r, r). Segment ``s``: bending DOFs ``seg_w[s]`` (w0, theta0, w1, theta1), axial DOFs
    ``seg_u[s]`` (u0, u1), geometric matrix ``G[s]`` [1/m], stiffness ``k[s]`` = EA/L [N/m],
    damping ``beta[s]`` [s]. Same quantities as ReducedModel.second_order (its notation).
    Work arrays: ``q, dq, g`` (n,), ``w4`` (4, 4), ``Lt, Re, Rv`` (2 n_seg, r), ``Z`` (n, r).
    The loops over the r coordinates run on one-dimensional row views (they vectorize).
    Records: ``segments = (seg_w, seg_u, G, k, beta)``, ``work = (q, dq, g, w4, Lt, Re, Rv,
    Z)``, ``terms = (N, Ne, Nv)`` (written)."""
    seg_w, seg_u, G, k, beta, _sections = segments
    q, dq, g, w4, Lt, Re, Rv, Z = work
    N, Ne, Nv = terms
    n, r = Tp.shape
    ns = seg_w.shape[0]
    node_state(Tp, Tdp, eta, v, q, dq)
    g[:] = 0.0
    if jac:
        Z[:, :] = 0.0
    d, dd, Gd, Gdd = w4[0], w4[1], w4[2], w4[3]
    for s in range(ns):
        for a in range(4):
            d[a] = q[seg_w[s, a]]
            dd[a] = dq[seg_w[s, a]]
        delta = 0.0
        rate = 0.0
        for a in range(4):
            x = G[s, a, 0] * d[0] + G[s, a, 1] * d[1] + G[s, a, 2] * d[2] + G[s, a, 3] * d[3]
            y = G[s, a, 0] * dd[0] + G[s, a, 1] * dd[1] + G[s, a, 2] * dd[2] + G[s, a, 3] * dd[3]
            Gd[a] = x
            Gdd[a] = y
            delta += d[a] * x
            rate += dd[a] * x
        delta *= 0.5
        ks, bs = k[s], beta[s]
        kb = ks * bs
        F = ks * (delta + bs * rate)                          # shortening force [N]
        u0, u1 = seg_u[s, 0], seg_u[s, 1]
        Pax = ks * ((q[u1] - q[u0]) + bs * (dq[u1] - dq[u0])) + F      # axial force [N]
        for a in range(4):
            g[seg_w[s, a]] += Pax * Gd[a]
        g[u1] += F
        g[u0] -= F
        if not jac:
            continue
        w0, w1, w2, w3 = seg_w[s, 0], seg_w[s, 1], seg_w[s, 2], seg_w[s, 3]
        T0, T1, T2, T3, Tu0, Tu1 = Tp[w0], Tp[w1], Tp[w2], Tp[w3], Tp[u0], Tp[u1]
        D0, D1, D2, D3, Du0, Du1 = Tdp[w0], Tdp[w1], Tdp[w2], Tdp[w3], Tdp[u0], Tdp[u1]
        Z0, Z1, Z2, Z3 = Z[w0], Z[w1], Z[w2], Z[w3]
        Lb, La, Reb, Rea, Rvb, Rva = Lt[s], Lt[ns + s], Re[s], Re[ns + s], Rv[s], Rv[ns + s]
        g0, g1, g2, g3 = Gd[0], Gd[1], Gd[2], Gd[3]
        h0, h1, h2, h3 = Gdd[0], Gdd[1], Gdd[2], Gdd[3]
        # P G on the segment's bending DOFs (geometric stiffness), row by row.
        P00, P01, P02, P03 = Pax * G[s, 0, 0], Pax * G[s, 0, 1], Pax * G[s, 0, 2], Pax * G[s, 0, 3]
        P10, P11, P12, P13 = Pax * G[s, 1, 0], Pax * G[s, 1, 1], Pax * G[s, 1, 2], Pax * G[s, 1, 3]
        P20, P21, P22, P23 = Pax * G[s, 2, 0], Pax * G[s, 2, 1], Pax * G[s, 2, 2], Pax * G[s, 2, 3]
        P30, P31, P32, P33 = Pax * G[s, 3, 0], Pax * G[s, 3, 1], Pax * G[s, 3, 2], Pax * G[s, 3, 3]
        for j in range(r):
            t0, t1, t2, t3 = T0[j], T1[j], T2[j], T3[j]
            b = g0 * t0 + g1 * t1 + g2 * t2 + g3 * t3                                 # dDelta/deta
            re = (g0 * D0[j] + g1 * D1[j] + g2 * D2[j] + g3 * D3[j]) + (h0 * t0 + h1 * t1 + h2 * t2 + h3 * t3)
            aj = Tu1[j] - Tu0[j]                                                      # de/deta
            adj = Du1[j] - Du0[j]
            F_eta = ks * (b + bs * re)
            F_v = kb * b
            Lb[j] = b
            La[j] = aj
            Reb[j] = ks * (aj + bs * adj) + F_eta
            Rea[j] = F_eta
            Rvb[j] = kb * aj + F_v
            Rva[j] = F_v
            Z0[j] += P00 * t0 + P01 * t1 + P02 * t2 + P03 * t3
            Z1[j] += P10 * t0 + P11 * t1 + P12 * t2 + P13 * t3
            Z2[j] += P20 * t0 + P21 * t1 + P22 * t2 + P23 * t3
            Z3[j] += P30 * t0 + P31 * t1 + P32 * t2 + P33 * t3
    np.dot(Tp.T, g, N)
    if jac:
        # dN/deta = sum_s [b (dP/deta)^T + a (dF/deta)^T] + sum_s P Ed^T G Ed; dN/deta' likewise.
        np.dot(Lt.T, Re, Ne)
        Ne += np.dot(Tp.T, Z)
        np.dot(Lt.T, Rv, Nv)


def corotational_forces(section, z, v, out):
    """One co-rotational segment's internal forces beyond the linear ones, ``-`` its pseudo-loads
    with P0 = 0 at its physical axial force ``P = EA/L (u1 - u0 + beta (u1 - u0)') + F``, into
    ``out`` (6,); returns ``(P, L (e - a))``. ``section`` as
    :func:`tmm_core.compiled.time_step.corotational_segment`;
    :func:`tmm_core.second_order.corotational_node_forces` is the reference."""
    L, EA, beta = section[0], section[1], section[2]
    first = corotational_segment(section, z, v, 0.0, 0.0)
    P = EA / L * ((z[3] - z[0]) + beta * (v[3] - v[0])) + first[6]
    forces = corotational_segment(section, z, v, P, 0.0)
    for a in range(6):
        out[a] = -forces[a]
    return P, forces[7]


def corotational_term(Tp, Tdp, eta, v, jac, sections, work, terms):
    """:func:`second_order` with co-rotational segments: ``N = T^T g`` (the segments' forces of
    :func:`corotational_forces` at ``q = T eta``, ``q' = T eta' + T' eta``) and, with ``jac``,
    ``Ne = sum_s T_s^T (g_q T_s + g_v T'_s)``, ``Nv = sum_s T_s^T g_v T_s`` with the segments'
    exact derivatives (:func:`tmm_core.compiled.time_step.corotational_tangent`). Records: ``sections =
    (start, data)`` with ``data`` (n_seg, 6) each segment's ``(L, EA, beta, k00, k01, k11)``;
    ``work = (q, dq, g, local (2, 6), plus (6,), scratch (3, 6), gz (6, 6), gv (6, 6), M1 (6, r), M2
    (6, r))``; ``terms = (N, Ne, Nv)`` (written)."""
    start, data = sections
    q, dq, g, local, plus, scratch, gz, gv, M1, M2 = work
    N, Ne, Nv = terms
    r = Tp.shape[1]
    node_state(Tp, Tdp, eta, v, q, dq)
    g[:] = 0.0
    if jac:
        Ne[:, :] = 0.0
        Nv[:, :] = 0.0
    for s in range(start.shape[0]):
        i0 = start[s]
        section = (data[s, 0], data[s, 1], data[s, 2], data[s, 3], data[s, 4], data[s, 5])
        for a in range(6):
            local[0, a] = q[i0 + a]
            local[1, a] = dq[i0 + a]
        P, _ = corotational_forces(section, local[0], local[1], plus)
        for a in range(6):
            g[i0 + a] += plus[a]
        if not jac:
            continue
        # g = -(pseudo-loads at the segment's own axial force, P0 = 0): its derivatives are minus
        # the tangent's (scratch rows: by P, unused here, and the shortening force's).
        corotational_tangent(section, local[0], local[1], P, True, 0.0, gz, gv, scratch[0], scratch[1], scratch[2])
        for a in range(6):
            for col in range(6):
                gz[a, col] = -gz[a, col]
                gv[a, col] = -gv[a, col]
        for a in range(6):
            for j in range(r):
                acc1 = 0.0
                acc2 = 0.0
                for b in range(6):
                    acc1 += gz[a, b] * Tp[i0 + b, j] + gv[a, b] * Tdp[i0 + b, j]
                    acc2 += gv[a, b] * Tp[i0 + b, j]
                M1[a, j] = acc1
                M2[a, j] = acc2
        for j in range(r):
            for m in range(r):
                s1 = 0.0
                s2 = 0.0
                for a in range(6):
                    s1 += Tp[i0 + a, j] * M1[a, m]
                    s2 += Tp[i0 + a, j] * M2[a, m]
                Ne[j, m] += s1
                Nv[j, m] += s2
    np.dot(Tp.T, g, N)


def segment_state(Tp, Tdp, eta, v, i0, local):
    """Fill ``local`` (2, 6) with the displacements and velocities of the segment whose first dof
    is ``i0`` at one stage point: ``T eta`` and ``T v + T' eta`` on its six dofs."""
    r = Tp.shape[1]
    for a in range(6):
        za = 0.0
        va = 0.0
        for j in range(r):
            za += Tp[i0 + a, j] * eta[j]
            va += Tp[i0 + a, j] * v[j] + Tdp[i0 + a, j] * eta[j]
        local[0, a] = za
        local[1, a] = va


def corotational_gauges(Tp, Tdp, eta, v, sections, local, out6, gauge_reading, out):
    """The gauges' co-rotational readings at one stage point, added into the stage's outputs
    ``out``: the axial strain from their segments' ``L (e - a)`` (:func:`corotational_forces`)
    with the weights [1/m] (columns ``2 + 2 g``) and the bending from their segment's chord lag
    (:func:`tmm_core.compiled.time_step.chord_lag`) with the weight [-] (columns ``1 + 2 g``).
    Record: ``gauge_reading = (gauge_seg, gauge_w, bend_seg, bend_w)``
    (:meth:`tmm_core.discretization.Discretization.gauge_reading`)."""
    start, data = sections
    gauge_seg, gauge_w, bend_seg, bend_w = gauge_reading
    for gi in range(gauge_seg.shape[0]):
        for gc in range(2):
            sg = gauge_seg[gi, gc]
            segment_state(Tp, Tdp, eta, v, start[sg], local)
            section = (data[sg, 0], data[sg, 1], data[sg, 2], data[sg, 3], data[sg, 4], data[sg, 5])
            _, excess = corotational_forces(section, local[0], local[1], out6)
            out[2 + 2 * gi] += excess * gauge_w[gi, gc]
        sb = bend_seg[gi]
        segment_state(Tp, Tdp, eta, v, start[sb], local)
        out[1 + 2 * gi] += bend_w[gi] * chord_lag(data[sb, 0], local[0, 3] - local[0, 0], local[0, 4] - local[0, 1])


def newton_matrix(h, A, A2, Mr, Cr, Kr, Ne, Nv, P0, J):
    """The Newton matrix of the stage equations of the step whose stage points start at ``P0``:
    block ``(i, j)`` = ``h A_ij (C_i + Nv_i) + h^2 (A^2)_ij (K_i + Ne_i)`` (+ ``M_i`` if i = j)."""
    r = Ne.shape[1]
    for i in range(3):
        p = P0 + i
        for jb in range(3):
            a1 = h * A[i, jb]
            a2 = h * h * A2[i, jb]
            for a in range(r):
                Jrow = J[i * r + a, jb * r:(jb + 1) * r]
                Crow, Nvrow, Krow, Nerow = Cr[p, a], Nv[i, a], Kr[p, a], Ne[i, a]
                for b in range(r):
                    Jrow[b] = a1 * (Crow[b] + Nvrow[b]) + a2 * (Krow[b] + Nerow[b])
        for a in range(r):
            Jrow = J[i * r + a, i * r:(i + 1) * r]
            Mrow = Mr[p, a]
            for b in range(r):
                Jrow[b] += Mrow[b]


def revolution(x0, guess, options, tableau, stages, segments, output_maps, newton, kept, results):
    """March one period (N = ``accs.shape[0]`` Radau IIA steps of ``h`` [s]) from ``x0 = (eta,
    eta')`` (2r,). Stage point ``p = 3 n + i`` of step ``n``: ``Mr, Cr, Kr`` (P, r, r), ``fr``
    (P, r), basis ``T`` and ``Td = T' theta'`` (P, n_dof, r); ``A``, ``A2 = A A``, ``c``: the
    Radau IIA tableau. Stage accelerations start from ``guess[n]`` (``have_guess``) or from the
    previous step's last stage (``guess[0]`` for the first step).

    Writes ``x_end`` (2r,), the stage accelerations ``accs`` (N, 3, r), with ``want_jac`` the
    monodromy ``mono`` (2r, 2r) (product of the step Jacobians), with ``want_out`` the outputs
    ``outs`` (3N, n_out): ``O0[p] + Oe[p] eta_i + Ov[p] eta'_i + Oa[p] acc_i`` plus, with
    ``nonlinear``, the shortenings of gauge g's two segments ``gauge_seg[g]`` times their weights
    ``gauge_w[g]`` [1/m] in column ``2 + 2 g`` (with ``corotational`` also the bending from the
    chord lag of ``bend_seg[g]`` times ``bend_w[g]``, :func:`corotational_gauges`); ``counts`` (2,): Newton
    iterations and factorizations (added to).

    ``chord_start``, ``chord_rate``: :data:`CHORD_START`, :data:`CHORD_CONTRACTION`.
    ``LUs`` (N, 3r, 3r), ``pivs`` (N, 3r): every step's last factorized Newton matrix, kept across
    revolutions; ``stored[n]`` says it is one of the nonlinear model's. With ``chord``, a step
    whose factorization is stored starts with chord iterations on it (after a few shooting
    iterations the state hardly moves, and the step needs no factorization at all).

    Returns -1, or the index of the step whose Newton iteration did not converge in
    ``iterations`` (``x_end`` then unset).

    Records (tuples, unpacked below): ``options = (nonlinear, want_jac, want_out, have_guess,
    chord, chord_start, chord_rate)``; ``tableau = (h, A, A2, c)``; ``stages = (Mr, Cr, Kr, fr,
    T, Td)``; ``segments = (seg_w, seg_u, G, k, beta)`` (as :func:`second_order`);
    ``output_maps = (O0, Oe, Ov, Oa, gauge_seg, gauge_w, bend_seg, bend_w)``; ``newton = (tol, iterations)``;
    ``kept = (LUs, pivs, stored)``; ``results = (x_end, mono, outs, accs, counts)`` (written)."""
    nonlinear, want_jac, want_out, have_guess, chord, chord_start, chord_rate, corotational = options
    h, A, A2, c = tableau
    Mr, Cr, Kr, fr, T, Td = stages
    seg_w, seg_u, G, k, beta, sections = segments
    O0, Oe, Ov, Oa, gauge_seg, gauge_w, bend_seg, bend_w = output_maps
    tol, iterations = newton
    LUs, pivs, stored = kept
    x_end, mono, outs, accs, counts = results
    r = x0.shape[0] // 2
    N = accs.shape[0]
    n = T.shape[1]
    ns = seg_w.shape[0]
    n3 = 3 * r
    eta = x0[:r].copy()
    v = x0[r:].copy()
    eta0, v0, res, q, dq, g = np.empty(r), np.empty(r), np.empty(n3), np.empty(n), np.empty(n), np.empty(n)
    acc, es, vs, w4 = np.empty((3, r)), np.empty((3, r)), np.empty((3, r)), np.empty((4, 4))
    Nn, Ne, Nv = np.zeros((3, r)), np.zeros((3, r, r)), np.zeros((3, r, r))   # stay 0 in the linear model
    Lt, Re, Rv, Z = np.empty((2 * ns, r)), np.empty((2 * ns, r)), np.empty((2 * ns, r)), np.zeros((n, r))
    Rm, S, prod = np.empty((n3, 2 * r)), np.empty((2 * r, 2 * r)), np.empty((2 * r, 2 * r))
    work = (q, dq, g, w4, Lt, Re, Rv, Z)
    local = np.empty((2, 6))
    corotational_work = (q, dq, g, local, np.empty(6), np.empty((3, 6)), np.empty((6, 6)), np.empty((6, 6)),
                         np.empty((6, r)), np.empty((6, r)))
    if want_jac:
        mono[:, :] = 0.0
        for i in range(2 * r):
            mono[i, i] = 1.0
    no = O0.shape[1]
    h2 = h * h
    # The Newton tolerance is relative to the largest stage acceleration of the steps so far as
    # well as the step's own: where all accelerations pass near zero the step's own scale sits
    # below the round-off floor of the update and the iteration would never stop.
    scale = 0.0
    for st in range(N):
        P0 = 3 * st
        for j in range(r):
            eta0[j] = eta[j]
            v0[j] = v[j]
        for i in range(3):
            for j in range(r):
                if have_guess or st == 0:
                    acc[i, j] = guess[st, i, j]
                else:
                    acc[i, j] = accs[st - 1, 2, j]
        use_chord = chord and nonlinear
        J = LUs[st]
        piv = pivs[st]
        refresh = not (use_chord and stored[st])
        refreshed = False
        prev = -1.0                       # last update's size; -1: no update on this matrix yet
        converged = False
        for it in range(iterations):
            stage_states(h, A, A2, c, eta, v, acc, es, vs)
            for i in range(3):
                p = P0 + i
                if nonlinear and corotational:
                    corotational_term(T[p], Td[p], es[i], vs[i], refresh, sections, corotational_work,
                                      (Nn[i], Ne[i], Nv[i]))
                elif nonlinear:
                    second_order(T[p], Td[p], es[i], vs[i], refresh, segments, work, (Nn[i], Ne[i], Nv[i]))
                for a in range(r):
                    s = dot(Mr[p, a], acc[i], 0, r) + dot(Cr[p, a], vs[i], 0, r) + dot(Kr[p, a], es[i], 0, r)
                    res[i * r + a] = -(s - fr[p, a] + Nn[i, a])
            if refresh:
                newton_matrix(h, A, A2, Mr, Cr, Kr, Ne, Nv, P0, J)
                lu_factor(J, piv)
                refreshed = True
                counts[1] += 1
            lu_solve(J, piv, res)
            counts[0] += 1
            dmax = 0.0
            amax = 0.0
            for i in range(3):
                for j in range(r):
                    acc[i, j] += res[i * r + j]
                    dmax = max(dmax, abs(res[i * r + j]))
                    amax = max(amax, abs(acc[i, j]))
            limit = tol * (max(amax, scale) + 1e-300)
            if not nonlinear:
                converged = True
                break
            if refresh:
                if dmax <= limit or (prev > 0.0 and dmax <= STALL_FACTOR * limit and dmax >= 0.5 * prev):
                    converged = True
                    break
                refresh = not (use_chord and dmax <= chord_start * amax)
            elif prev < 0.0:
                # First iteration on a stored factorization: no contraction rate yet.
                if dmax == 0.0:
                    if not want_jac:
                        converged = True
                        break
                    refresh = True
            else:
                theta = dmax / prev
                if dmax <= limit and theta * dmax <= 1e-3 * limit:
                    if not want_jac:
                        converged = True
                        break
                    # The step's Jacobian S needs the Newton matrix: one more iteration on a
                    # fresh one at the converged stage values (its update is at round-off).
                    refresh = True
                    prev = dmax
                    continue
                if theta > 1.0:
                    # Diverging on an old matrix: step back before refactorizing.
                    for i in range(3):
                        for j in range(r):
                            acc[i, j] -= res[i * r + j]
                # Finish with a Newton step when converged but the estimate is not yet small
                # (near the round-off floor), or when the chord iteration contracts slowly.
                refresh = dmax <= limit or not theta <= chord_rate
            prev = dmax
        if refreshed:
            stored[st] = nonlinear
        if not converged:
            return st
        scale = max(scale, amax)
        for j in range(r):
            accs[st, 0, j] = acc[0, j]
            accs[st, 1, j] = acc[1, j]
            accs[st, 2, j] = acc[2, j]
            eta[j] = eta0[j] + h * v0[j] + (h2 * A2[2, 0] * acc[0, j] + h2 * A2[2, 1] * acc[1, j] +
                                            h2 * A2[2, 2] * acc[2, j])
            v[j] = v0[j] + (h * A[2, 0] * acc[0, j] + h * A[2, 1] * acc[1, j] + h * A[2, 2] * acc[2, j])
        if want_out:
            stage_states(h, A, A2, c, eta0, v0, acc, es, vs)
            for i in range(3):
                p = P0 + i
                for o in range(no):
                    s = O0[p, o]
                    for j in range(r):
                        s += Oe[p, o, j] * es[i, j] + Ov[p, o, j] * vs[i, j] + Oa[p, o, j] * acc[i, j]
                    outs[p, o] = s
                if nonlinear and corotational:
                    corotational_gauges(T[p], Td[p], es[i], vs[i], sections, local, corotational_work[4],
                                 (gauge_seg, gauge_w, bend_seg, bend_w), outs[p])
                elif nonlinear:
                    for gi in range(gauge_seg.shape[0]):
                        for gc in range(2):
                            sg = gauge_seg[gi, gc]
                            d = w4[0]
                            for a in range(4):
                                d[a] = 0.0
                                row = seg_w[sg, a]
                                for j in range(r):
                                    d[a] += T[p, row, j] * es[i, j]
                            delta = 0.0
                            for a in range(4):
                                delta += d[a] * (G[sg, a, 0] * d[0] + G[sg, a, 1] * d[1] + G[sg, a, 2] * d[2] +
                                                 G[sg, a, 3] * d[3])
                            outs[p, 2 + 2 * gi] += 0.5 * delta * gauge_w[gi, gc]
        if want_jac:
            # d(acc)/d(eta, eta') = -J^-1 [Ke_i, Ce_i + h c_i Ke_i] (the last Newton matrix).
            for i in range(3):
                p = P0 + i
                hc = h * c[i]
                for a in range(r):
                    for b in range(r):
                        ke = Kr[p, a, b] + Ne[i, a, b]
                        Rm[i * r + a, b] = ke
                        Rm[i * r + a, r + b] = (Cr[p, a, b] + Nv[i, a, b]) + hc * ke
            lu_solve_many(J, piv, Rm)
            S[:, :] = 0.0
            for a in range(r):
                S[a, a] = 1.0
                S[a, r + a] = h
                S[r + a, r + a] = 1.0
            for a in range(r):
                for b in range(2 * r):
                    S[a, b] -= h2 * (A2[2, 0] * Rm[a, b] + A2[2, 1] * Rm[r + a, b] + A2[2, 2] * Rm[2 * r + a, b])
                    S[r + a, b] -= h * (A[2, 0] * Rm[a, b] + A[2, 1] * Rm[r + a, b] + A[2, 2] * Rm[2 * r + a, b])
            np.dot(S, mono, prod)
            mono[:, :] = prod
    for j in range(r):
        x_end[j] = eta[j]
        x_end[r + j] = v[j]
    return -1
