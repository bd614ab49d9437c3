"""Anderson-accelerated fixed-point iteration of a revolution map, for periodic shooting from a
good first guess (the previous speed's orbit in a sweep).

The periodic state is the fixed point ``x = F(x)`` of the revolution map ``F`` (one revolution
marched from the state ``x``). Plain revolutions converge at the rate of the largest Floquet
multiplier; Anderson mixing (type II, mixing parameter 1) combines the last few revolutions so
that the directions they have already explored converge at once: near a stable orbit it needs a
few revolutions and no monodromy (each revolution of the FE rig costs about a third of a
monodromy matrix). It does not converge to an unstable orbit reliably, so it reports a stall
and the caller falls back to Newton shooting from its best iterate.

The residual is the periodic solvers' own check: ``max|F(x) - x| / max|x|`` (dimensionless).
The least-squares mixing runs in weighted coordinates (``weights``, one per state component),
since a state stacks displacements [m], velocities [m/s] and accelerations [m/s^2] whose sizes
differ by orders of magnitude.

Owns: the accelerated fixed-point iteration. Boundaries: no model knowledge; the revolution is
the caller's.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .errors import TMMError


@dataclass(frozen=True)
class AndersonOptions:
    """``tolerance``: the residual at which the iteration stops (the solver's own tolerance);
    ``iterations``: the most revolutions; ``memory``: how many previous revolutions the mixing
    combines; ``window``, ``rate``: a stall is a residual that has not fallen by ``rate`` over the
    last ``window`` revolutions."""

    tolerance: float
    iterations: int = 30
    memory: int = 6
    window: int = 3
    rate: float = 0.5


@dataclass
class FixedPoint:
    """The iteration's end: ``x`` (the best iterate: the lowest residual), ``image`` (what the
    revolution returned at ``x``), ``residual`` there, ``revolutions`` marched and whether the
    residual reached the tolerance (``converged``)."""

    x: np.ndarray
    image: object
    residual: float
    revolutions: int
    converged: bool


def anderson_coefficients(dR, r):
    """Least-squares coefficients ``gamma`` of ``dR gamma = r`` (dR: (n, h), h <= ANDERSON_DEPTH)
    by modified Gram-Schmidt QR; a column whose remaining norm is below 1e-12 of the largest
    column's (a rank-deficient history) gets a zero coefficient. The same arithmetic as the
    compiled march's (:mod:`tmm_core.compiled.march`), which it is checked against. The one
    least-squares step of Anderson mixing: the second-order step's and the revolutions' (below)."""
    h = dR.shape[1]
    Q = np.array(dR, dtype=float)
    R = np.zeros((h, h))
    gamma = np.zeros(h)
    # A diverging iteration can overflow here: the coefficients are then not finite and the
    # caller restarts the mixing (as the compiled march does); no warnings.
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        big = float(np.max(np.sqrt(np.sum(Q * Q, axis=0))))
        for c in range(h):
            for p in range(c):
                R[p, c] = Q[:, p] @ Q[:, c]
                Q[:, c] -= R[p, c] * Q[:, p]
            R[c, c] = math.sqrt(float(Q[:, c] @ Q[:, c]))
            Q[:, c] = Q[:, c] / R[c, c] if R[c, c] > 1e-12 * big else 0.0
        for c in range(h - 1, -1, -1):
            if R[c, c] > 1e-12 * big:
                gamma[c] = (Q[:, c] @ r - R[c, c + 1:] @ gamma[c + 1:]) / R[c, c]
    return gamma


def residual_of(x: np.ndarray, x_end: np.ndarray) -> float:
    """The periodic solvers' residual: the state's change over a revolution relative to its size."""
    return float(np.max(np.abs(x_end - x)) / max(float(np.max(np.abs(x))), 1e-300))


def anderson(revolve: Callable, x0: np.ndarray, weights: np.ndarray, options: AndersonOptions) -> FixedPoint:
    """Fixed point of ``revolve`` from ``x0``. ``revolve(x)`` returns ``(x_end, image)``: the state
    after one revolution from ``x`` and anything the caller wants back from it (trajectory,
    outputs). A revolution that raises a :class:`tmm_core.errors.TMMError` or leaves the finite
    range ends the iteration as a stall (the best iterate so far is returned)."""
    xs, fs, history = [], [], []
    best = None
    x = np.asarray(x0, dtype=float).copy()
    for k in range(1, options.iterations + 1):
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                x_end, image = revolve(x)
        except (TMMError, np.linalg.LinAlgError):
            break
        if not np.all(np.isfinite(x_end)):
            break
        r = residual_of(x, x_end)
        history.append(r)
        if best is None or r < best.residual:
            best = FixedPoint(x.copy(), image, r, k, r < options.tolerance)
        if r < options.tolerance:
            best.revolutions = k
            return best
        if len(history) > options.window and r > options.rate * history[-1 - options.window]:
            break
        xs.append(x)
        fs.append(x_end)
        xs, fs = xs[-(options.memory + 1):], fs[-(options.memory + 1):]
        x = _mixed(xs, fs, weights)
    if best is None:            # the first revolution already failed: nothing to fall back from but x0
        return FixedPoint(np.asarray(x0, dtype=float).copy(), None, np.inf, len(history), False)
    best.revolutions = len(history)
    return best


def _mixed(xs: list, fs: list, weights: np.ndarray) -> np.ndarray:
    """The next iterate from the stored iterates ``xs`` and their images ``fs``: the image of the
    last one less the combination of image differences that best cancels its residual (weighted
    least squares)."""
    f_last = fs[-1]
    if len(xs) == 1:
        return f_last.copy()
    G = np.stack([(f - x) * weights for x, f in zip(xs, fs)], axis=1)      # weighted residuals
    dG = np.diff(G, axis=1)
    dF = np.diff(np.stack(fs, axis=1), axis=1)
    gamma = anderson_coefficients(dG, G[:, -1])
    return f_last - dF @ gamma


def block_weights(x: np.ndarray, blocks: int) -> np.ndarray:
    """Weights that give each of ``blocks`` equal parts of the state vector ``x`` (e.g.
    displacements, velocities, accelerations) the same size in the mixing: one over each part's
    largest magnitude (one for a part that is zero)."""
    parts = np.split(np.abs(np.asarray(x, dtype=float)), blocks)
    return np.concatenate([np.full(len(p), 1.0 / (float(p.max()) if p.size and p.max() > 0 else 1.0))
                           for p in parts])
