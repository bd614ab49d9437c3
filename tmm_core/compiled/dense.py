"""Small dense helpers of the compiled factorization (:mod:`tmm_core.compiled.structure`): Stumpff
functions, 3x3 inverse and product, LDL^T inertia, the compiled layer's one LU (partial pivoting,
LAPACK's row-swap pivots, blocked by four columns; its solves for one right-hand side and for
many, which the joint system of every configuration and the reduced model's Newton matrix share),
the sparse blocks of a segment's field matrix, and the beam-column iteration's change and
stopping rule. Plain Python here; :mod:`tmm_core.compiled.binding` compiles them (numba, cached on
disk: the LU in ``binding.lu``, the others in ``binding.static_solve``) and binds the compiled
objects where the kernels look them up.

Owns: the small dense numba helpers of the compiled factorization (Stumpff functions, 3x3
algebra, LDL^T inertia, the one LU). Boundaries: no structure knowledge; compiled by
tmm_core.compiled.binding.
"""
from __future__ import annotations

import math

import numpy as np

from ..matrices import SERIES_LIMIT


def stumpff(s, inv_fact, out):
    """``out[k] = c_k(s)``, k = 0..4 (see :func:`tmm_core.matrices.stumpff`)."""
    a_ = abs(s)
    if a_ < SERIES_LIMIT:
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


def inv3(A, out):
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


def mm3(A, B, out):
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


def ldl_inertia(S, n, work):
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


def copy_states(dst, src):
    """``dst[...] = src`` for station-state arrays ``(Nn, 2, 6)``, element by element: a slice
    assignment compiles numba's broadcasting checks and their error messages (about 1.5 s of a
    first run's compilation)."""
    for i in range(src.shape[0]):
        for side in range(2):
            for k in range(6):
                dst[i, side, k] = src[i, side, k]


def state_change(new, old, w, scales):
    """Relative change between two station-state arrays ``(Nn, 2, 6)`` of one configuration,
    weighted by ``w (6,)`` (as :func:`tmm_core.statics.solve_static`'s change): the larger of the
    largest displacement change over ``scales[0]`` and the largest force change over
    ``scales[1]`` (the largest displacement and force of the batch; 0: not counted). NaN if
    ``new`` is not finite."""
    dd = 0.0
    df = 0.0
    for i in range(new.shape[0]):
        for side in range(2):
            for k in range(6):
                x = new[i, side, k]
                if not math.isfinite(x):
                    return math.nan
                d = abs(x - old[i, side, k]) * w[k]
                if k < 3:
                    dd = max(dd, d)
                else:
                    df = max(df, d)
    return max(dd / scales[0] if scales[0] > 0.0 else 0.0, df / scales[1] if scales[1] > 0.0 else 0.0)


def iteration_start(start, P, seg_off, L, EI, factor, rigid, negative, pivots, status, weights, scales, cond_limit,
                    check_buckling):
    """Between the linear solve of a batch (station states ``start (B, Nn, 2, 6)``) and its
    beam-column iteration, in the driver call that does both
    (:func:`tmm_core.compiled.statics.iterate_prepared`). True if the linear solve passes the checks
    of :func:`tmm_core.compiled.statics._checked` (``status`` 0, pivot ratio below
    ``cond_limit``, with ``check_buckling`` no negative pivot), its states are finite and the
    tension parameters ``P L^2 / EI`` of the initial axial forces stay below 700^2 (cosh
    overflow); then ``scales (2,)`` holds the batch's change scales (as
    :func:`tmm_core.statics.change_scales`: the largest weighted |displacement| and |force|)
    and ``P (B, S)`` the initial axial forces [N] (mean of each segment's two end values, 0 for
    rigid segments). False otherwise: the caller repeats the checks in Python, which raise."""
    B = start.shape[0]
    for b in range(B):
        if status[b] != 0 or not (pivots[b, 0] > 0.0 and pivots[b, 1] / pivots[b, 0] < cond_limit):
            return False
        if check_buckling and negative[b, 0] + negative[b, 1] > 0:
            return False
    # Max is exact: the largest |entry| of each column times its weight is the float value
    # that numpy's reduction in statics.change_scales gives.
    big = np.zeros(6)
    for b in range(B):
        for i in range(start.shape[1]):
            for side in range(2):
                for k in range(6):
                    x = abs(start[b, i, side, k])
                    if not x < math.inf:
                        return False
                    if x > big[k]:
                        big[k] = x
    d = 0.0
    f = 0.0
    for k in range(3):
        d = max(d, big[k] * weights[k])
        f = max(f, big[k + 3] * weights[k + 3])
    scales[0] = d
    scales[1] = f
    for b in range(B):
        for mi in range(seg_off.shape[0] - 1):
            for sg in range(seg_off[mi], seg_off[mi + 1]):
                node = sg + mi
                p = 0.0 if rigid[sg] else 0.5 * (start[b, node, 1, 5] + start[b, node + 1, 0, 5])
                P[b, sg] = p
                if p * (L[sg] * L[sg]) / (EI[sg] * factor[b, sg]) > 490000.0:
                    return False
    return True


def iteration_converged(c1, c2, c3, n, tol):
    """The stopping rule of the successive linear solutions, on the last three relative changes
    ``c1, c2, c3`` (``c3`` the last; ``n`` changes so far): see
    :func:`tmm_core.statics.iteration_converged`, which applies it to every configuration of a
    batch in the numpy path; the compiled iteration calls it directly."""
    if c3 < tol:
        return True
    if n < 3 or not (0.0 < c1 < math.inf and 0.0 < c2 < math.inf and 0.0 < c3 < math.inf):
        return False
    r = max(c3 / c2, c2 / c1)
    return r < 0.5 and c3 * r / (1.0 - r) < tol


def lu_factor(a, piv):
    """In-place LU with partial pivoting of the square ``a`` (LAPACK getrf's pivots, rows swapped
    whole); ``piv[k]`` is the row swapped with row k. Blocked by 4 columns: the trailing update
    subtracts four pivot rows in one pass over each row (half the memory traffic of one at a
    time), on one-dimensional row views (which numba's loops vectorize better than 2-D indexing):
    measured 2.5x faster than the plain loop at 69 x 69. Returns False when a pivot is exactly
    zero (a singular matrix); the factorization still runs to its end, with infinities and NaNs
    where it divided by that pivot, which a caller may let propagate instead of checking."""
    n = a.shape[0]
    regular = True
    for k0 in range(0, n, 4):
        k1 = min(k0 + 4, n)
        # Panel: columns k0..k1-1 of every row below, with the pivot search over all of them.
        for k in range(k0, k1):
            p = k
            big = abs(a[k, k])
            for i in range(k + 1, n):
                if abs(a[i, k]) > big:
                    big = abs(a[i, k])
                    p = i
            piv[k] = p
            if big == 0.0:
                regular = False
            if p != k:
                for j in range(n):
                    t = a[k, j]
                    a[k, j] = a[p, j]
                    a[p, j] = t
            inv = 1.0 / a[k, k]
            for i in range(k + 1, n):
                l_ = a[i, k] * inv
                a[i, k] = l_
                for j in range(k + 1, k1):
                    a[i, j] -= l_ * a[k, j]
        # The pivot rows right of the panel, then the trailing rows.
        for k in range(k0, k1):
            for i in range(k + 1, k1):
                l_ = a[i, k]
                for j in range(k1, n):
                    a[i, j] -= l_ * a[k, j]
        if k1 - k0 == 4:
            m = n - k1
            p0, p1, p2, p3 = a[k0, k1:], a[k0 + 1, k1:], a[k0 + 2, k1:], a[k0 + 3, k1:]
            for i in range(k1, n):
                l0, l1, l2, l3 = a[i, k0], a[i, k0 + 1], a[i, k0 + 2], a[i, k0 + 3]
                row = a[i, k1:]
                for j in range(m):
                    row[j] -= l0 * p0[j] + l1 * p1[j] + l2 * p2[j] + l3 * p3[j]
        else:
            for i in range(k1, n):
                for k in range(k0, k1):
                    l_ = a[i, k]
                    for j in range(k1, n):
                        a[i, j] -= l_ * a[k, j]
    return regular


def dot(x, y, lo, hi):
    """``sum x[lo:hi] y[lo:hi]`` with four partial sums (a single running sum waits on the
    latency of every addition: 3x slower)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    k = lo
    while k + 4 <= hi:
        s0 += x[k] * y[k]
        s1 += x[k + 1] * y[k + 1]
        s2 += x[k + 2] * y[k + 2]
        s3 += x[k + 3] * y[k + 3]
        k += 4
    while k < hi:
        s0 += x[k] * y[k]
        k += 1
    return (s0 + s1) + (s2 + s3)


def lu_solve(lu, piv, b):
    """``b <- A^{-1} b`` in place for one right-hand side (``lu``, ``piv`` from lu_factor)."""
    n = lu.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t
    for i in range(n):
        b[i] -= dot(lu[i], b, 0, i)
    for i in range(n - 1, -1, -1):
        b[i] = (b[i] - dot(lu[i], b, i + 1, n)) / lu[i, i]


def lu_solve_many(lu, piv, B):
    """``B <- A^{-1} B`` in place for the columns of ``B``: row operations on contiguous rows,
    four rows of the factor at a time (as in lu_factor)."""
    n, m = B.shape
    for k in range(n):
        p = piv[k]
        if p != k:
            for j in range(m):
                t = B[k, j]
                B[k, j] = B[p, j]
                B[p, j] = t
    # np.int64(0), not a bare 0: numba would compile subtract_rows once more for the literal.
    for i in range(n):                       # forward: L Y = B (unit diagonal)
        subtract_rows(lu, i, B, np.int64(0), i)
    for i in range(n - 1, -1, -1):           # backward: U X = Y
        subtract_rows(lu, i, B, i + 1, n)
        inv = 1.0 / lu[i, i]
        row = B[i]
        for j in range(m):
            row[j] *= inv


def subtract_rows(lu, i, B, lo, hi):
    """``B[i] -= sum(lu[i, k] B[k] for lo <= k < hi)``, four rows of ``B`` per pass over ``B[i]``."""
    m = B.shape[1]
    row = B[i]
    k = lo
    while k + 4 <= hi:
        l0, l1, l2, l3 = lu[i, k], lu[i, k + 1], lu[i, k + 2], lu[i, k + 3]
        b0, b1, b2, b3 = B[k], B[k + 1], B[k + 2], B[k + 3]
        for j in range(m):
            row[j] -= l0 * b0[j] + l1 * b1[j] + l2 * b2[j] + l3 * b3[j]
        k += 4
    while k < hi:
        l_ = lu[i, k]
        b0 = B[k]
        for j in range(m):
            row[j] -= l_ * b0[j]
        k += 1


def segment_blocks(l, ea, ei, p_, qt, qa, is_rigid, inv_fact, c5, sp, t1, t2):
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
    stumpff(p_ * l2 * rei, inv_fact, c5)
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


def full6(sp, t1, t2, T, t):
    """The 6x6 homogeneous part (state order u, w, theta, M, V, N) and load column of a segment
    from :func:`segment_blocks`."""
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
