"""Numerically stable chaining of transfer matrices along a link (Riccati transfer).

Why not plain products
----------------------
Shin's method multiplies the 7x7 matrices of all segments of a link and then solves for the
boundary unknowns. The product contains exponentially growing and decaying solutions (cosh and
sinh of K*L under tension, of the beam wavenumber in dynamics) plus round-off from every
factor; the boundary equations then cancel large numbers against each other, so precision is
lost as segment count and axial force grow (see ``tests/test_riccati.py`` for a measurement).

Riccati transfer
----------------
Split the state into displacements ``z = (u, w, theta)`` and forces in conjugate order
``f = (N, V, M)``. Instead of carrying ``(z, f)`` we carry the *relations* between the start
station 0 and the current station i::

    f_0 = A z_0 + B z_i + a          (force entering the chain at its start)
    f_i = C z_0 + D z_i + c          (internal force at the current station)

``D`` is the usual Riccati matrix (the stiffness of the chain seen from station i), and the
recursion through a transfer matrix ``T`` is ``D' = (T21 + T22 D)(T11 + T12 D)^-1``. Each step
inverts only the small matrix ``G = T11 + T12 D``, which is (a multiple of) the stiffness
Schur complement at station i; the recursion is block Gaussian elimination of the chain's
interior nodes, so its precision does not depend on the number of segments.

At the end the chain is condensed to its end stations: the forces applied to the chain by the
outside are ``[F_start; F_end] = K [z_start; z_end] + load`` with ``F_start = -f_0`` and
``F_end = f_m``. ``K`` is symmetric for a conservative chain. The number of negative
eigenvalues of the eliminated Schur complements is counted (Sylvester's law of inertia), which
the structure solver uses to detect buckling (Wittrick-Williams).

All arrays carry leading batch dimensions (e.g. crank positions).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .errors import InputError
from .matrices import F_IDX, ONE, Z_IDX, split_blocks


@dataclass(frozen=True)
class ChainCondensation:
    """A chain of transfer matrices condensed to its two end stations.

    ``stiffness`` ``(..., 6, 6)`` and ``load`` ``(..., 6)`` give the forces applied to the chain
    at its ends, ``[F_start; F_end] = stiffness @ [z_start; z_end] + load``, with z in
    ``(u, w, theta)`` and F in ``(N-direction, V-direction, moment)`` order, local frame.
    ``negative_pivots`` counts negative eigenvalues of the eliminated interior Schur complements.
    """

    stiffness: np.ndarray
    load: np.ndarray
    negative_pivots: np.ndarray
    n_stations: int
    _prefix: tuple          # partial products of the leading non-deformable matrices
    _first: int             # index of the first deformable matrix
    _steps: tuple           # (Ginv, X, y) for matrices first+1 .. m-1
    _relations: tuple       # (C, D, c) at stations first+1 .. m
    _start: tuple           # (A, B, a) final start relation


def _state(z, f):
    S = np.zeros(np.broadcast_shapes(z.shape, f.shape)[:-1] + (7,), dtype=np.result_type(z, f))
    S[..., Z_IDX] = z
    S[..., F_IDX] = f
    S[..., ONE] = 1.0
    return S


def _mv(A, x):
    return np.einsum("...ij,...j->...i", A, x)


def condense_chain(matrices: Sequence[np.ndarray], deformable: Sequence[bool]) -> ChainCondensation:
    """Condense a chain ``S_m = T_{m-1} ... T_1 T_0 S_0`` by the Riccati recursion.

    ``deformable[j]`` must be True for field matrices of elastic segments (their flexibility
    block ``T12`` is invertible) and False for point, frame-rotation and rigid-element matrices.
    At least one matrix must be deformable.
    """
    m = len(matrices)
    if m != len(deformable):
        raise InputError(f"condense_chain: {m} matrices but {len(deformable)} deformable flags")
    try:
        first = next(j for j, d in enumerate(deformable) if d)
    except StopIteration:
        raise InputError("condense_chain: a chain needs at least one deformable segment") from None

    prefix = [np.broadcast_to(np.eye(7), np.shape(matrices[0])).copy()]
    for j in range(first):
        prefix.append(matrices[j] @ prefix[-1])
    T = matrices[first] @ prefix[-1]
    T11, T12, T21, T22, t1, t2 = split_blocks(T)
    B = np.linalg.inv(T12)
    A = -B @ T11
    a = -_mv(B, t1)
    C = T21 + T22 @ A
    D = T22 @ B
    c = _mv(T22, a) + t2

    batch = np.broadcast_shapes(*(np.shape(Tj)[:-2] for Tj in matrices))
    negative = np.zeros(batch, dtype=int)
    steps, relations = [], [(C, D, c)]
    for j in range(first + 1, m):
        T11, T12, T21, T22, t1, t2 = split_blocks(matrices[j])
        G = T11 + T12 @ D
        Gi = np.linalg.inv(G)
        if deformable[j]:
            schur = np.linalg.solve(T12, G)
            negative = negative + np.sum(np.linalg.eigvalsh(0.5 * (schur + np.swapaxes(schur, -1, -2))) < 0, axis=-1)
        X = T12 @ C
        y = _mv(T12, c) + t1
        H = T21 + T22 @ D
        HGi = H @ Gi
        BGi = B @ Gi
        A = A - BGi @ X
        a = a - _mv(BGi, y)
        B = BGi
        C = T22 @ C - HGi @ X
        c = _mv(T22, c) + t2 - _mv(HGi, y)
        D = HGi
        steps.append((Gi, X, y))
        relations.append((C, D, c))

    K = np.concatenate([np.concatenate([-A, -B], axis=-1), np.concatenate([C, D], axis=-1)], axis=-2)
    load = np.concatenate([-a, c], axis=-1)
    return ChainCondensation(K, load, negative, m + 1, tuple(prefix), first,
                             tuple(steps), tuple(relations), (A, B, a))


def chain_states(cond: ChainCondensation, z_start, z_end) -> np.ndarray:
    """Full states ``(..., m+1, 7)`` at every station, given the end displacements (local frame)."""
    z_start = np.asarray(z_start)
    z_end = np.asarray(z_end)
    A, B, a = cond._start
    f0 = _mv(A, z_start) + _mv(B, z_end) + a
    S0 = _state(z_start, f0)
    m = cond.n_stations - 1
    first = cond._first
    states = [None] * (m + 1)
    for j, P in enumerate(cond._prefix):
        states[j] = _mv(P, S0)
    # Displacements of stations first+1 .. m by back-substitution.
    z = [None] * (m + 1)
    z[m] = z_end
    for j in range(m - 1, first, -1):
        Gi, X, y = cond._steps[j - first - 1]
        z[j] = _mv(Gi, z[j + 1] - _mv(X, z_start) - y)
    for j in range(first + 1, m + 1):
        C, D, c = cond._relations[j - first - 1]
        states[j] = _state(z[j], _mv(C, z_start) + _mv(D, z[j]) + c)
    return np.stack(np.broadcast_arrays(*states), axis=-2)


def chain_product(matrices: Sequence[np.ndarray]) -> np.ndarray:
    """Plain product ``T_{m-1} ... T_0`` (Shin's chaining), kept for comparison and for short chains."""
    out = np.broadcast_to(np.eye(7), np.shape(matrices[0])).copy()
    for T in matrices:
        out = T @ out
    return out
