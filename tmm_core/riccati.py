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
    return np.einsum("...ij,...j->...i", A, x)


def _blocks(T6):
    """Split the 6x6 homogeneous part (state order u,w,th,M,V,N) into z/f blocks."""
    Tz, Tf = T6[..., _Z, :], T6[..., _F, :]
    return Tz[..., _Z], Tz[..., _F], Tf[..., _Z], Tf[..., _F]


def _split_load(t7):
    """Load column of a 7x7 (or 6-vector) into its z and f parts."""
    return t7[..., _Z], t7[..., _F]


@dataclass(frozen=True)
class ChainFactor:
    """Load-independent Riccati factorization of a chain of ``m`` transfer matrices.

    ``stiffness`` ``(..., 6, 6)``: forces applied to the chain at its ends per end displacement,
    ``[F_start; F_end] = stiffness @ [z_start; z_end] + load`` (load from :func:`sweep_loads`).
    ``negative_pivots`` ``(...,)``: negative eigenvalues of the eliminated interior Schur complements.
    """

    stiffness: np.ndarray
    negative_pivots: np.ndarray
    n_stations: int
    first: int                # index of the first deformable matrix
    lead: tuple               # 6x6 parts of the matrices 0..first (non-deformable ones, then the first field)
    prefix: tuple             # their running products, stations 0..first
    init: tuple               # (B0, T22) of the first deformable step
    steps: tuple              # per matrix first+1..m-1: (T12, T22, Gi, BGi, HGi, X)
    relations: tuple          # (C, D) at stations first+1..m
    start: tuple              # (A, B) final start relation


@dataclass(frozen=True)
class ChainLoads:
    """The load part of a chain solution: condensed end load and the recursion constants."""

    load: np.ndarray          # (..., 6) condensed end load, see ChainFactor.stiffness
    prefix: tuple             # load columns of the running products, stations 0..first
    a: np.ndarray             # final start-relation constant
    ys: tuple                 # back-substitution constants per step
    cs: tuple                 # force-relation constants at stations first+1..m


def factor_chain(matrices: Sequence[np.ndarray], deformable: Sequence[bool]) -> ChainFactor:
    """Factor a chain ``S_m = T_{m-1} ... T_0 S_0`` by the Riccati recursion (load columns ignored).

    ``deformable[j]`` must be True for field matrices of elastic segments (their flexibility
    block ``T12`` is invertible) and False for point, frame-rotation and rigid-element matrices.
    """
    m = len(matrices)
    if m != len(deformable):
        raise InputError(f"factor_chain: {m} matrices but {len(deformable)} deformable flags")
    try:
        first = next(j for j, d in enumerate(deformable) if d)
    except StopIteration:
        raise InputError("factor_chain: a chain needs at least one deformable segment") from None
    H6 = [np.asarray(T)[..., :6, :6] for T in matrices]
    batch = np.broadcast_shapes(*(T.shape[:-2] for T in H6))

    prefix = [np.broadcast_to(np.eye(6), batch + (6, 6))]
    for j in range(first):
        prefix.append(H6[j] @ prefix[-1])
    T11, T12, T21, T22 = _blocks(H6[first] @ prefix[-1])
    B = np.linalg.inv(T12)
    A = -B @ T11
    C = T21 + T22 @ A
    D = T22 @ B
    init = (B, T22)

    negative = np.zeros(batch, dtype=int)
    steps, relations = [], [(C, D)]
    for j in range(first + 1, m):
        T11, T12, T21, T22 = _blocks(H6[j])
        G = T11 + T12 @ D
        Gi = np.linalg.inv(G)
        if deformable[j]:
            schur = np.linalg.solve(T12, G)
            negative = negative + np.sum(
                np.linalg.eigvalsh(0.5 * (schur + np.swapaxes(schur, -1, -2))) < 0, axis=-1)
        X = T12 @ C
        HGi = (T21 + T22 @ D) @ Gi
        BGi = B @ Gi
        A = A - BGi @ X
        B = BGi
        C = T22 @ C - HGi @ X
        D = HGi
        steps.append((T12, T22, Gi, BGi, HGi, X))
        relations.append((C, D))

    K = np.concatenate([np.concatenate([-A, -B], axis=-1), np.concatenate([C, D], axis=-1)], axis=-2)
    return ChainFactor(K, negative, m + 1, first, tuple(H6[:first + 1]), tuple(prefix), init,
                       tuple(steps), tuple(relations), (A, B))


def load_column(T) -> np.ndarray:
    """Column 7 of a 7x7 transfer matrix without its last entry, ``(..., 6)``."""
    return np.asarray(T)[..., :6, ONE]


def sweep_loads(factor: ChainFactor, load_columns: Sequence[np.ndarray]) -> ChainLoads:
    """Push the load columns (``(..., 6)`` per matrix, see :func:`load_column`) through a
    factorization. Returns the condensed end load and the back-substitution constants."""
    first = factor.first
    p = [np.zeros(np.shape(load_columns[0]))]
    for j in range(first):
        p.append(_mv(factor.lead[j], p[-1]) + load_columns[j])
    t1, t2 = _split_load(_mv(factor.lead[first], p[-1]) + load_columns[first])
    B0, T22 = factor.init
    a = -_mv(B0, t1)
    c = _mv(T22, a) + t2
    ys, cs = [], [c]
    for k, (T12, T22s, Gi, BGi, HGi, X) in enumerate(factor.steps):
        t1, t2 = _split_load(load_columns[first + 1 + k])
        y = _mv(T12, c) + t1
        a = a - _mv(BGi, y)
        c = _mv(T22s, c) + t2 - _mv(HGi, y)
        ys.append(y)
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
        T12, T22, Gi, BGi, HGi, X = factor.steps[j - first - 1]
        z[j] = _mv(Gi, z[j + 1] - _mv(X, z_start) - loads.ys[j - first - 1])
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


def condense_chain(matrices: Sequence[np.ndarray], deformable: Sequence[bool]):
    """Factor a chain and sweep its own load columns: returns ``(ChainFactor, ChainLoads)``."""
    factor = factor_chain(matrices, deformable)
    return factor, sweep_loads(factor, [load_column(T) for T in matrices])
