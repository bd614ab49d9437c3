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
sliders. :func:`supported` says whether a structure qualifies; the callers use the numpy path
otherwise. Kernels are compiled on first use and cached on disk (numba ``cache=True``).

Measured (FE rig at 241 rpm, 8 segments per link, 360 positions, side by side with numpy,
``tests/benchmarks/factorization_benchmark.py``): a beam-column quasi-static revolution 8x faster,
the time domain's configurations with their maps 5x faster (16 segments per link: 10x and 6x).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from . import kernels
from .errors import BucklingError, ConvergenceError, InputError, SingularStructureError, require_finite
from .matrices import frame_rotation

AVAILABLE = kernels.AVAILABLE
_COMPILED = {}
#: Threads of the compiled batch solve (None: numba's default, the number of cores). The
#: configurations of a batch are independent; results do not depend on the thread count. Default
#: 1: on the shared 2-core machine two threads made a quasi-static revolution 2-3x *slower*
#: (OpenMP threads spinning between the kernel calls take the core the numpy parts need).
THREADS: int | None = 1
numba_prange = range      # numba.prange once compiled

_SERIES_LIMIT = 4.0
_SERIES_TERMS = 24
INV_FACT = np.array([1.0 / math.factorial(k) for k in range(2 * _SERIES_TERMS + 6)])
# State order (u, w, theta, M, V, N): displacement indices z and conjugate force indices f.
_ZI = (0, 1, 2)
_FI = (5, 4, 3)


def compiled_solve():
    """The compiled :func:`solve_batch` (numba, cached on disk)."""
    if "solve" not in _COMPILED:
        import numba
        jit = numba.njit(cache=True, error_model="numpy")
        for name in ("_stumpff", "_inv3", "_mm3", "_ldl_inertia", "_lu_factor", "_lu_solve", "_segment_blocks",
                     "_full6"):
            globals()[name] = jit(globals()[name])
        globals()["solve_range"] = jit(solve_range)
        globals()["numba_prange"] = numba.prange
        _COMPILED["solve"] = numba.njit(cache=True, error_model="numpy", parallel=True)(solve_batch)
        _COMPILED["change"] = jit(_iteration_change)
    return _COMPILED["solve"]


# -- small dense helpers (compiled) ---------------------------------------------------------
def _stumpff(s, inv_fact, out):
    """``out[k] = c_k(s)``, k = 0..4 (see :func:`tmm_core.matrices.stumpff`)."""
    a_ = abs(s)
    if a_ < 4.0:
        # Horner over the terms that matter: the first term left out is below 1e-17 of the sum
        # (the numpy reference sums 24; the difference is round-off).
        top = 11 if a_ >= 1.0 else (8 if a_ >= 0.1 else (5 if a_ >= 1e-3 else 3))
        c3 = 0.0
        c4 = 0.0
        for n in range(top, -1, -1):
            c3 = c3 * s + inv_fact[2 * n + 3]
            c4 = c4 * s + inv_fact[2 * n + 4]
        c1 = 1.0 + s * c3
        c2 = 0.5 + s * c4
        c0 = 1.0 + s * c2
    else:
        r = math.sqrt(abs(s))
        if s > 0:
            c0 = math.cosh(r)
            c1 = math.sinh(r) / r
        else:
            c0 = math.cos(r)
            c1 = math.sin(r) / r
        c2 = (c0 - 1.0) / s
        c3 = (c1 - 1.0) / s
        c4 = (c2 - 0.5) / s
    out[0] = c0
    out[1] = c1
    out[2] = c2
    out[3] = c3
    out[4] = c4


def _inv3(A, out):
    """Adjugate inverse of a 3x3 matrix (as :func:`tmm_core.riccati.inv3`); returns the determinant."""
    a, b, c = A[0, 0], A[0, 1], A[0, 2]
    d, e, f = A[1, 0], A[1, 1], A[1, 2]
    g, h, i = A[2, 0], A[2, 1], A[2, 2]
    out[0, 0] = e * i - f * h
    out[0, 1] = c * h - b * i
    out[0, 2] = b * f - c * e
    out[1, 0] = f * g - d * i
    out[1, 1] = a * i - c * g
    out[1, 2] = c * d - a * f
    out[2, 0] = d * h - e * g
    out[2, 1] = b * g - a * h
    out[2, 2] = a * e - b * d
    det = a * out[0, 0] + b * out[1, 0] + c * out[2, 0]
    if det != 0.0 and math.isfinite(det):
        rdet = 1.0 / det
        for r in range(3):
            for k in range(3):
                out[r, k] *= rdet
    return det


def _mm3(A, B, out):
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


def _ldl_inertia(S, n, work):
    """Negative pivots of the LDL^T factorization (no pivoting) of the leading ``n x n`` block of
    the symmetric matrix ``S`` (overwritten in ``work``), and the smallest and largest pivot
    magnitudes. Sylvester's law of inertia: the number of negative pivots is the number of
    negative eigenvalues (an exactly zero pivot is counted as non-negative and reported by the
    smallest magnitude)."""
    for i in range(n):
        for j in range(n):
            work[i, j] = S[i, j]
    negative = 0
    pmin = np.inf
    pmax = 0.0
    for k in range(n):
        d = work[k, k]
        if d < 0.0:
            negative += 1
        ad = abs(d)
        if ad < pmin:
            pmin = ad
        if ad > pmax:
            pmax = ad
        if d == 0.0:
            continue
        for i in range(k + 1, n):
            lik = work[i, k] / d
            for j in range(k + 1, i + 1):
                work[i, j] -= lik * work[j, k]
        for i in range(k + 1, n):
            for j in range(k + 1, i + 1):
                work[j, i] = work[i, j]
    return negative, pmin, pmax


def _iteration_change(new, old, w):
    """``(largest |displacement change|, largest |displacement|, largest |force change|, largest
    |force|)`` of two station-state arrays ``(B, Nn, 2, 6)`` weighted by ``w (6,)``."""
    dd = 0.0
    ds = 0.0
    df = 0.0
    fs = 0.0
    B, Nn = new.shape[0], new.shape[1]
    for b in range(B):
        for i in range(Nn):
            for side in range(2):
                for k in range(6):
                    a = new[b, i, side, k] * w[k]
                    d = abs(a - old[b, i, side, k] * w[k])
                    a = abs(a)
                    if k < 3:
                        if a > ds:
                            ds = a
                        if d > dd:
                            dd = d
                    else:
                        if a > fs:
                            fs = a
                        if d > df:
                            df = d
    return dd, ds, df, fs


def _lu_factor(A, n, lu, piv):
    """LU factorization with partial pivoting of ``A[:n, :n]`` into ``lu``, ``piv``; False if singular."""
    for i in range(n):
        piv[i] = i
        for j in range(n):
            lu[i, j] = A[i, j]
    for k in range(n):
        p = k
        big = abs(lu[k, k])
        for i in range(k + 1, n):
            if abs(lu[i, k]) > big:
                big = abs(lu[i, k])
                p = i
        if big == 0.0:
            return False
        if p != k:
            for j in range(n):
                t = lu[k, j]
                lu[k, j] = lu[p, j]
                lu[p, j] = t
            t2 = piv[k]
            piv[k] = piv[p]
            piv[p] = t2
        for i in range(k + 1, n):
            l = lu[i, k] / lu[k, k]
            lu[i, k] = l
            if l != 0.0:
                for j in range(k + 1, n):
                    lu[i, j] -= l * lu[k, j]
    return True


def _lu_solve(lu, piv, n, rhs, x):
    """Solve with the factors of :func:`_lu_factor`."""
    for i in range(n):
        x[i] = rhs[piv[i]]
    for i in range(n):
        s = x[i]
        for j in range(i):
            s -= lu[i, j] * x[j]
        x[i] = s
    for k in range(n - 1, -1, -1):
        s = x[k]
        for j in range(k + 1, n):
            s -= lu[k, j] * x[j]
        x[k] = s / lu[k, k]


def _segment_blocks(l, ea, ei, p_, qt, qa, is_rigid, inv_fact, c5, sp, t1, t2):
    """Non-zero entries of a segment's field matrix in z/f blocks (straight chord, beta = 0):
    ``sp = (T12[0,0], T11[1,2], T11[2,2], T12[1,1], T12[1,2], T12[2,1], T12[2,2], T21[2,2],
    T22[2,1], T22[2,2])``, the other entries of T11, T22 being the identity's and of T12, T21
    zero; ``t1, t2`` the load column (see :func:`tmm_core.matrices.field_matrix` and
    :func:`tmm_core.matrices.rigid_element_matrix`)."""
    if is_rigid:
        sp[0] = 0.0
        sp[1] = l * 1.0
        sp[2] = 1.0
        sp[3] = 0.0
        sp[4] = 0.0
        sp[5] = 0.0
        sp[6] = 0.0
        sp[7] = 0.0
        sp[8] = -l
        sp[9] = 1.0
        for r in range(3):
            t1[r] = 0.0
            t2[r] = 0.0
        return
    rei = 1.0 / ei
    l2 = l * l
    _stumpff(p_ * l2 * rei, inv_fact, c5)
    c0, c1, c2, c3, c4 = c5[0], c5[1], c5[2], c5[3], c5[4]
    sp[0] = l / ea
    sp[1] = l * c1
    sp[2] = c0
    sp[3] = -(l2 * l) * c3 * rei
    sp[4] = l2 * c2 * rei
    sp[5] = -l2 * c2 * rei
    sp[6] = l * c1 * rei
    sp[7] = p_ * l * c1
    sp[8] = -l * c1
    sp[9] = c0
    t1[0] = -qa * l2 / (2.0 * ea)
    t1[1] = qt * (l2 * l2) * c4 * rei
    t1[2] = qt * (l2 * l) * c3 * rei
    t2[0] = -qa * l
    t2[1] = -qt * l
    t2[2] = qt * l**2 * c2


def _full6(sp, t1, t2, T, t):
    """The 6x6 homogeneous part (state order u, w, theta, M, V, N) and load column of a segment
    from :func:`_segment_blocks`."""
    for r in range(6):
        for q in range(6):
            T[r, q] = 1.0 if r == q else 0.0
    # z = (0, 1, 2), f = (5, 4, 3)
    T[0, 5] = sp[0]
    T[1, 2] = sp[1]
    T[2, 2] = sp[2]
    T[1, 4] = sp[3]
    T[1, 3] = sp[4]
    T[2, 4] = sp[5]
    T[2, 3] = sp[6]
    T[3, 2] = sp[7]
    T[3, 4] = sp[8]
    T[3, 3] = sp[9]
    t[0] = t1[0]
    t[1] = t1[1]
    t[2] = t1[2]
    t[5] = t2[0]
    t[4] = t2[1]
    t[3] = t2[2]


def solve_batch(inv_fact, seg_off, L, EA, EI, rigid, factor, P, qloc, Kn, Fn, angle, ends, free, count,
                states, q_out, reaction, negative, pivots, status, zout, nout, gnode, gstate, chunks):
    """:func:`solve_range` over the whole batch in ``chunks`` parts, in parallel (numba threads;
    each configuration is independent, so the result does not depend on the split)."""
    B = P.shape[0]
    for c in numba_prange(chunks):
        solve_range(B * c // chunks, B * (c + 1) // chunks, inv_fact, seg_off, L, EA, EI, rigid, factor, P, qloc,
                    Kn, Fn, angle, ends, free, count, states, q_out, reaction, negative, pivots, status, zout, nout,
                    gnode, gstate)


def solve_range(b_start, b_stop, inv_fact, seg_off, L, EA, EI, rigid, factor, P, qloc, Kn, Fn, angle, ends, free,
                count, states, q_out, reaction, negative, pivots, status, zout, nout, gnode, gstate):
    """Factorize the configurations ``b_start <= b < b_stop`` of a batch once each and solve
    them for ``R`` sets of node loads (see the module docstring).

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
    values), ``gstate (B, G, 6, R)`` the right-side state at the nodes ``gnode (G,)``."""
    R = Fn.shape[1]
    full = states.shape[1] > 0
    compact = zout.shape[1] > 0
    M = seg_off.shape[0] - 1
    nd = q_out.shape[2]
    nf = free.shape[0]
    nmax = 0
    for i in range(M):
        nmax = max(nmax, seg_off[i + 1] - seg_off[i])
    mmax = 2 * nmax + 1
    # Load-independent factors, per member.
    lead = np.zeros((M, mmax + 1, 6, 6))      # 6x6 parts of the matrices 0..first
    prefix = np.zeros((M, mmax + 1, 6, 6))    # their running products
    lcol = np.zeros((M, 6))                   # load column of the first deformable matrix
    B0 = np.zeros((M, 3, 3))
    T220 = np.zeros((M, 3, 3))
    SP = np.zeros((M, mmax, 10))              # sparse field blocks of every segment
    TL = np.zeros((M, mmax, 6))               # and their load columns (t1, t2)
    Gis = np.zeros((M, mmax, 3, 3))
    Xs = np.zeros((M, mmax, 3, 3))
    BGis = np.zeros((M, mmax, 3, 3))
    HGis = np.zeros((M, mmax, 3, 3))
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
    Kc = np.zeros((6, 6))
    T6 = np.zeros((6, 6))
    t6 = np.zeros(6)
    tmp6 = np.zeros((6, 6))
    Kfull = np.zeros((nd, nd))
    rfull = np.zeros(nd)
    Kff = np.zeros((nf, nf))
    Ks = np.zeros((nf, nf))
    lu = np.zeros((nf, nf))
    piv = np.zeros(nf, dtype=np.int64)
    work = np.zeros((max(nf, 3), max(nf, 3)))
    rhs = np.zeros(nf)
    xf = np.zeros(nf)
    qv = np.zeros(nd)
    c5 = np.zeros(5)
    sp = np.zeros(10)
    T11 = np.zeros((3, 3))
    T12 = np.zeros((3, 3))
    T21 = np.zeros((3, 3))
    T22 = np.zeros((3, 3))
    A = np.zeros((3, 3))
    Bm = np.zeros((3, 3))
    C = np.zeros((3, 3))
    D = np.zeros((3, 3))
    t1 = np.zeros(3)
    t2 = np.zeros(3)
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
    zi = np.array([0, 1, 2])
    fi = np.array([5, 4, 3])
    stn = np.zeros((Kn.shape[1], 2, 6))

    for bi in range(b_start, b_stop):
        status[bi] = 0
        neg_chain = 0
        for i in range(nd):
            for j in range(nd):
                Kfull[i, j] = 0.0
        # -- factorization (tmm_core.riccati.factor_chain), member by member -----------------
        for mi in range(M):
            s0, s1 = seg_off[mi], seg_off[mi + 1]
            n = s1 - s0
            m = 2 * n + 1
            node0 = s0 + mi
            # The chain: point matrix of node j at index 2j, segment j at 2j + 1; the first
            # deformable segment starts the Riccati recursion, everything before it is a prefix.
            first = -1
            for j in range(n):
                if not rigid[s0 + j]:
                    first = 2 * j + 1
                    break
            firsts[mi] = first
            for r in range(6):
                for q in range(6):
                    prefix[mi, 0, r, q] = 1.0 if r == q else 0.0
            for j in range(first):
                if j % 2 == 0:       # point matrix: identity with the node stiffness in the f-z block
                    nd_ = node0 + j // 2
                    for r in range(6):
                        for q in range(6):
                            lead[mi, j, r, q] = 1.0 if r == q else 0.0
                    for r in range(3):
                        for q in range(3):
                            lead[mi, j, fi[r], zi[q]] += Kn[bi, nd_, r, q]
                else:                # a rigid segment before the first deformable one
                    _segment_blocks(L[s0 + j // 2], 1.0, 1.0, 0.0, 0.0, 0.0, True, inv_fact, c5, sp, t1, t2)
                    _full6(sp, t1, t2, T6, t6)
                    for r in range(6):
                        for q in range(6):
                            lead[mi, j, r, q] = T6[r, q]
                for r in range(6):
                    for q in range(6):
                        acc = 0.0
                        for w in range(6):
                            acc += lead[mi, j, r, w] * prefix[mi, j, w, q]
                        prefix[mi, j + 1, r, q] = acc
            sg = s0 + first // 2
            _segment_blocks(L[sg], EA[sg] * factor[bi, sg], EI[sg] * factor[bi, sg], P[bi, sg], qloc[bi, sg, 1],
                            qloc[bi, sg, 0], False, inv_fact, c5, sp, t1, t2)
            _full6(sp, t1, t2, T6, t6)
            for r in range(6):
                lcol[mi, r] = t6[r]
                for q in range(6):
                    lead[mi, first, r, q] = T6[r, q]
                    acc = 0.0
                    for w in range(6):
                        acc += T6[r, w] * prefix[mi, first, w, q]
                    tmp6[r, q] = acc
            for r in range(3):
                for q in range(3):
                    T11[r, q] = tmp6[zi[r], zi[q]]
                    T12[r, q] = tmp6[zi[r], fi[q]]
                    T21[r, q] = tmp6[fi[r], zi[q]]
                    T22[r, q] = tmp6[fi[r], fi[q]]
            det = _inv3(T12, Bm)
            if det == 0.0 or not math.isfinite(det):
                status[bi] = 2
            _mm3(Bm, T11, A)
            for r in range(3):
                for q in range(3):
                    A[r, q] = -A[r, q]
            _mm3(T22, A, C)
            for r in range(3):
                for q in range(3):
                    C[r, q] += T21[r, q]
            _mm3(T22, Bm, D)
            for r in range(3):
                for q in range(3):
                    B0[mi, r, q] = Bm[r, q]
                    T220[mi, r, q] = T22[r, q]
                    Cs[mi, first + 1, r, q] = C[r, q]
                    Ds[mi, first + 1, r, q] = D[r, q]
            a00 = A[0, 0]; a01 = A[0, 1]; a02 = A[0, 2]; a10 = A[1, 0]; a11 = A[1, 1]; a12 = A[1, 2]; a20 = A[2, 0]; a21 = A[2, 1]; a22 = A[2, 2]
            b00 = Bm[0, 0]; b01 = Bm[0, 1]; b02 = Bm[0, 2]; b10 = Bm[1, 0]; b11 = Bm[1, 1]; b12 = Bm[1, 2]; b20 = Bm[2, 0]; b21 = Bm[2, 1]; b22 = Bm[2, 2]
            c00 = C[0, 0]; c01 = C[0, 1]; c02 = C[0, 2]; c10 = C[1, 0]; c11 = C[1, 1]; c12 = C[1, 2]; c20 = C[2, 0]; c21 = C[2, 1]; c22 = C[2, 2]
            d00 = D[0, 0]; d01 = D[0, 1]; d02 = D[0, 2]; d10 = D[1, 0]; d11 = D[1, 1]; d12 = D[1, 2]; d20 = D[2, 0]; d21 = D[2, 1]; d22 = D[2, 2]
            for j in range(first + 1, m):
                if j % 2 == 0:
                    nd_ = node0 + j // 2
                    d00 += Kn[bi, nd_, 0, 0]; d01 += Kn[bi, nd_, 0, 1]; d02 += Kn[bi, nd_, 0, 2]
                    d10 += Kn[bi, nd_, 1, 0]; d11 += Kn[bi, nd_, 1, 1]; d12 += Kn[bi, nd_, 1, 2]
                    d20 += Kn[bi, nd_, 2, 0]; d21 += Kn[bi, nd_, 2, 1]; d22 += Kn[bi, nd_, 2, 2]
                else:
                    sg = s0 + j // 2
                    _segment_blocks(L[sg], EA[sg] * factor[bi, sg], EI[sg] * factor[bi, sg], P[bi, sg],
                                    qloc[bi, sg, 1], qloc[bi, sg, 0], rigid[sg], inv_fact, c5, sp, t1, t2)
                    for r in range(10):
                        SP[mi, j, r] = sp[r]
                    for r in range(3):
                        TL[mi, j, r] = t1[r]
                        TL[mi, j, r + 3] = t2[r]
                    ta, e1, u22, f11, f12, f21, f22, kk, g, v22 = (sp[0], sp[1], sp[2], sp[3], sp[4], sp[5], sp[6],
                                                                 sp[7], sp[8], sp[9])
                    # G = T11 + T12 D, X = T12 C, H = T21 + T22 D (sparse blocks; scalars: registers, not memory)
                    g00 = 1.0 + ta * d00; g01 = ta * d01; g02 = ta * d02
                    g10 = f11 * d10 + f12 * d20; g11 = 1.0 + (f11 * d11 + f12 * d21); g12 = e1 + (f11 * d12 + f12 * d22)
                    g20 = f21 * d10 + f22 * d20; g21 = f21 * d11 + f22 * d21; g22 = u22 + (f21 * d12 + f22 * d22)
                    x00 = ta * c00; x01 = ta * c01; x02 = ta * c02
                    x10 = f11 * c10 + f12 * c20; x11 = f11 * c11 + f12 * c21; x12 = f11 * c12 + f12 * c22
                    x20 = f21 * c10 + f22 * c20; x21 = f21 * c11 + f22 * c21; x22 = f21 * c12 + f22 * c22
                    h00 = d00; h01 = d01; h02 = d02; h10 = d10; h11 = d11; h12 = d12
                    h20 = g * d10 + v22 * d20; h21 = g * d11 + v22 * d21; h22 = kk + (g * d12 + v22 * d22)
                    i00 = g11 * g22 - g12 * g21; i01 = g02 * g21 - g01 * g22; i02 = g01 * g12 - g02 * g11
                    i10 = g12 * g20 - g10 * g22; i11 = g00 * g22 - g02 * g20; i12 = g02 * g10 - g00 * g12
                    i20 = g10 * g21 - g11 * g20; i21 = g01 * g20 - g00 * g21; i22 = g00 * g11 - g01 * g10
                    det = g00 * i00 + g01 * i10 + g02 * i20
                    if det != 0.0 and math.isfinite(det):
                        rdet = 1.0 / det
                        i00 *= rdet; i01 *= rdet; i02 *= rdet; i10 *= rdet; i11 *= rdet; i12 *= rdet
                        i20 *= rdet; i21 *= rdet; i22 *= rdet
                    else:
                        status[bi] = 2
                    if count[mi] and not rigid[sg]:
                        # The eliminated Schur complement T12^-1 G: its inertia from the LDL^T pivots.
                        rta = 1.0 / ta
                        rd2 = 1.0 / (f11 * f22 - f12 * f21)
                        m00 = g00 * rta; m01 = g01 * rta; m02 = g02 * rta
                        m10 = (f22 * g10 - f12 * g20) * rd2; m11 = (f22 * g11 - f12 * g21) * rd2; m12 = (f22 * g12 - f12 * g22) * rd2
                        m20 = (-f21 * g10 + f11 * g20) * rd2; m21 = (-f21 * g11 + f11 * g21) * rd2; m22 = (-f21 * g12 + f11 * g22) * rd2
                        s00 = m00; s01 = 0.5 * (m01 + m10); s02 = 0.5 * (m02 + m20)
                        s11 = m11; s12 = 0.5 * (m12 + m21); s22 = m22
                        if s00 < 0.0:
                            neg_chain += 1
                        if s00 != 0.0:
                            s11 -= s01 / s00 * s01
                            s12 -= s02 / s00 * s01
                            s22 -= s02 / s00 * s02
                        if s11 < 0.0:
                            neg_chain += 1
                        if s11 != 0.0:
                            s22 -= s12 / s11 * s12
                        if s22 < 0.0:
                            neg_chain += 1
                    hg00 = h00 * i00 + h01 * i10 + h02 * i20
                    hg01 = h00 * i01 + h01 * i11 + h02 * i21
                    hg02 = h00 * i02 + h01 * i12 + h02 * i22
                    hg10 = h10 * i00 + h11 * i10 + h12 * i20
                    hg11 = h10 * i01 + h11 * i11 + h12 * i21
                    hg12 = h10 * i02 + h11 * i12 + h12 * i22
                    hg20 = h20 * i00 + h21 * i10 + h22 * i20
                    hg21 = h20 * i01 + h21 * i11 + h22 * i21
                    hg22 = h20 * i02 + h21 * i12 + h22 * i22
                    bg00 = b00 * i00 + b01 * i10 + b02 * i20
                    bg01 = b00 * i01 + b01 * i11 + b02 * i21
                    bg02 = b00 * i02 + b01 * i12 + b02 * i22
                    bg10 = b10 * i00 + b11 * i10 + b12 * i20
                    bg11 = b10 * i01 + b11 * i11 + b12 * i21
                    bg12 = b10 * i02 + b11 * i12 + b12 * i22
                    bg20 = b20 * i00 + b21 * i10 + b22 * i20
                    bg21 = b20 * i01 + b21 * i11 + b22 * i21
                    bg22 = b20 * i02 + b21 * i12 + b22 * i22
                    p00 = bg00 * x00 + bg01 * x10 + bg02 * x20
                    p01 = bg00 * x01 + bg01 * x11 + bg02 * x21
                    p02 = bg00 * x02 + bg01 * x12 + bg02 * x22
                    p10 = bg10 * x00 + bg11 * x10 + bg12 * x20
                    p11 = bg10 * x01 + bg11 * x11 + bg12 * x21
                    p12 = bg10 * x02 + bg11 * x12 + bg12 * x22
                    p20 = bg20 * x00 + bg21 * x10 + bg22 * x20
                    p21 = bg20 * x01 + bg21 * x11 + bg22 * x21
                    p22 = bg20 * x02 + bg21 * x12 + bg22 * x22
                    r00 = hg00 * x00 + hg01 * x10 + hg02 * x20
                    r01 = hg00 * x01 + hg01 * x11 + hg02 * x21
                    r02 = hg00 * x02 + hg01 * x12 + hg02 * x22
                    r10 = hg10 * x00 + hg11 * x10 + hg12 * x20
                    r11 = hg10 * x01 + hg11 * x11 + hg12 * x21
                    r12 = hg10 * x02 + hg11 * x12 + hg12 * x22
                    r20 = hg20 * x00 + hg21 * x10 + hg22 * x20
                    r21 = hg20 * x01 + hg21 * x11 + hg22 * x21
                    r22 = hg20 * x02 + hg21 * x12 + hg22 * x22
                    a00 -= p00; a01 -= p01; a02 -= p02; a10 -= p10; a11 -= p11; a12 -= p12; a20 -= p20; a21 -= p21; a22 -= p22
                    c20 = (g * c10 + v22 * c20) - r20; c21 = (g * c11 + v22 * c21) - r21; c22 = (g * c12 + v22 * c22) - r22
                    c00 = c00 - r00; c01 = c01 - r01; c02 = c02 - r02; c10 = c10 - r10; c11 = c11 - r11; c12 = c12 - r12
                    b00 = bg00; b01 = bg01; b02 = bg02; b10 = bg10; b11 = bg11; b12 = bg12; b20 = bg20; b21 = bg21; b22 = bg22
                    d00 = hg00; d01 = hg01; d02 = hg02; d10 = hg10; d11 = hg11; d12 = hg12; d20 = hg20; d21 = hg21; d22 = hg22
                    Gis[mi, j, 0, 0] = i00; Gis[mi, j, 0, 1] = i01; Gis[mi, j, 0, 2] = i02
                    Gis[mi, j, 1, 0] = i10; Gis[mi, j, 1, 1] = i11; Gis[mi, j, 1, 2] = i12
                    Gis[mi, j, 2, 0] = i20; Gis[mi, j, 2, 1] = i21; Gis[mi, j, 2, 2] = i22
                    Xs[mi, j, 0, 0] = x00; Xs[mi, j, 0, 1] = x01; Xs[mi, j, 0, 2] = x02
                    Xs[mi, j, 1, 0] = x10; Xs[mi, j, 1, 1] = x11; Xs[mi, j, 1, 2] = x12
                    Xs[mi, j, 2, 0] = x20; Xs[mi, j, 2, 1] = x21; Xs[mi, j, 2, 2] = x22
                    BGis[mi, j, 0, 0] = bg00; BGis[mi, j, 0, 1] = bg01; BGis[mi, j, 0, 2] = bg02
                    BGis[mi, j, 1, 0] = bg10; BGis[mi, j, 1, 1] = bg11; BGis[mi, j, 1, 2] = bg12
                    BGis[mi, j, 2, 0] = bg20; BGis[mi, j, 2, 1] = bg21; BGis[mi, j, 2, 2] = bg22
                    HGis[mi, j, 0, 0] = hg00; HGis[mi, j, 0, 1] = hg01; HGis[mi, j, 0, 2] = hg02
                    HGis[mi, j, 1, 0] = hg10; HGis[mi, j, 1, 1] = hg11; HGis[mi, j, 1, 2] = hg12
                    HGis[mi, j, 2, 0] = hg20; HGis[mi, j, 2, 1] = hg21; HGis[mi, j, 2, 2] = hg22
                Cs[mi, j + 1, 0, 0] = c00; Cs[mi, j + 1, 0, 1] = c01; Cs[mi, j + 1, 0, 2] = c02
                Cs[mi, j + 1, 1, 0] = c10; Cs[mi, j + 1, 1, 1] = c11; Cs[mi, j + 1, 1, 2] = c12
                Cs[mi, j + 1, 2, 0] = c20; Cs[mi, j + 1, 2, 1] = c21; Cs[mi, j + 1, 2, 2] = c22
                Ds[mi, j + 1, 0, 0] = d00; Ds[mi, j + 1, 0, 1] = d01; Ds[mi, j + 1, 0, 2] = d02
                Ds[mi, j + 1, 1, 0] = d10; Ds[mi, j + 1, 1, 1] = d11; Ds[mi, j + 1, 1, 2] = d12
                Ds[mi, j + 1, 2, 0] = d20; Ds[mi, j + 1, 2, 1] = d21; Ds[mi, j + 1, 2, 2] = d22
            A[0, 0] = a00; A[0, 1] = a01; A[0, 2] = a02
            A[1, 0] = a10; A[1, 1] = a11; A[1, 2] = a12
            A[2, 0] = a20; A[2, 1] = a21; A[2, 2] = a22
            Bm[0, 0] = b00; Bm[0, 1] = b01; Bm[0, 2] = b02
            Bm[1, 0] = b10; Bm[1, 1] = b11; Bm[1, 2] = b12
            Bm[2, 0] = b20; Bm[2, 1] = b21; Bm[2, 2] = b22
            C[0, 0] = c00; C[0, 1] = c01; C[0, 2] = c02
            C[1, 0] = c10; C[1, 1] = c11; C[1, 2] = c12
            C[2, 0] = c20; C[2, 1] = c21; C[2, 2] = c22
            D[0, 0] = d00; D[0, 1] = d01; D[0, 2] = d02
            D[1, 0] = d10; D[1, 1] = d11; D[1, 2] = d12
            D[2, 0] = d20; D[2, 1] = d21; D[2, 2] = d22
            for r in range(3):
                for q in range(3):
                    Af[mi, r, q] = A[r, q]
                    Bf[mi, r, q] = Bm[r, q]
                    Kc[r, q] = -A[r, q]
                    Kc[r, q + 3] = -Bm[r, q]
                    Kc[r + 3, q] = C[r, q]
                    Kc[r + 3, q + 3] = D[r, q]
            # Rotate to the global frame (Lam^T Kc Lam) and add to the joint system.
            cp = math.cos(-angle[bi, mi])
            sn = math.sin(-angle[bi, mi])
            for r in range(6):
                for h in range(2):
                    o = 3 * h
                    tmp6[r, o] = Kc[r, o] * cp + Kc[r, o + 1] * sn
                    tmp6[r, o + 1] = Kc[r, o] * (-sn) + Kc[r, o + 1] * cp
                    tmp6[r, o + 2] = Kc[r, o + 2]
            for h in range(2):
                o = 3 * h
                e0, e1_, e2 = ends[mi, o], ends[mi, o + 1], ends[mi, o + 2]
                for q in range(6):
                    eq = ends[mi, q]
                    Kfull[e0, eq] += cp * tmp6[o, q] + sn * tmp6[o + 1, q]
                    Kfull[e1_, eq] += -sn * tmp6[o, q] + cp * tmp6[o + 1, q]
                    Kfull[e2, eq] += tmp6[o + 2, q]
        negative[bi, 0] = neg_chain
        # Joint system: inertia and singularity from the LDL^T pivots of the scaled symmetric part.
        for i in range(nf):
            for j in range(nf):
                Kff[i, j] = Kfull[free[i], free[j]]
        for i in range(nf):
            if Kff[i, i] == 0.0:
                status[bi] = 1
        for i in range(nf):
            di = math.sqrt(abs(Kff[i, i])) if Kff[i, i] != 0.0 else 1.0
            for j in range(nf):
                dj = math.sqrt(abs(Kff[j, j])) if Kff[j, j] != 0.0 else 1.0
                Ks[i, j] = 0.5 * (Kff[i, j] + Kff[j, i]) / di / dj
        ng, pmin, pmax = _ldl_inertia(Ks, nf, work)
        negative[bi, 1] = ng
        pivots[bi, 0] = pmin
        pivots[bi, 1] = pmax
        if not _lu_factor(Kff, nf, lu, piv):
            status[bi] = 2
            continue
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
                        ta, f11, f12, f21, f22, g, c22 = (SP[mi, j, 0], SP[mi, j, 3], SP[mi, j, 4], SP[mi, j, 5],
                                                          SP[mi, j, 6], SP[mi, j, 8], SP[mi, j, 9])
                        y[0] = ta * c[0] + TL[mi, j, 0]
                        y[1] = (f11 * c[1] + f12 * c[2]) + TL[mi, j, 1]
                        y[2] = (f21 * c[1] + f22 * c[2]) + TL[mi, j, 2]
                        for r in range(3):
                            a[r] -= BGis[mi, j, r, 0] * y[0] + BGis[mi, j, r, 1] * y[1] + BGis[mi, j, r, 2] * y[2]
                        v3[0] = c[0] + TL[mi, j, 3]
                        v3[1] = c[1] + TL[mi, j, 4]
                        v3[2] = (g * c[1] + c22 * c[2]) + TL[mi, j, 5]
                        for r in range(3):
                            c[r] = v3[r] - (HGis[mi, j, r, 0] * y[0] + HGis[mi, j, r, 1] * y[1]
                                            + HGis[mi, j, r, 2] * y[2])
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
            for i in range(nf):
                rhs[i] = -rfull[free[i]]
            _lu_solve(lu, piv, nf, rhs, xf)
            for i in range(nd):
                qv[i] = 0.0
            for i in range(nf):
                qv[free[i]] = xf[i]
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
                            v3[r] = zj[j + 1, r] - (Xs[mi, j, r, 0] * zs[0] + Xs[mi, j, r, 1] * zs[1]
                                                    + Xs[mi, j, r, 2] * zs[2]) - ys[mi, j, r]
                        for r in range(3):
                            zj[j, r] = Gis[mi, j, r, 0] * v3[0] + Gis[mi, j, r, 1] * v3[1] + Gis[mi, j, r, 2] * v3[2]
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


# -- Python side ---------------------------------------------------------------------------
def supported(structure) -> bool:
    """Does the compiled path handle this structure (joints and members only, see the module
    docstring)?"""
    if structure.springs or structure.rigid_bodies or structure.sliders:
        return False
    if any(j.support not in ("free", "pinned", "clamped") for j in structure.joints):
        return False
    return all(not m.is_rigid.all() for m in structure.members)


@dataclass(frozen=True)
class Layout:
    """Per-structure data of the compiled solve: segment and node offsets, segment properties,
    the joint DOFs (from :func:`tmm_core.structure.factorize` on one configuration)."""

    seg_off: np.ndarray
    node_off: np.ndarray
    L: np.ndarray
    EA: np.ndarray
    EI: np.ndarray
    rigid: np.ndarray
    ends: np.ndarray
    fixed: np.ndarray
    free: np.ndarray
    labels: tuple


_LAYOUTS: dict = {}


def layout(structure, joint_positions: Mapping[str, np.ndarray]) -> Layout:
    """The :class:`Layout` of a structure (cached per structure)."""
    try:
        return _LAYOUTS[structure]
    except (KeyError, TypeError):
        pass
    from .structure import LoadCase, factorize
    one = {k: np.asarray(v, dtype=float).reshape(-1, 2)[0] for k, v in joint_positions.items()}
    f = factorize(structure, LoadCase(one), check_buckling=False, check_singular=False, count_inertia=False)
    members = structure.members
    seg_off = np.cumsum([0] + [m.n_segments for m in members]).astype(np.int64)
    out = Layout(seg_off, seg_off + np.arange(len(members) + 1), np.concatenate([m.segment_lengths for m in members]),
                 np.concatenate([m.EA for m in members]), np.concatenate([m.EI for m in members]),
                 np.concatenate([m.is_rigid for m in members]),
                 np.array([f.ends[m.name] for m in members], dtype=np.int64), np.asarray(f.fixed),
                 np.flatnonzero(~np.asarray(f.fixed)).astype(np.int64), tuple(f.labels))
    try:
        if len(_LAYOUTS) > 32:
            _LAYOUTS.clear()
        _LAYOUTS[structure] = out
    except TypeError:
        pass
    return out


def _local_rotation(angle):
    """(..., 3, 3) global (X, Y, theta) -> member local (u, w, theta)."""
    return frame_rotation(-np.asarray(angle, dtype=float))[..., :3, :3]


@dataclass
class Prepared:
    """A structure and load case laid out for :func:`solve_batch` (everything but the axial
    forces, which change from one beam-column iteration to the next)."""

    structure: object
    case: object
    layout: Layout
    angle: np.ndarray          # (B, M)
    origin: dict               # {member: (B, 2)}
    factor: np.ndarray         # (B, S)
    factor_given: dict         # {member: bool}
    qloc: np.ndarray           # (B, S, 2)
    Kn: np.ndarray             # (B, Nn, 3, 3)
    Fn: np.ndarray             # (B, Nn, 3)


def prepare(structure, case, stiffness_factor: Mapping[str, np.ndarray] | None = None) -> Prepared:
    """Lay out a :func:`supported` structure and a one-dimensional batch of configurations
    (``case``, any frame) for the compiled solve: member angles, local node stiffness and loads."""
    stiffness_factor = stiffness_factor or {}
    members = structure.members
    jp = {k: np.asarray(v, dtype=float) for k, v in case.joint_positions.items()}
    shapes = [v.shape[:-1] for v in jp.values()]
    for mapping, trail in ((case.node_loads, 2), (case.distributed_loads, 2), (case.node_stiffness, 3)):
        shapes += [np.shape(v)[:-trail] for v in mapping.values()]
    full = np.broadcast_shapes(*shapes)
    if len(full) > 1:
        raise InputError(f"the compiled solve takes a one-dimensional batch of configurations, got {full}")
    batch = full if full else (1,)
    B = batch[0]
    lay = layout(structure, jp)
    S = int(lay.seg_off[-1])
    Nn = S + len(members)
    angle = np.empty((B, len(members)))
    origin = {}
    factor = np.empty((B, S))
    qloc = np.zeros((B, S, 2))
    Kn = np.zeros((B, Nn, 3, 3))
    Fn = np.zeros((B, Nn, 3))
    for i, m in enumerate(members):
        try:
            a0 = np.broadcast_to(require_finite(f"joint '{m.start}' position", jp[m.start]), batch + (2,))
            b0 = np.broadcast_to(require_finite(f"joint '{m.end}' position", jp[m.end]), batch + (2,))
        except KeyError as exc:
            raise InputError(f"load case: no position for joint {exc.args[0]!r}") from None
        d = b0 - a0
        dist = np.hypot(d[..., 0], d[..., 1])
        if np.any(np.abs(dist - m.length) > 1e-9 * max(m.length, 1.0) + 1e-12):
            raise InputError(f"member '{m.name}': length {m.length:.9g} m does not match the distance between "
                             f"joints '{m.start}' and '{m.end}' (off by up to {np.max(np.abs(dist - m.length)):.3g} m)")
        angle[:, i] = np.arctan2(d[..., 1], d[..., 0])
        origin[m.name] = a0
        sl = slice(lay.seg_off[i], lay.seg_off[i + 1])
        nl = slice(lay.node_off[i], lay.node_off[i + 1])
        factor[:, sl] = np.broadcast_to(np.asarray(stiffness_factor.get(m.name, 1.0), dtype=float),
                                        batch + (m.n_segments,))
        R3 = _local_rotation(angle[:, i])[:, None]          # (B, 1, 3, 3)
        K = case.node_stiffness.get(m.name)
        if K is not None:
            K = require_finite(f"member '{m.name}': node_stiffness", K)
            if case.frame == "global":
                K = R3 @ K @ np.swapaxes(R3, -1, -2)
            Kn[:, nl] = np.broadcast_to(K, batch + (m.n_segments + 1, 3, 3))
        F = case.node_loads.get(m.name)
        if F is not None:
            F = require_finite(f"member '{m.name}': node_loads", F)
            if case.frame == "global":
                F = (R3 @ F[..., None])[..., 0]
            Fn[:, nl] = np.broadcast_to(F, batch + (m.n_segments + 1, 3))
        q = case.distributed_loads.get(m.name)
        if q is not None:
            q = require_finite(f"member '{m.name}': distributed_loads", q)
            qloc[:, sl] = np.broadcast_to((R3[..., :2, :2] @ q[..., None])[..., 0], batch + (m.n_segments, 2))
    return Prepared(structure, case, lay, angle, origin, factor,
                    {m.name: stiffness_factor.get(m.name) is not None for m in members}, qloc, Kn, Fn)


def solve_prepared(prep: Prepared, P: np.ndarray, *, check_buckling: bool = True, cond_limit: float = 1e12,
                   count_inertia: bool | None = None, node_loads: np.ndarray | None = None,
                   compact_nodes: np.ndarray | None = None):
    """One compiled solve of a :class:`Prepared` batch at the stacked segment axial forces
    ``P (B, S)``: ``(states (B, Nn, 2, 6), joint displacements (B, nd), joint forces (B, nd),
    inertia count (B,))``. ``node_loads (B or 1, R, Nn, 3)`` (local frame) instead of the case's
    loads: one factorization per configuration solved for R load sets; the outputs then carry
    the load-set axis after the batch axis. ``compact_nodes``: return, instead of every station
    state, ``(node displacements (B, 3 Nn, R), segment axial forces (B, S, R), right-side states
    at these nodes (B, G, 6, R))`` in the place of the states (much less memory; the load set
    last, as the columns of a map). Raises :class:`SingularStructureError` and, with ``check_buckling``,
    :class:`BucklingError` (module docstring)."""
    from .structure import clamped_clamped_buckling_count
    lay = prep.layout
    B, S = prep.factor.shape
    P = np.ascontiguousarray(np.broadcast_to(np.asarray(P, dtype=float), (B, S)))
    if count_inertia is None:
        count = np.array([check_buckling and bool(np.any(P[:, lay.seg_off[i]:lay.seg_off[i + 1]] < 0))
                          for i in range(len(lay.seg_off) - 1)], dtype=np.bool_)
    else:
        count = np.full(len(lay.seg_off) - 1, bool(count_inertia))
    s = P * lay.L**2 / (lay.EI * prep.factor)
    if np.any(s > 700.0**2):
        raise InputError(f"segment tension parameter P*L^2/EI = {float(np.max(s)):.4g} overflows cosh; "
                         "split the link into more segments")
    nd = len(lay.labels)
    Fn = prep.Fn[:, None] if node_loads is None else node_loads
    R = Fn.shape[1]
    Nn = prep.Kn.shape[1]
    if compact_nodes is None:
        states = np.empty((B, R, Nn, 2, 6))
        zout, nout, gnode, gstate = np.empty((B, 0, 0)), np.empty((B, 0, 0)), np.zeros(0, np.int64), np.empty((B, 0, 0, 6))
    else:
        states = np.empty((B, 0, Nn, 2, 6))
        gnode = np.asarray(compact_nodes, dtype=np.int64)
        zout, nout, gstate = np.empty((B, 3 * Nn, R)), np.empty((B, S, R)), np.empty((B, len(gnode), 6, R))
    q = np.empty((B, R, nd))
    reaction = np.empty((B, R, nd))
    negative = np.zeros((B, 2), dtype=np.int64)
    pivots = np.empty((B, 2))
    status = np.zeros(B, dtype=np.int64)
    solve = compiled_solve()
    import numba
    threads = numba.get_num_threads() if THREADS is None else max(1, min(int(THREADS), numba.config.NUMBA_NUM_THREADS))
    chunks = max(1, min(B, threads if B * Fn.shape[1] >= 64 else 1))
    args = (INV_FACT, lay.seg_off, lay.L, lay.EA, lay.EI, lay.rigid, prep.factor, P, prep.qloc, prep.Kn,
            Fn, prep.angle, lay.ends, lay.free, count, states, q, reaction, negative, pivots, status, zout, nout,
            gnode, gstate)
    if chunks == 1:
        solve_range(0, B, *args)      # no parallel region: its start costs ~0.4 ms
    else:
        solve(*args, chunks)
    if compact_nodes is not None:
        states = (zout, nout, gstate)
    elif node_loads is None:
        states, q, reaction = states[:, 0], q[:, 0], reaction[:, 0]
    if np.any(status == 1):
        raise SingularStructureError("instantaneous structure is singular: no stiffness at a joint DOF "
                                     f"(batch entries {np.flatnonzero(status == 1)[:5].tolist()})")
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(pivots[:, 0] > 0, pivots[:, 1] / pivots[:, 0], np.inf)
    if np.any(status == 2) or np.any(~(condition < cond_limit)):
        worst = int(np.argmax(np.where(status == 2, np.inf, np.nan_to_num(condition, nan=np.inf))))
        raise SingularStructureError(
            f"instantaneous structure is singular (pivot ratio of the scaled joint stiffness "
            f"{float(condition[worst]):.3g} at batch index ({worst},)): a toggle position (collinear links at a "
            "revolute), an unconstrained joint, a member at its buckling load, or a speed at a natural frequency")
    total = negative[:, 0] + negative[:, 1]
    total = total + np.sum(np.where(lay.rigid, 0, clamped_clamped_buckling_count(s)), -1)
    if check_buckling and np.any(total > 0):
        raise BucklingError(buckling_message(prep.structure, {m.name: P[:, lay.seg_off[i]:lay.seg_off[i + 1]]
                                                              for i, m in enumerate(prep.structure.members)}, total))
    return states, q, reaction, total


def linear_solution(prep: Prepared, P, states, q, reaction, negative):
    """The :class:`tmm_core.structure.LinearSolution` of a :func:`solve_prepared` result."""
    from .structure import LinearSolution, MemberResult
    lay = prep.layout
    B = prep.factor.shape[0]
    out = {}
    for i, m in enumerate(prep.structure.members):
        sl = slice(lay.seg_off[i], lay.seg_off[i + 1])
        out[m.name] = MemberResult(m, prep.angle[:, i], prep.origin[m.name], states[:, lay.node_off[i]:lay.node_off[i + 1]],
                                   P[:, sl], np.zeros((B, m.n_segments)),
                                   prep.factor[:, sl] if prep.factor_given[m.name] else 1.0)
    index = {lab: k for k, lab in enumerate(lay.labels)}
    reactions = {}
    for j in prep.structure.joints:
        if j.support == "free":
            continue
        r = np.zeros((B, 3))
        r[:, 0] = reaction[:, index[(j.name, "x")]]
        r[:, 1] = reaction[:, index[(j.name, "y")]]
        if j.support == "clamped":
            r[:, 2] = reaction[:, index[(j.name, "r")]]
        reactions[j.name] = r
    joint_disp = {j.name: np.stack([q[:, index[(j.name, "x")]], q[:, index[(j.name, "y")]]], -1)
                  for j in prep.structure.joints}
    return LinearSolution(prep.structure, prep.case, out, reactions, negative, joint_disp, {})


def solve_linear(structure, case, axial_force: Mapping[str, np.ndarray] | None = None, *,
                 check_buckling: bool = True, cond_limit: float = 1e12,
                 stiffness_factor: Mapping[str, np.ndarray] | None = None, count_inertia: bool | None = None):
    """Compiled equivalent of :func:`tmm_core.structure.solve_linear` (small deflection, no chord
    rotation) for a :func:`supported` structure and a one-dimensional batch of configurations.
    Returns a :class:`tmm_core.structure.LinearSolution`; raises the same errors (singular
    structure, buckling), decided from the pivots of the factorization (module docstring)."""
    prep = prepare(structure, case, stiffness_factor)
    P = stack_segments(prep, axial_force or {})
    res = solve_prepared(prep, P, check_buckling=check_buckling, cond_limit=cond_limit, count_inertia=count_inertia)
    return linear_solution(prep, P, *res)


def stack_segments(prep: Prepared, per_member: Mapping[str, np.ndarray]) -> np.ndarray:
    """``{member: (B, n) or scalar}`` (missing: 0) as the stacked ``(B, S)`` array."""
    lay = prep.layout
    B, S = prep.factor.shape
    P = np.zeros((B, S))
    for i, m in enumerate(prep.structure.members):
        if m.name in per_member:
            P[:, lay.seg_off[i]:lay.seg_off[i + 1]] = np.broadcast_to(np.asarray(per_member[m.name], dtype=float),
                                                                      (B, m.n_segments))
    return P


def buckling_message(structure, axial_force: Mapping[str, np.ndarray], negative) -> str:
    """The refusal of a member at or beyond its buckling load (as :func:`tmm_core.structure.factorize`)."""
    worst_name, worst_ratio, worst_P, worst_Pcr = None, -np.inf, 0.0, 0.0
    for m in structure.members:
        P = axial_force[m.name]
        Pmin = float(np.min(P)) if P.size else 0.0
        Pcr = float(np.pi**2 * np.min(m.EI) / m.length**2)
        if -Pmin / Pcr > worst_ratio:
            worst_name, worst_ratio, worst_P, worst_Pcr = m.name, -Pmin / Pcr, Pmin, Pcr
    return (f"a member is at or beyond its buckling load: the stiffness has {int(np.max(negative))} negative "
            f"eigenvalue(s) (batch entries affected: {int(np.sum(negative > 0))} of {np.size(negative)}); most "
            f"compressed member '{worst_name}' carries P = {worst_P:.4g} N against its pinned-pinned Euler load "
            f"{worst_Pcr:.4g} N")


def solve_static(structure, case, *, beam_column: bool = False, tol: float = 1e-10, max_iter: int = 200,
                 count_inertia: bool | None = None):
    """Compiled equivalent of :func:`tmm_core.statics.solve_static` (linear or beam-column, not
    large deflection): the same successive linear solutions, relaxation and stopping rule, on
    the stacked arrays of one :class:`Prepared` batch."""
    from .statics import StaticSolution
    mode = "beam_column" if beam_column else "linear"
    prep = prepare(structure, case)
    lay = prep.layout
    P = np.zeros(prep.factor.shape)
    res = solve_prepared(prep, P, count_inertia=count_inertia)
    if not beam_column:
        return StaticSolution(linear_solution(prep, P, *res), mode, 1, 0.0)
    # Stacked forms of the iteration of tmm_core.statics: segment s of member i lies between
    # nodes s + i and s + i + 1; the change is weighted by the longest member.
    left = np.arange(int(lay.seg_off[-1])) + np.repeat(np.arange(len(lay.seg_off) - 1), np.diff(lay.seg_off))
    Lc = max(m.length for m in structure.members)
    w = np.array([1.0, 1.0, Lc, 1.0 / Lc, 1.0, 1.0])

    def axial(states):
        return np.where(lay.rigid, 0.0, 0.5 * (states[:, left, 1, 5] + states[:, left + 1, 0, 5]))

    def change(new, old):
        # NaN anywhere: non-finite (the compiled maxima skip NaN, so check it here).
        if not (np.isfinite(new[:, 0, 0, 0]).all() and np.isfinite(new).all()):
            return float("nan")
        dd, dscale, df, fscale = _COMPILED["change"](new, old, w)
        return max(dd / dscale if dscale > 0 else 0.0, df / fscale if fscale > 0 else 0.0)

    relax, prev_change = 1.0, np.inf
    P = axial(res[0])
    for it in range(2, max_iter + 1):
        new = solve_prepared(prep, P, count_inertia=count_inertia)
        ch = change(new[0], res[0])
        if not np.isfinite(ch):
            raise ConvergenceError(f"{mode} iteration produced non-finite values at iteration {it}")
        res, P_used = new, P
        if ch < tol:
            return StaticSolution(linear_solution(prep, P_used, *res), mode, it, ch)
        if ch > prev_change and relax > 0.15:
            relax *= 0.5
        prev_change = ch
        P = P + relax * (axial(res[0]) - P)
    raise ConvergenceError(f"{mode} iteration did not converge in {max_iter} iterations "
                           f"(last relative change {ch:.3g}, tolerance {tol:.3g})")
