"""Numerically stable chaining of transfer matrices along a link (Riccati transfer).

Why not plain products
----------------------
Shin's method multiplies the 7x7 matrices of all segments of a link and then solves for the
boundary unknowns. The product contains exponentially growing and decaying solutions (cosh and
sinh of K*L under tension, of the beam wavenumber in dynamics) plus round-off from every
factor; the boundary equations then cancel large numbers against each other, so precision is
lost as segment count and axial force grow. ``tests/test_riccati.py`` measures it: at K*L = 40
the plain product is wrong in the first digit, the Riccati chain is at round-off.

Riccati transfer
----------------
Split the state into displacements ``z = (u, w, theta)`` and forces in conjugate order
``f = (N, V, M)``. Instead of carrying ``(z, f)`` we carry the *relations* between the start
station 0 and the current station i::

    f_0 = A z_0 + B z_i + a          (force entering the chain at its start)
    f_i = C z_0 + D z_i + c          (internal force at the current station)

``D`` is the usual Riccati matrix (the stiffness of the chain seen from station i); through a
transfer matrix ``T`` it becomes ``D' = (T21 + T22 D)(T11 + T12 D)^-1``. Each step inverts only
the small matrix ``G = T11 + T12 D``, which is (a multiple of) the stiffness Schur complement at
station i: the recursion is block Gaussian elimination of the chain's interior nodes, so its
precision does not depend on the number of segments.

At the end the chain is condensed to its end stations: the forces applied to the chain by the
outside are ``[F_start; F_end] = K [z_start; z_end] + load`` with ``F_start = -f_0`` and
``F_end = f_m``. ``K`` is symmetric for a conservative chain. The negative eigenvalues of the
eliminated Schur complements are counted (Sylvester's law of inertia); the structure solver
uses the count to detect buckling and to count natural frequencies (Wittrick-Williams).

Factorization and loads are separated: :func:`factor_chain` works on the 6x6 (homogeneous)
parts of the matrices only, and :func:`sweep_loads` pushes any set of load columns (column 7 of
the matrices) through it. A time-domain solver re-uses one factorization for every step with the
same geometry and dynamic stiffness. All arrays carry leading batch dimensions.

Owns: the Riccati transfer along a chain. Boundaries: no joints (tmm_core.structure).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .errors import InputError
from .matrices import F_IDX, ONE, Z_IDX

_Z = Z_IDX
_F = F_IDX


def _mv(A, x):
    """Batched matrix-vector product. For the 3x3 Riccati blocks the unrolled sum is 1.2-2.4x
    faster than einsum, most where one matrix batch meets many load columns (the unit-load maps
    of the time domain), which profiling showed to dominate the TMM engine's set-up."""
    if A.shape[-1] == 3:
        return A[..., :, 0] * x[..., None, 0] + A[..., :, 1] * x[..., None, 1] + A[..., :, 2] * x[..., None, 2]
    return np.einsum("...ij,...j->...i", A, x)


def inv3(A):
    """Inverse of (..., 3, 3) matrices. For large batches the adjugate formula is ~4x faster than
    ``np.linalg.inv`` (LAPACK per matrix); it is exact under row and column scaling, which is
    what the dimensionally mixed Riccati blocks need."""
    A = np.asarray(A)
    if A.ndim < 3 or A.size < 64 * 9:
        return np.linalg.inv(A)
    a, b, c = A[..., 0, 0], A[..., 0, 1], A[..., 0, 2]
    d, e, f = A[..., 1, 0], A[..., 1, 1], A[..., 1, 2]
    g, h, i = A[..., 2, 0], A[..., 2, 1], A[..., 2, 2]
    out = np.empty(A.shape, dtype=np.result_type(A, 1.0))
    out[..., 0, 0] = e * i - f * h
    out[..., 0, 1] = c * h - b * i
    out[..., 0, 2] = b * f - c * e
    out[..., 1, 0] = f * g - d * i
    out[..., 1, 1] = a * i - c * g
    out[..., 1, 2] = c * d - a * f
    out[..., 2, 0] = d * h - e * g
    out[..., 2, 1] = b * g - a * h
    out[..., 2, 2] = a * e - b * d
    det = a * out[..., 0, 0] + b * out[..., 1, 0] + c * out[..., 2, 0]
    if not np.all(np.isfinite(det)) or np.any(det == 0):
        return np.linalg.inv(A)   # raises LinAlgError for a singular matrix
    out /= det[..., None, None]
    return out


def _blocks(T6):
    """Split the 6x6 homogeneous part (state order u,w,th,M,V,N) into z/f blocks."""
    Tz, Tf = T6[..., _Z, :], T6[..., _F, :]
    return Tz[..., _Z], Tz[..., _F], Tf[..., _Z], Tf[..., _F]


def _split_load(t7):
    """Load column of a 7x7 (or 6-vector) into its z and f parts."""
    return t7[..., _Z], t7[..., _F]


def ldl_pivots(S) -> np.ndarray:
    """The pivots ``(..., n)`` of the LDL^T factorization (no pivoting) of symmetric matrices
    ``S (..., n, n)``, vectorised. Sylvester's law of inertia: as many pivots are negative as
    eigenvalues (the pivots are ratios of successive leading principal minors); after an exactly
    zero pivot (a singular leading block) the rest are not defined and are returned as zero."""
    S = np.array(S, dtype=float, copy=True)
    n = S.shape[-1]
    pivots = np.zeros(S.shape[:-1])
    for k in range(n):
        d = S[..., k, k]
        pivots[..., k] = d
        if k + 1 < n:
            l = np.divide(S[..., k + 1:, k], d[..., None], out=np.zeros(S[..., k + 1:, k].shape),
                          where=(d != 0.0)[..., None])
            S[..., k + 1:, k + 1:] -= l[..., :, None] * S[..., None, k, k + 1:]
    return pivots


def inertia_count(S) -> np.ndarray:
    """Number of negative eigenvalues of symmetric matrices ``S (..., n, n)`` from the signs of
    their LDL^T pivots (:func:`ldl_pivots`), without an eigenvalue problem. An exactly zero pivot
    (e.g. exactly at a buckling load) counts as non-negative."""
    return np.sum(ldl_pivots(S) < 0, axis=-1)


KINDS = ("field", "point", "load", "rigid")


@dataclass(frozen=True)
class ChainFactor:
    """Load-independent Riccati factorization of a chain of ``m`` transfer matrices.

    ``stiffness`` ``(..., 6, 6)``: forces applied to the chain at its ends per end displacement,
    ``[F_start; F_end] = stiffness @ [z_start; z_end] + load`` (load from :func:`sweep_loads`).
    ``negative_pivots`` ``(...,)``: negative eigenvalues of the eliminated interior Schur
    complements (only counted when requested).
    """

    stiffness: np.ndarray
    negative_pivots: np.ndarray
    n_stations: int
    first: int                # index of the first deformable matrix
    lead: tuple               # 6x6 parts of the matrices 0..first
    prefix: tuple             # their running products, stations 0..first
    init: tuple               # (B0, T22) of the first deformable step
    steps: tuple              # per matrix first+1..m-1: (kind, data) for the load sweep and back-substitution
    relations: tuple          # (C, D) at stations first+1..m
    start: tuple              # (A, B) final start relation


@dataclass(frozen=True)
class ChainLoads:
    """The load part of a chain solution: condensed end load and the recursion constants."""

    load: np.ndarray          # (..., 6) condensed end load, see ChainFactor.stiffness
    prefix: tuple             # load columns of the running products, stations 0..first
    a: np.ndarray             # final start-relation constant
    ys: tuple                 # back-substitution constants per step (None for point steps)
    cs: tuple                 # force-relation constants at stations first+1..m


def _kinds(deformable_or_kinds):
    out = []
    for k in deformable_or_kinds:
        if k is True or k is False or isinstance(k, (bool, np.bool_)):
            out.append("field" if k else "rigid")
        elif k in KINDS:
            out.append(k)
        else:
            raise InputError(f"chain matrix kind must be one of {KINDS} or a bool, got {k!r}")
    return out


def _stiffness_blocks(T11, T12, T21, T22):
    """One Riccati step from a free start: f_0 = A z_0 + B z_1, f_1 = C z_0 + D z_1."""
    B = inv3(T12)
    A = -B @ T11
    return A, B, T21 + T22 @ A, T22 @ B


def segment_stiffness(T):
    """Stiffness form of a single deformable transfer matrix (one Riccati step), vectorised.

    For ``S_1 = T S_0`` returns ``K (..., 6, 6)`` and ``r (..., 6)`` with
    ``[F_0; F_1] = K [z_0; z_1] + r``: the forces applied to the segment at its ends in the
    conjugate order (N, V, M) <-> (u, w, theta), local frame; ``r`` holds the fixed-end forces of
    the segment's own loads (column 7 of T).
    """
    T = np.asarray(T)
    T11, T12, T21, T22 = _blocks(T[..., :6, :6])
    t1, t2 = _split_load(T[..., :6, ONE])
    A, B, C, D = _stiffness_blocks(T11, T12, T21, T22)
    K = np.concatenate([np.concatenate([-A, -B], axis=-1), np.concatenate([C, D], axis=-1)], axis=-2)
    a = -_mv(B, t1)
    return K, np.concatenate([-a, _mv(T22, a) + t2], axis=-1)


def factor_chain(matrices: Sequence[np.ndarray], kinds: Sequence, count_inertia: bool = False) -> ChainFactor:
    """Factor a chain ``S_m = T_{m-1} ... T_0 S_0`` by the Riccati recursion (load columns ignored).

    ``kinds[j]``: 'field' for elastic segments (flexibility block ``T12`` invertible); 'point' for
    point matrices (identity except a stiffness ``T21`` and loads in the force rows); 'load' for
    point matrices without stiffness; 'rigid' for any other non-deformable matrix (frame
    rotations, rigid elements). Booleans are accepted as field (True) / rigid (False).
    ``count_inertia``: count the negative eigenvalues of the eliminated Schur complements.
    """
    kinds = _kinds(kinds)
    m = len(matrices)
    if m != len(kinds):
        raise InputError(f"factor_chain: {m} matrices but {len(kinds)} kinds")
    try:
        first = kinds.index("field")
    except ValueError:
        raise InputError("factor_chain: a chain needs at least one deformable segment") from None
    batch = np.broadcast_shapes(*(np.shape(T)[:-2] for T in matrices))

    lead = [np.asarray(matrices[j])[..., :6, :6] for j in range(first + 1)]
    prefix = [np.broadcast_to(np.eye(6), batch + (6, 6))]
    for j in range(first):
        prefix.append(prefix[-1] if kinds[j] == "load" else lead[j] @ prefix[-1])
    T11, T12, T21, T22 = _blocks(lead[first] @ prefix[-1])
    A, B, C, D = _stiffness_blocks(T11, T12, T21, T22)
    init = (B, T22)

    negative = np.zeros(batch, dtype=int)
    steps, relations = [], [(C, D)]
    for j in range(first + 1, m):
        kind = kinds[j]
        if kind == "load":
            steps.append(("load", None))
        elif kind == "point":
            K = np.asarray(matrices[j])[..., _F[:, None], _Z[None, :]]
            D = D + K
            steps.append(("point", D))
        else:
            T11, T12, T21, T22 = _blocks(np.asarray(matrices[j])[..., :6, :6])
            G = T11 + T12 @ D
            Gi = inv3(G)
            if count_inertia and kind == "field":
                schur = np.linalg.solve(T12, G)
                negative = negative + inertia_count(0.5 * (schur + np.swapaxes(schur, -1, -2)))
            X = T12 @ C
            HGi = (T21 + T22 @ D) @ Gi
            BGi = B @ Gi
            A = A - BGi @ X
            B = BGi
            C = T22 @ C - HGi @ X
            D = HGi
            steps.append(("full", (T12, T22, Gi, BGi, HGi, X)))
        relations.append((C, D))

    K = np.concatenate([np.concatenate([-A, -B], axis=-1), np.concatenate([C, D], axis=-1)], axis=-2)
    return ChainFactor(K, negative, m + 1, first, tuple(lead), tuple(prefix), init,
                       tuple(steps), tuple(relations), (A, B))


def load_column(T) -> np.ndarray:
    """Column 7 of a 7x7 transfer matrix without its last entry, ``(..., 6)``."""
    return np.asarray(T)[..., :6, ONE]


def sweep_loads(factor: ChainFactor, load_columns: Sequence[np.ndarray]) -> ChainLoads:
    """Push the load columns (``(..., 6)`` per matrix, see :func:`load_column`) through a
    factorization. Returns the condensed end load and the back-substitution constants.
    Point and load matrices must carry loads in their force rows only."""
    first = factor.first
    p = [np.zeros(np.shape(load_columns[0]))]
    for j in range(first):
        p.append(_mv(factor.lead[j], p[-1]) + load_columns[j])
    t1, t2 = _split_load(_mv(factor.lead[first], p[-1]) + load_columns[first])
    B0, T22 = factor.init
    a = -_mv(B0, t1)
    c = _mv(T22, a) + t2
    ys, cs = [], [c]
    for k, (kind, data) in enumerate(factor.steps):
        col = load_columns[first + 1 + k]
        if kind == "full":
            T12, T22s, Gi, BGi, HGi, X = data
            t1, t2 = _split_load(col)
            y = _mv(T12, c) + t1
            a = a - _mv(BGi, y)
            c = _mv(T22s, c) + t2 - _mv(HGi, y)
            ys.append(y)
        else:
            c = c + col[..., _F]
            ys.append(None)
        cs.append(c)
    return ChainLoads(np.concatenate([-a, c], axis=-1), tuple(p), a, tuple(ys), tuple(cs))


def _state(z, f):
    S = np.zeros(np.broadcast_shapes(z.shape, f.shape)[:-1] + (6,), dtype=np.result_type(z, f))
    S[..., _Z] = z
    S[..., _F] = f
    return S


def chain_states(factor: ChainFactor, loads: ChainLoads, z_start, z_end) -> np.ndarray:
    """States ``(..., m+1, 6)`` in order (u, w, theta, M, V, N) at every station, given the end
    displacements (local frame)."""
    z_start = np.asarray(z_start)
    z_end = np.asarray(z_end)
    A, B = factor.start
    f0 = _mv(A, z_start) + _mv(B, z_end) + loads.a
    S0 = _state(z_start, f0)
    m = factor.n_stations - 1
    first = factor.first
    states = [None] * (m + 1)
    for j in range(first + 1):
        states[j] = _mv(factor.prefix[j], S0) + loads.prefix[j]
    z = [None] * (m + 1)
    z[m] = z_end
    for j in range(m - 1, first, -1):
        kind, data = factor.steps[j - first - 1]
        if kind == "full":
            T12, T22, Gi, BGi, HGi, X = data
            z[j] = _mv(Gi, z[j + 1] - _mv(X, z_start) - loads.ys[j - first - 1])
        else:
            z[j] = z[j + 1]
    for j in range(first + 1, m + 1):
        C, D = factor.relations[j - first - 1]
        states[j] = _state(z[j], _mv(C, z_start) + _mv(D, z[j]) + loads.cs[j - first - 1])
    return np.stack(np.broadcast_arrays(*states), axis=-2)


def chain_product(matrices: Sequence[np.ndarray]) -> np.ndarray:
    """Plain product ``T_{m-1} ... T_0`` (Shin's chaining), kept for comparison and for short chains."""
    out = np.broadcast_to(np.eye(7), np.shape(matrices[0])).copy()
    for T in matrices:
        out = T @ out
    return out


def condense_chain(matrices: Sequence[np.ndarray], kinds: Sequence, count_inertia: bool = False):
    """Factor a chain and sweep its own load columns: returns ``(ChainFactor, ChainLoads)``."""
    factor = factor_chain(matrices, kinds, count_inertia)
    return factor, sweep_loads(factor, [load_column(T) for T in matrices])
