"""The load solve of the compiled factorization for many load sets at once (numba): the
load-to-response maps of :func:`tmm_core.step_data.compiled_maps` solve every unit node load of a
configuration (``n_dof + 1`` load sets) on one factorization.

:func:`tmm_core.compiled.structure.solve_loads` (the reference, kept for one load set: the stored
factorizations' solve of a time step calls it per iteration) does the load sweep, the joint solve
and the back-substitution one load set at a time in scalar 3x3 / 6x6 arithmetic. Here the same
arithmetic, in the same order for every load set, runs with the load set as the innermost,
contiguous loop (arrays ``(..., R)``), so that LLVM vectorizes it across load sets (the loops
start at zero or run on unsigned indices: numba's negative-index check on a signed index of
unknown sign keeps LLVM from vectorizing). The results equal the scalar solve's bit for bit.
Two savings on top: a member's load sweep runs only for the load sets with a load on that member
plus one zero-load set, whose sweep the others copy (a unit load elsewhere leaves the sweep as
without it); and the back-substitution evaluates only the station values that the compact
outputs read (node displacements, the axial force row, the gauges' states).

Measured side by side with the scalar solve (2 threads, AVX-512: vectors of 8 doubles). FE
crank-rocker at 373 rpm, 8 segments per link, 720 positions, 55 load sets: the maps' compiled call
(factorization and solves) 27 -> 8.1-8.5 ms, its load solves 24.6 -> 5.6-5.8 ms (0.62 -> 0.15 us
per load set); ``TimeDomain.configurations`` with the maps 51-52 -> 33 ms (best of 15).
Alexander-Lawrence, 4 segments per link, 360 positions, 46 load sets: 11.3 -> 3.9 ms and
20-21 -> 12.7-12.9 ms.

Owns: the many-load-set compact solve (:func:`solve_loads_many`) and its scratch
(:func:`maps_scratch`). Boundaries: the factorization is :mod:`tmm_core.compiled.riccati`, the
one-load-set solve and the batch loop :mod:`tmm_core.compiled.structure`, which compiles this module's
functions (:func:`tmm_core.compiled.binding.static_solve`); an edit here starts a fresh cache
by itself (:mod:`tmm_core.compiled.cache`).
"""
from __future__ import annotations

import math

import numpy as np

from .dense import lu_solve_many  # the compiled one once bound (tmm_core.compiled.binding)


def maps_scratch(M, mmax, nd, nf, Nn, R):
    """The work arrays of :func:`solve_loads_many` for ``M`` members of at most ``mmax`` chain
    matrices, ``nd`` joint DOFs (``nf`` free), ``Nn`` nodes and ``R`` load sets: ``(FT, ranges,
    filled, pcol, cs, ys, af, rfull, xf, qv, S0, st, zc, F5)``. Their lanes: the load sets, then
    zero-load ones (lane ``R`` the reference), up to whole vectors of 8 (the loops over them run
    without a scalar remainder; with 55 load sets it was 7 of them, a quarter of the time)."""
    R1 = (R + 8) // 8 * 8
    return (np.zeros((Nn, 3, R1)), np.zeros((M, 2), dtype=np.int64), np.full(1, -1, dtype=np.int64),
            np.zeros((M, mmax + 1, 6, R1)), np.zeros((M, mmax + 1, 3, R1)), np.zeros((M, mmax, 3, R1)),
            np.zeros((M, 3, R1)), np.zeros((nd, R1)), np.zeros((nf, R1)), np.zeros((nd, R1)), np.zeros((6, R1)),
            np.zeros((6, R1)), np.zeros((3, R1)), np.zeros((mmax + 1, R1)))


def sweep_member(mi, l0, l1, seg_off, FT, lead, lcol, B0, T220, SP, TL, BGis, HGis, firsts, pcol, cs, ys, af, st):
    """The load sweep (:func:`tmm_core.riccati.sweep_loads`) of member ``mi`` for the load sets
    ``l0 <= ri < l1``: ``pcol`` up to the first deformable segment, then ``af`` (a), ``cs`` (c at
    every chain index) and ``ys`` (y of every segment); the scalar solve's expressions."""
    s0, s1 = seg_off[mi], seg_off[mi + 1]
    m = 2 * (s1 - s0) + 1
    node0 = s0 + mi
    first = firsts[mi]
    u0, u1 = np.uint64(l0), np.uint64(l1)
    for r in range(6):
        for ri in range(u0, u1):
            pcol[mi, 0, r, ri] = 0.0
    for j in range(first):
        for r in range(6):
            for ri in range(u0, u1):
                pcol[mi, j + 1, r, ri] = 0.0
            for w in range(6):
                lw = lead[mi, j, r, w]
                for ri in range(u0, u1):
                    pcol[mi, j + 1, r, ri] += lw * pcol[mi, j, w, ri]
        if j % 2 == 0:
            node = node0 + j // 2
            for r in range(3):
                for ri in range(u0, u1):
                    pcol[mi, j + 1, 5 - r, ri] += -FT[node, r, ri]      # force rows fi = (5, 4, 3)
    # The first deformable segment's load column and the start of the Riccati recursion (a, c).
    for r in range(6):
        lc = lcol[mi, r]
        for ri in range(u0, u1):
            st[r, ri] = lc
        for w in range(6):
            lw = lead[mi, first, r, w]
            for ri in range(u0, u1):
                st[r, ri] += lw * pcol[mi, first, w, ri]
    b00 = B0[mi, 0, 0]; b01 = B0[mi, 0, 1]; b02 = B0[mi, 0, 2]
    b10 = B0[mi, 1, 0]; b11 = B0[mi, 1, 1]; b12 = B0[mi, 1, 2]
    b20 = B0[mi, 2, 0]; b21 = B0[mi, 2, 1]; b22 = B0[mi, 2, 2]
    t00 = T220[mi, 0, 0]; t01 = T220[mi, 0, 1]; t02 = T220[mi, 0, 2]
    t10 = T220[mi, 1, 0]; t11 = T220[mi, 1, 1]; t12 = T220[mi, 1, 2]
    t20 = T220[mi, 2, 0]; t21 = T220[mi, 2, 1]; t22 = T220[mi, 2, 2]
    for ri in range(u0, u1):
        z0 = st[0, ri]; z1 = st[1, ri]; z2 = st[2, ri]           # t1: rows zi = (0, 1, 2)
        a0 = -(b00 * z0 + b01 * z1 + b02 * z2)
        a1 = -(b10 * z0 + b11 * z1 + b12 * z2)
        a2 = -(b20 * z0 + b21 * z1 + b22 * z2)
        af[mi, 0, ri] = a0; af[mi, 1, ri] = a1; af[mi, 2, ri] = a2
        cs[mi, first + 1, 0, ri] = t00 * a0 + t01 * a1 + t02 * a2 + st[5, ri]   # t2: rows fi
        cs[mi, first + 1, 1, ri] = t10 * a0 + t11 * a1 + t12 * a2 + st[4, ri]
        cs[mi, first + 1, 2, ri] = t20 * a0 + t21 * a1 + t22 * a2 + st[3, ri]
    for j in range(first + 1, m):
        k = j // 2
        if j % 2 == 0:
            node = node0 + k
            for r in range(3):
                for ri in range(u0, u1):
                    cs[mi, j + 1, r, ri] = cs[mi, j, r, ri] + (-FT[node, r, ri])
            continue
        ta, f11, f12, f21, f22, g, c22 = SP[mi, k, 0], SP[mi, k, 3], SP[mi, k, 4], SP[mi, k, 5], SP[mi, k, 6], \
            SP[mi, k, 8], SP[mi, k, 9]
        l0_ = TL[mi, k, 0]; l1_ = TL[mi, k, 1]; l2_ = TL[mi, k, 2]; l3_ = TL[mi, k, 3]; l4_ = TL[mi, k, 4]
        l5_ = TL[mi, k, 5]
        p00 = BGis[mi, k, 0, 0]; p01 = BGis[mi, k, 0, 1]; p02 = BGis[mi, k, 0, 2]
        p10 = BGis[mi, k, 1, 0]; p11 = BGis[mi, k, 1, 1]; p12 = BGis[mi, k, 1, 2]
        p20 = BGis[mi, k, 2, 0]; p21 = BGis[mi, k, 2, 1]; p22 = BGis[mi, k, 2, 2]
        h00 = HGis[mi, k, 0, 0]; h01 = HGis[mi, k, 0, 1]; h02 = HGis[mi, k, 0, 2]
        h10 = HGis[mi, k, 1, 0]; h11 = HGis[mi, k, 1, 1]; h12 = HGis[mi, k, 1, 2]
        h20 = HGis[mi, k, 2, 0]; h21 = HGis[mi, k, 2, 1]; h22 = HGis[mi, k, 2, 2]
        for ri in range(u0, u1):
            c0 = cs[mi, j, 0, ri]; c1 = cs[mi, j, 1, ri]; c2 = cs[mi, j, 2, ri]
            y0 = ta * c0 + l0_
            y1 = (f11 * c1 + f12 * c2) + l1_
            y2 = (f21 * c1 + f22 * c2) + l2_
            af[mi, 0, ri] = af[mi, 0, ri] - (p00 * y0 + p01 * y1 + p02 * y2)
            af[mi, 1, ri] = af[mi, 1, ri] - (p10 * y0 + p11 * y1 + p12 * y2)
            af[mi, 2, ri] = af[mi, 2, ri] - (p20 * y0 + p21 * y1 + p22 * y2)
            v0 = c0 + l3_
            v1 = c1 + l4_
            v2 = (g * c1 + c22 * c2) + l5_
            cs[mi, j + 1, 0, ri] = v0 - (h00 * y0 + h01 * y1 + h02 * y2)
            cs[mi, j + 1, 1, ri] = v1 - (h10 * y0 + h11 * y1 + h12 * y2)
            cs[mi, j + 1, 2, ri] = v2 - (h20 * y0 + h21 * y1 + h22 * y2)
            ys[mi, j, 0, ri] = y0; ys[mi, j, 1, ri] = y1; ys[mi, j, 2, ri] = y2


def copy_sweep(mi, l0, l1, src, m, first, pcol, cs, ys, af):
    """The sweep of member ``mi`` of load set ``src`` copied to the load sets ``l0 <= ri < l1``
    (none of which loads the member: their sweeps equal the zero-load set's)."""
    u0, u1 = np.uint64(l0), np.uint64(l1)
    for j in range(first + 1):
        for r in range(6):
            v = pcol[mi, j, r, src]
            for ri in range(u0, u1):
                pcol[mi, j, r, ri] = v
    for r in range(3):
        v = af[mi, r, src]
        for ri in range(u0, u1):
            af[mi, r, ri] = v
    for j in range(first + 1, m + 1):
        for r in range(3):
            v = cs[mi, j, r, src]
            for ri in range(u0, u1):
                cs[mi, j, r, ri] = v
            if j < m and j % 2 == 1:
                v = ys[mi, j, r, src]
                for ri in range(u0, u1):
                    ys[mi, j, r, ri] = v


def solve_loads_many(bi, Fn, joints, outputs, factors, scratch):
    """:func:`tmm_core.compiled.structure.solve_loads` for ``R`` load sets and the compact outputs only
    (``zout``, ``nout``, ``gstate``, with ``q_out`` and ``reaction``; units and layout as
    :func:`tmm_core.compiled.structure.solve_range`), vectorized across the load sets; ``scratch`` from
    :func:`maps_scratch` (one per batch loop: the transposed loads are kept between configurations
    when ``Fn`` has no batch entries).

    Records as :func:`tmm_core.compiled.structure.solve_loads` (``outputs``' station states are not
    written)."""
    seg_off, rigid, angle, ends, free = joints
    _states, q_out, reaction, zout, nout, gnode, gstate = outputs
    lead, prefix, lcol, B0, T220, SP, TL, Gis, Xs, BGis, HGis, Cs, Ds, Af, Bf, firsts, Kfull, lu, piv = factors
    R, M, nd, nf = Fn.shape[1], seg_off.shape[0] - 1, Kfull.shape[0], lu.shape[0]
    FT, ranges, filled, pcol, cs, ys, af, rfull, xf, qv, S0, st, zc, F5 = scratch
    G = gnode.shape[0]
    # The work arrays' lanes (load sets, then zero-load ones): the loops over them have no
    # remainder; the outputs take the first R.
    Rp = FT.shape[2]
    # Loads transposed to (node, component, load set); lane R stays zero: the zero-load set.
    if Fn.shape[0] > 1 or filled[0] < 0:
        filled[0] = 1
        fb = bi if Fn.shape[0] > 1 else 0
        for ri in range(R):
            for node in range(FT.shape[0]):
                for r in range(3):
                    FT[node, r, ri] = Fn[fb, ri, node, r]
        # Per member, the range of load sets that load it (the others share the zero-load sweep).
        for mi in range(M):
            lo, hi = R, 0
            for node in range(seg_off[mi] + mi, seg_off[mi + 1] + mi + 1):
                for r in range(3):
                    for ri in range(R):
                        if FT[node, r, ri] != 0.0:
                            lo = min(lo, ri)
                            hi = max(hi, ri + 1)
            if hi <= lo:
                lo, hi = 0, 0
            ranges[mi, 0] = lo
            ranges[mi, 1] = hi
    # -- load sweep of every member, assembled into the joint forces ----------------------
    for i in range(nd):
        for ri in range(Rp):
            rfull[i, ri] = 0.0
    for mi in range(M):
        lo, hi = ranges[mi, 0], ranges[mi, 1]
        m = 2 * (seg_off[mi + 1] - seg_off[mi]) + 1
        # Whole vectors of lanes (the extra ones are overwritten below or are zero-load lanes).
        hi8 = min(lo + (hi - lo + 7) // 8 * 8, Rp)
        sweep_member(mi, lo, hi8, seg_off, FT, lead, lcol, B0, T220, SP, TL, BGis, HGis, firsts, pcol, cs, ys, af, st)
        sweep_member(mi, R, Rp, seg_off, FT, lead, lcol, B0, T220, SP, TL, BGis, HGis, firsts, pcol, cs, ys, af, st)
        # np.int64(0), not a bare 0: numba would compile copy_sweep once more for the literal.
        copy_sweep(mi, np.int64(0), lo, R, m, firsts[mi], pcol, cs, ys, af)
        copy_sweep(mi, hi, R, R, m, firsts[mi], pcol, cs, ys, af)
        cp = math.cos(-angle[bi, mi])
        sn = math.sin(-angle[bi, mi])
        e0, e1, e2 = ends[mi, 0], ends[mi, 1], ends[mi, 2]
        for ri in range(Rp):           # start: qe = -a
            q0 = -af[mi, 0, ri]; q1 = -af[mi, 1, ri]; q2 = -af[mi, 2, ri]
            rfull[e0, ri] += cp * q0 + sn * q1
            rfull[e1, ri] += -sn * q0 + cp * q1
            rfull[e2, ri] += q2
        e0, e1, e2 = ends[mi, 3], ends[mi, 4], ends[mi, 5]
        for ri in range(Rp):           # end: qe = c
            q0 = cs[mi, m, 0, ri]; q1 = cs[mi, m, 1, ri]; q2 = cs[mi, m, 2, ri]
            rfull[e0, ri] += cp * q0 + sn * q1
            rfull[e1, ri] += -sn * q0 + cp * q1
            rfull[e2, ri] += q2
    # -- joint solve (the one-load solve's, dense.lu_solve_many), displacements and joint forces --
    for i in range(nf):
        src = free[i]
        for ri in range(Rp):
            xf[i, ri] = -rfull[src, ri]
    lu_solve_many(lu, piv, xf)
    for i in range(nd):
        for ri in range(Rp):
            qv[i, ri] = 0.0
    for i in range(nf):
        fi_ = free[i]
        for ri in range(Rp):
            qv[fi_, ri] = xf[i, ri]
    for i in range(nd):
        for j in range(nd):
            kij = Kfull[i, j]
            for ri in range(Rp):
                rfull[i, ri] += kij * qv[j, ri]
    for ri in range(R):
        for i in range(nd):
            q_out[bi, ri, i] = qv[i, ri]
            reaction[bi, ri, i] = rfull[i, ri]
    # -- back-substitution (tmm_core.riccati.chain_states): the stations the outputs read ---
    for mi in range(M):
        s0, s1 = seg_off[mi], seg_off[mi + 1]
        n = s1 - s0
        m = 2 * n + 1
        node0 = s0 + mi
        first = firsts[mi]
        cp = math.cos(-angle[bi, mi])
        sn = math.sin(-angle[bi, mi])
        e0, e1, e2, e3, e4, e5 = ends[mi, 0], ends[mi, 1], ends[mi, 2], ends[mi, 3], ends[mi, 4], ends[mi, 5]
        a00 = Af[mi, 0, 0]; a01 = Af[mi, 0, 1]; a02 = Af[mi, 0, 2]
        a10 = Af[mi, 1, 0]; a11 = Af[mi, 1, 1]; a12 = Af[mi, 1, 2]
        a20 = Af[mi, 2, 0]; a21 = Af[mi, 2, 1]; a22 = Af[mi, 2, 2]
        b00 = Bf[mi, 0, 0]; b01 = Bf[mi, 0, 1]; b02 = Bf[mi, 0, 2]
        b10 = Bf[mi, 1, 0]; b11 = Bf[mi, 1, 1]; b12 = Bf[mi, 1, 2]
        b20 = Bf[mi, 2, 0]; b21 = Bf[mi, 2, 1]; b22 = Bf[mi, 2, 2]
        # S0 = the start state (z rows 0..2, f rows 5, 4, 3); zc the running end displacements.
        for ri in range(Rp):
            gx = qv[e0, ri]; gy = qv[e1, ri]
            zs0 = cp * gx + (-sn) * gy
            zs1 = sn * gx + cp * gy
            zs2 = qv[e2, ri]
            gx = qv[e3, ri]; gy = qv[e4, ri]
            ze0 = cp * gx + (-sn) * gy
            ze1 = sn * gx + cp * gy
            ze2 = qv[e5, ri]
            S0[0, ri] = zs0; S0[1, ri] = zs1; S0[2, ri] = zs2
            S0[5, ri] = (a00 * zs0 + a01 * zs1 + a02 * zs2) + (b00 * ze0 + b01 * ze1 + b02 * ze2) + af[mi, 0, ri]
            S0[4, ri] = (a10 * zs0 + a11 * zs1 + a12 * zs2) + (b10 * ze0 + b11 * ze1 + b12 * ze2) + af[mi, 1, ri]
            S0[3, ri] = (a20 * zs0 + a21 * zs1 + a22 * zs2) + (b20 * ze0 + b21 * ze1 + b22 * ze2) + af[mi, 2, ri]
            zc[0, ri] = ze0; zc[1, ri] = ze1; zc[2, ri] = ze2
        # Stations up to the first deformable segment: prefix S0 + pcol, every row.
        for j in range(first + 1):
            for r in range(6):
                for ri in range(Rp):
                    st[r, ri] = 0.0
                for q in range(6):
                    pq = prefix[mi, j, r, q]
                    for ri in range(Rp):
                        st[r, ri] += pq * S0[q, ri]
                for ri in range(Rp):
                    st[r, ri] += pcol[mi, j, r, ri]
            node = node0 + j // 2
            for ri in range(Rp):
                F5[j, ri] = st[5, ri]
            if j % 2 == 0:
                for r in range(3):
                    for ri in range(R):
                        zout[bi, 3 * node + r, ri] = st[r, ri]
            else:
                for gk in range(G):
                    if gnode[gk] == node:
                        for r in range(6):
                            for ri in range(R):
                                gstate[bi, gk, r, ri] = st[r, ri]
        # The Riccati stations, backwards: z from the end, f = C zs + D z + c (row 5 always: the
        # axial force; every row at a gauge).
        for j in range(m, first, -1):
            k = j // 2
            node = node0 + k
            c0 = Cs[mi, j, 0, 0]; c1 = Cs[mi, j, 0, 1]; c2 = Cs[mi, j, 0, 2]
            d0 = Ds[mi, j, 0, 0]; d1 = Ds[mi, j, 0, 1]; d2 = Ds[mi, j, 0, 2]
            if j % 2 == 1 and j < m:
                x00 = Xs[mi, k, 0, 0]; x01 = Xs[mi, k, 0, 1]; x02 = Xs[mi, k, 0, 2]
                x10 = Xs[mi, k, 1, 0]; x11 = Xs[mi, k, 1, 1]; x12 = Xs[mi, k, 1, 2]
                x20 = Xs[mi, k, 2, 0]; x21 = Xs[mi, k, 2, 1]; x22 = Xs[mi, k, 2, 2]
                g00 = Gis[mi, k, 0, 0]; g01 = Gis[mi, k, 0, 1]; g02 = Gis[mi, k, 0, 2]
                g10 = Gis[mi, k, 1, 0]; g11 = Gis[mi, k, 1, 1]; g12 = Gis[mi, k, 1, 2]
                g20 = Gis[mi, k, 2, 0]; g21 = Gis[mi, k, 2, 1]; g22 = Gis[mi, k, 2, 2]
                for ri in range(Rp):       # the segment's start z, then the station's axial force
                    s0_ = S0[0, ri]; s1_ = S0[1, ri]; s2_ = S0[2, ri]
                    v0 = zc[0, ri] - (x00 * s0_ + x01 * s1_ + x02 * s2_) - ys[mi, j, 0, ri]
                    v1 = zc[1, ri] - (x10 * s0_ + x11 * s1_ + x12 * s2_) - ys[mi, j, 1, ri]
                    v2 = zc[2, ri] - (x20 * s0_ + x21 * s1_ + x22 * s2_) - ys[mi, j, 2, ri]
                    z0 = g00 * v0 + g01 * v1 + g02 * v2
                    z1 = g10 * v0 + g11 * v1 + g12 * v2
                    z2 = g20 * v0 + g21 * v1 + g22 * v2
                    zc[0, ri] = z0; zc[1, ri] = z1; zc[2, ri] = z2
                    F5[j, ri] = (c0 * s0_ + c1 * s1_ + c2 * s2_) + (d0 * z0 + d1 * z1 + d2 * z2) + cs[mi, j, 0, ri]
            else:
                for ri in range(Rp):
                    F5[j, ri] = (c0 * S0[0, ri] + c1 * S0[1, ri] + c2 * S0[2, ri]) \
                        + (d0 * zc[0, ri] + d1 * zc[1, ri] + d2 * zc[2, ri]) + cs[mi, j, 0, ri]
            if j % 2 == 0:
                for r in range(3):
                    for ri in range(R):
                        zout[bi, 3 * node + r, ri] = zc[r, ri]
                continue
            for gk in range(G):
                if gnode[gk] != node:
                    continue
                for r in range(3):
                    for ri in range(R):
                        gstate[bi, gk, r, ri] = zc[r, ri]
                for ri in range(R):
                    gstate[bi, gk, 5, ri] = F5[j, ri]
                for r in range(1, 3):
                    c0 = Cs[mi, j, r, 0]; c1 = Cs[mi, j, r, 1]; c2 = Cs[mi, j, r, 2]
                    d0 = Ds[mi, j, r, 0]; d1 = Ds[mi, j, r, 1]; d2 = Ds[mi, j, r, 2]
                    for ri in range(R):
                        gstate[bi, gk, 5 - r, ri] = (c0 * S0[0, ri] + c1 * S0[1, ri] + c2 * S0[2, ri]) \
                            + (d0 * zc[0, ri] + d1 * zc[1, ri] + d2 * zc[2, ri]) + cs[mi, j, r, ri]
        # Segment axial forces: the mean of the two end values (0 for a rigid segment).
        for k in range(n):
            sg = s0 + k
            if rigid[sg]:
                for ri in range(R):
                    nout[bi, sg, ri] = 0.0
            else:
                for ri in range(R):
                    nout[bi, sg, ri] = 0.5 * (F5[2 * k + 1, ri] + F5[2 * k + 2, ri])
