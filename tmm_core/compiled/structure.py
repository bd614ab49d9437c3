"""Compiled factorization and solve of the instantaneous structure (numba), and the compiled
quasi-static (kineto-elastostatic) beam-column iteration built on it.

:func:`tmm_core.structure.factorize` / :func:`tmm_core.structure.solve_factored` (numpy, batched)
are the reference. This module does the same arithmetic for one configuration at a time in a
compiled loop over the batch: the exact beam-column field matrices at the segments' axial forces
(Stumpff functions), the Riccati condensation of every member (:mod:`tmm_core.riccati`), the joint
system and its LU factorization, then for every set of node loads the load sweep, the joint solve
and the back-substitution to the station states. One factorization serves many load sets: the
time domain's load-to-response maps (``TimeDomain.configurations``) solve all unit loads of a
configuration on it. ``tests/test_kernels.py`` checks it against the numpy path (solves, the
quasi-static iteration and the maps).

Stability (Wittrick-Williams) comes from the factorization itself, without an eigenvalue
problem: the negative pivots of the LDL^T factorization of the eliminated Schur complements
(member interiors) and of the scaled joint stiffness, plus the clamped-clamped buckling count of
every segment (the J0 term); the numpy path counts the member interiors the same way
(:func:`tmm_core.riccati.inertia_count`). The ratio of the largest to the smallest pivot magnitude
of the scaled joint stiffness is the singularity check (a toggle, an unconstrained joint, a member
at its buckling load), compared with ``cond_limit``.

Scope: structures of joints and members (pinned, clamped and free joints; pin and rigid member
connections; rigid segments): the four-bars and the linkages without springs, plates or
sliders. :func:`tmm_core.compiled.statics.supported` says whether a structure qualifies; the
callers use the numpy path otherwise. Kernels are compiled on first use and cached on disk (numba
``cache=True``).

Modules: this one holds the kernel (:func:`solve_range`, its load-solve phase :func:`solve_loads`
and its scratch, :func:`range_workspace`); :mod:`tmm_core.compiled.riccati` the factorization phase,
:mod:`tmm_core.compiled.step_data` the load solve of many load sets with compact outputs (the maps,
vectorized across the load sets: 3x faster there), :mod:`tmm_core.compiled.dense` the small dense
helpers, :mod:`tmm_core.compiled.statics` the Python driver (layout, checks, the compiled
``solve_linear`` and ``solve_static``).

The beam-column iteration runs in the kernel too, one configuration at a time to its own
tolerance (the loop of :func:`tmm_core.statics.solve_static`): no solves for configurations
that have converged, and one call per part of the batch for the whole iteration.

Threads: the kernel releases the GIL (``nogil``), and the Python driver
(:mod:`tmm_core.compiled.statics`) runs the parts of a batch on a thread pool, each part an
independent range of configurations (so the result does not depend on the split). Numba's own
parallel loops did the same, but compiling them took about as long as every other kernel
together on a 2-core machine (the parallel lowering of a 60-argument loop body).

Measured (FE rig at 241 rpm, 8 segments per link, 360 positions, side by side with numpy,
``tests/benchmarks/factorization_benchmark.py``): a beam-column quasi-static revolution 9-11x faster
(best 7.9-9.7 ms, median 10.2-15 ms with the machine's noise, before the one-call iteration;
15-30 % more with one region per solve), the time domain's configurations with their maps 5x
faster (16 segments per link: 10x and 6x).
"""
from __future__ import annotations

import math

import numpy as np

from .. import matrices
from .dense import copy_states, iteration_converged, lu_solve_many, state_change
from .riccati import factor_scratch
from .step_data import maps_scratch


INV_FACT = np.array(matrices.INV_FACT)        # the Stumpff series' 1/k! (the numpy path's table)


def range_workspace(segments, configuration, Fn, joints, outputs):
    """The scratch record of :func:`solve_range` for one range of a batch (its records as that
    kernel's): ``(many, factors, factor_scratch, load_work, maps_scratch)``, ``many`` whether the
    load sets go to the maps' solve (:func:`tmm_core.compiled.step_data.solve_loads_many`: many
    load sets with compact outputs only), then the records the factorization and the load solves
    take. Called from Python (the binding's ``RangeSolve``) with numpy, once per range: inside the
    kernel its fifty allocations took longer to compile than the loop that uses them, and the
    binding reads the callees' signatures off the records' types."""
    seg_off = segments[1]
    Kn, free = configuration[3], joints[1]
    states, q_out, zout = outputs[0], outputs[1], outputs[3]
    R = Fn.shape[1]
    many = zout.shape[1] > 0 and R > 1 and states.shape[1] == 0
    M, nd, nf = seg_off.shape[0] - 1, q_out.shape[2], free.shape[0]
    nmax = 0
    for i in range(M):
        nmax = max(nmax, seg_off[i + 1] - seg_off[i])
    mmax = 2 * nmax + 1
    # Load-independent factors, per member (a segment's blocks at its index j // 2, j = 2 i + 1 its
    # matrix in the chain; the stations' at j).
    lead = np.zeros((M, mmax + 1, 6, 6))      # 6x6 parts of the matrices 0..first
    prefix = np.zeros((M, mmax + 1, 6, 6))    # their running products
    lcol = np.zeros((M, 6))                   # load column of the first deformable matrix
    B0 = np.zeros((M, 3, 3))
    T220 = np.zeros((M, 3, 3))
    SP = np.zeros((M, nmax, 10))              # sparse field blocks of every segment
    TL = np.zeros((M, nmax, 6))               # and their load columns (t1, t2)
    Gis = np.zeros((M, nmax, 3, 3))
    Xs = np.zeros((M, nmax, 3, 3))
    BGis = np.zeros((M, nmax, 3, 3))
    HGis = np.zeros((M, nmax, 3, 3))
    Cs = np.zeros((M, mmax + 1, 3, 3))
    Ds = np.zeros((M, mmax + 1, 3, 3))
    Af = np.zeros((M, 3, 3))
    Bf = np.zeros((M, 3, 3))
    firsts = np.zeros(M, dtype=np.int64)
    # Load-dependent constants, per member (one load set at a time).
    pcol = np.zeros((M, mmax + 1, 6))
    ys = np.zeros((M, mmax, 3))
    cs = np.zeros((M, mmax + 1, 3))
    af = np.zeros((M, 3))
    scratch_factor = factor_scratch(nf)
    # Its t6, t1, t2 and the index vectors zi, fi serve the load solve too.
    _Kc, _T6, t6, _tmp6, _Kff, _Ks, _work, _c5, _sp, _T11, _T12, _T21, _T22, _A, _Bm, _C, _D, t1, t2, zi, fi = \
        scratch_factor
    Kfull = np.zeros((nd, nd))
    rfull = np.zeros(nd)
    lu = np.zeros((nf, nf))
    piv = np.zeros(nf, dtype=np.int64)
    xf = np.zeros((nf, 1))         # the joint solve's one column (the maps' solve has many)
    qv = np.zeros(nd)
    a = np.zeros(3)
    c = np.zeros(3)
    y = np.zeros(3)
    v3 = np.zeros(3)
    zs = np.zeros(3)
    ze = np.zeros(3)
    zj = np.zeros((mmax + 1, 3))
    S0 = np.zeros(6)
    zl = np.zeros(6)
    qe = np.zeros(6)
    stn = np.zeros((Kn.shape[1], 2, 6))
    factors = (lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv)
    load_work = (pcol, ys, cs, af, t6, t1, t2, a, c, y, v3, rfull, xf, qv, zl, zs, ze, qe, S0, zj, stn, zi, fi)
    return many, factors, scratch_factor, load_work, maps_scratch(M, mmax, nd, nf, Kn.shape[1], R if many else 0)


def solve_range(b_start, b_stop, segments, configuration, Fn, joints, outputs, checks, iteration, control,
                workspace, kernels):
    """Factorize the configurations ``b_start <= b < b_stop`` of a batch once each and solve
    them for ``R`` sets of node loads (see the module docstring); or, with
    ``iteration = (tol, max_iter, count from P)`` and ``max_iter > 1``, iterate each one on its
    segment axial forces (beam-column: the loop of :func:`tmm_core.statics.solve_static`, one
    configuration at a time).

    Per segment (``seg_off`` delimits the members): length ``L``, ``EA``, ``EI``, ``rigid``;
    per configuration: ``factor (B, S)`` (stiffness factor), ``P (B, S)`` axial forces,
    ``qloc (B, S, 2)`` local distributed loads (axial, transverse), ``Kn (B, Nn, 3, 3)`` local
    node stiffness (member ``i`` has nodes ``seg_off[i] + i ...``; rows in conjugate order);
    ``Fn (B or 1, R, Nn, 3)`` local node loads of each load set; ``angle (B, M)`` member angles;
    ``ends (M, 6)`` joint DOFs of the member ends; ``free`` the free joint DOFs; ``count (M,)``
    count the members' interior inertia.
    Outputs: ``states (B, R, Nn, 2, 6)``, joint displacements ``q_out (B, R, nd)``, joint forces
    ``reaction (B, R, nd)`` (applied by the supports at fixed DOFs), ``negative (B, 2)`` inertia
    (member interiors, joint system), ``pivots (B, 2)`` smallest and largest pivot magnitude of
    the scaled joint stiffness, ``status (B,)`` 0 ok, 1 a joint DOF without stiffness,
    2 a singular block or joint system. Compact outputs (for many load sets, when ``states`` has
    no load-set entries; the load set last, as the columns of a map): ``zout (B, 3 Nn, R)`` node
    displacements (u, w, theta), ``nout (B, S, R)`` segment axial forces (mean of the two end
    values), ``gstate (B, G, 6, R)`` the right-side state at the nodes ``gnode (G,)``.
    Iteration (``R`` = 1, every station state): it starts from the linear solution ``start
    (B, Nn, 2, 6)`` (the first solve), with ``P`` its axial forces, and returns the last axial
    forces in ``P``; ``weights (6,)`` and ``scales (2,)`` of the change
    (:func:`tmm_core.compiled.dense.state_change`); ``iterations (B,)`` solves made (the first
    included), ``last_change (B,)``; ``status`` 3 a non-finite iterate, 4 not converged in
    ``max_iter`` solves; ``count`` the members to count, or with ``count from P`` recounted
    before every solve (the members in compression).

    Records (tuples of arrays, unpacked below): ``segments = (inv_fact, seg_off, L, EA, EI,
    rigid)``, ``configuration = (factor, P, qloc, Kn, angle)``, ``joints = (ends, free, count)``,
    ``outputs = (states, q_out, reaction, zout, nout, gnode, gstate)``, ``checks = (negative,
    pivots, status)``, ``control = (weights, start, scales, iterations, last_change)``.

    ``workspace`` from :func:`range_workspace` (one per range: the threads' ranges each have
    their own); ``kernels = (factor_configuration, solve_loads_many, solve_loads)``: the factorization and the
    two load solves, passed as numba first-class functions (the binding compiles each once, for
    the records' types). A kernel that calls another directly has the callee's machine code
    generated again inside its own: passed as arguments, this kernel compiles in a fraction of
    the time (the first run's compilation, ``docs/benchmarks.md``)."""
    inv_fact, seg_off, L, EA, EI, rigid = segments
    factor, P, qloc, Kn, angle = configuration
    ends, free, count = joints
    states, q_out, reaction, zout, nout, gnode, gstate = outputs
    negative, pivots, status = checks
    weights, start, scales, iterations, last_change = control
    M = seg_off.shape[0] - 1
    # Many load sets with compact outputs (the maps): the load solve vectorized across them.
    many, factors, scratch_factor, load_work, scratch = workspace
    stn = load_work[20]
    load_joints = (seg_off, rigid, angle, ends, free)
    factor_configuration, solve_loads_many, solve_loads = kernels

    tol, max_iter, recount = iteration
    cnt = count.copy()
    old = np.zeros_like(stn)
    for bi in range(b_start, b_stop):
        # Beam-column iteration of one configuration (statics.solve_static's loop): the
        # relative change between successive solves, the stopping rule, and the relaxation
        # halved when the change grows.
        relax, prev, c1, c2, c3 = 1.0, math.inf, 0.0, 0.0, 0.0
        it = 2
        if max_iter > 1:
            copy_states(old, start[bi])
        while True:
            if recount:
                for mi in range(M):
                    cnt[mi] = False
                    for sg in range(seg_off[mi], seg_off[mi + 1]):
                        if P[bi, sg] < 0.0:
                            cnt[mi] = True
            if not factor_configuration(bi, segments, configuration, (ends, free, cnt), checks, factors,
                                        scratch_factor):
                break
            if many:
                solve_loads_many(bi, Fn, load_joints, outputs, factors, scratch)
            else:
                solve_loads(bi, Fn, load_joints, outputs, factors, load_work)
            if max_iter <= 1:
                break
            iterations[bi] = it
            ch = state_change(stn, old, weights, scales)
            last_change[bi] = ch
            if not math.isfinite(ch):
                status[bi] = 3
                break
            c1, c2, c3 = c2, c3, ch
            if iteration_converged(c1, c2, c3, it - 1, tol):
                break
            if ch > prev and relax > 0.15:
                relax *= 0.5
            prev = ch
            if it >= max_iter:
                status[bi] = 4
                break
            for mi in range(M):
                for sg in range(seg_off[mi], seg_off[mi + 1]):
                    node = sg + mi
                    target = 0.0 if rigid[sg] else 0.5 * (stn[node, 1, 5] + stn[node + 1, 0, 5])
                    P[bi, sg] = P[bi, sg] + relax * (target - P[bi, sg])
            copy_states(old, stn)
            it += 1


def solve_loads(bi, Fn, joints, outputs, factors, work):
    """Solve the factorized configuration ``bi`` (:func:`tmm_core.compiled.riccati.factor_configuration`)
    for every load set: the load sweep (:func:`tmm_core.riccati.sweep_loads`), the joint solve and the
    back-substitution to the station states (outputs as :func:`solve_range`). One load set at a
    time: the one-load-set callers (a time step on the stored factorizations, the quasi-static
    solves); many load sets with compact outputs go to
    :func:`tmm_core.compiled.step_data.solve_loads_many`.

    Records: ``joints = (seg_off, rigid, angle, ends, free)``, ``outputs = (states, q_out,
    reaction, zout, nout, gnode, gstate)`` (as :func:`solve_range`), ``factors`` the
    configuration's factorization (:func:`tmm_core.compiled.riccati.factor_configuration`),
    ``work = (pcol, ys, cs, af, t6, t1, t2, a, c, y, v3, rfull, xf, qv, zl, zs, ze, qe, S0,
    zj, stn, zi, fi)`` scratch arrays."""
    seg_off, rigid, angle, ends, free = joints
    states, q_out, reaction, zout, nout, gnode, gstate = outputs
    lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv = factors
    pcol, ys, cs, af, t6, t1, t2, a, c, y, v3, rfull, xf, qv, zl, zs, ze, qe, S0, zj, stn, zi, fi = work
    R, M, nd, nf = Fn.shape[1], seg_off.shape[0] - 1, Kfull.shape[0], lu.shape[0]
    full, compact = states.shape[1] > 0, zout.shape[1] > 0
    # -- every load set: load sweep (tmm_core.riccati.sweep_loads), joint solve, states ------
    fb = bi if Fn.shape[0] > 1 else 0
    for ri in range(R):
        for i in range(nd):
            rfull[i] = 0.0
        for mi in range(M):
            s0, s1 = seg_off[mi], seg_off[mi + 1]
            n = s1 - s0
            m = 2 * n + 1
            node0 = s0 + mi
            first = firsts[mi]
            for r in range(6):
                pcol[mi, 0, r] = 0.0
            for j in range(first):
                for r in range(6):
                    acc = 0.0
                    for w in range(6):
                        acc += lead[mi, j, r, w] * pcol[mi, j, w]
                    pcol[mi, j + 1, r] = acc
                if j % 2 == 0:
                    for r in range(3):
                        pcol[mi, j + 1, fi[r]] += -Fn[fb, ri, node0 + j // 2, r]
            for r in range(6):
                acc = lcol[mi, r]
                for w in range(6):
                    acc += lead[mi, first, r, w] * pcol[mi, first, w]
                t6[r] = acc
            for r in range(3):
                t1[r] = t6[zi[r]]
                t2[r] = t6[fi[r]]
            for r in range(3):
                a[r] = -(B0[mi, r, 0] * t1[0] + B0[mi, r, 1] * t1[1] + B0[mi, r, 2] * t1[2])
            for r in range(3):
                c[r] = T220[mi, r, 0] * a[0] + T220[mi, r, 1] * a[1] + T220[mi, r, 2] * a[2] + t2[r]
                cs[mi, first + 1, r] = c[r]
            for j in range(first + 1, m):
                if j % 2 == 0:
                    for r in range(3):
                        c[r] += -Fn[fb, ri, node0 + j // 2, r]
                else:
                    ta, f11, f12, f21, f22, g, c22 = (SP[mi, j // 2, 0], SP[mi, j // 2, 3], SP[mi, j // 2, 4], SP[mi, j // 2, 5],
                                                      SP[mi, j // 2, 6], SP[mi, j // 2, 8], SP[mi, j // 2, 9])
                    y[0] = ta * c[0] + TL[mi, j // 2, 0]
                    y[1] = (f11 * c[1] + f12 * c[2]) + TL[mi, j // 2, 1]
                    y[2] = (f21 * c[1] + f22 * c[2]) + TL[mi, j // 2, 2]
                    for r in range(3):
                        a[r] -= BGis[mi, j // 2, r, 0] * y[0] + BGis[mi, j // 2, r, 1] * y[1] + BGis[mi, j // 2, r, 2] * y[2]
                    v3[0] = c[0] + TL[mi, j // 2, 3]
                    v3[1] = c[1] + TL[mi, j // 2, 4]
                    v3[2] = (g * c[1] + c22 * c[2]) + TL[mi, j // 2, 5]
                    for r in range(3):
                        c[r] = v3[r] - (HGis[mi, j // 2, r, 0] * y[0] + HGis[mi, j // 2, r, 1] * y[1]
                                        + HGis[mi, j // 2, r, 2] * y[2])
                        ys[mi, j, r] = y[r]
                for r in range(3):
                    cs[mi, j + 1, r] = c[r]
            for r in range(3):
                af[mi, r] = a[r]
                qe[r] = -a[r]
                qe[r + 3] = c[r]
            cp = math.cos(-angle[bi, mi])
            sn = math.sin(-angle[bi, mi])
            for h in range(2):
                o = 3 * h
                rfull[ends[mi, o]] += cp * qe[o] + sn * qe[o + 1]
                rfull[ends[mi, o + 1]] += -sn * qe[o] + cp * qe[o + 1]
                rfull[ends[mi, o + 2]] += qe[o + 2]
        # The joint solve as the maps' (one column of the same solve: equal bit for bit).
        for i in range(nf):
            xf[i, 0] = -rfull[free[i]]
        lu_solve_many(lu, piv, xf)
        for i in range(nd):
            qv[i] = 0.0
        for i in range(nf):
            qv[free[i]] = xf[i, 0]
        for i in range(nd):
            q_out[bi, ri, i] = qv[i]
            acc = rfull[i]
            for j in range(nd):
                acc += Kfull[i, j] * qv[j]
            reaction[bi, ri, i] = acc
        # Back-substitution along every member (tmm_core.riccati.chain_states).
        for mi in range(M):
            s0, s1 = seg_off[mi], seg_off[mi + 1]
            n = s1 - s0
            m = 2 * n + 1
            node0 = s0 + mi
            first = firsts[mi]
            cp = math.cos(-angle[bi, mi])
            sn = math.sin(-angle[bi, mi])
            for h in range(2):
                o = 3 * h
                gx = qv[ends[mi, o]]
                gy = qv[ends[mi, o + 1]]
                zl[o] = cp * gx + (-sn) * gy
                zl[o + 1] = sn * gx + cp * gy
                zl[o + 2] = qv[ends[mi, o + 2]]
            for r in range(3):
                zs[r] = zl[r]
                ze[r] = zl[r + 3]
            for r in range(3):
                f0 = (Af[mi, r, 0] * zs[0] + Af[mi, r, 1] * zs[1] + Af[mi, r, 2] * zs[2]) \
                    + (Bf[mi, r, 0] * ze[0] + Bf[mi, r, 1] * ze[1] + Bf[mi, r, 2] * ze[2]) + af[mi, r]
                S0[zi[r]] = zs[r]
                S0[fi[r]] = f0
            for j in range(first + 1):
                node = node0 + j // 2
                side = j % 2
                for r in range(6):
                    acc = 0.0
                    for q in range(6):
                        acc += prefix[mi, j, r, q] * S0[q]
                    stn[node, side, r] = acc + pcol[mi, j, r]
            for r in range(3):
                zj[m, r] = ze[r]
            for j in range(m - 1, first, -1):
                if j % 2 == 0:
                    for r in range(3):
                        zj[j, r] = zj[j + 1, r]
                else:
                    for r in range(3):
                        v3[r] = zj[j + 1, r] - (Xs[mi, j // 2, r, 0] * zs[0] + Xs[mi, j // 2, r, 1] * zs[1]
                                                + Xs[mi, j // 2, r, 2] * zs[2]) - ys[mi, j, r]
                    for r in range(3):
                        zj[j, r] = Gis[mi, j // 2, r, 0] * v3[0] + Gis[mi, j // 2, r, 1] * v3[1] + Gis[mi, j // 2, r, 2] * v3[2]
            for j in range(first + 1, m + 1):
                node = node0 + j // 2
                side = j % 2
                for r in range(3):
                    stn[node, side, zi[r]] = zj[j, r]
                    stn[node, side, fi[r]] = (Cs[mi, j, r, 0] * zs[0] + Cs[mi, j, r, 1] * zs[1]
                                              + Cs[mi, j, r, 2] * zs[2]) \
                        + (Ds[mi, j, r, 0] * zj[j, 0] + Ds[mi, j, r, 1] * zj[j, 1]
                           + Ds[mi, j, r, 2] * zj[j, 2]) + cs[mi, j, r]
        if full:
            for node in range(stn.shape[0]):
                for side in range(2):
                    for r in range(6):
                        states[bi, ri, node, side, r] = stn[node, side, r]
        if compact:
            for node in range(stn.shape[0]):
                for r in range(3):
                    zout[bi, 3 * node + r, ri] = stn[node, 0, r]
            for mi in range(M):
                for sg in range(seg_off[mi], seg_off[mi + 1]):
                    node = sg + mi
                    nout[bi, sg, ri] = 0.0 if rigid[sg] else 0.5 * (stn[node, 1, 5] + stn[node + 1, 0, 5])
            for k in range(gnode.shape[0]):
                for r in range(6):
                    gstate[bi, k, r, ri] = stn[gnode[k], 1, r]
