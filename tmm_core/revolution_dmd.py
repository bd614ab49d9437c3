"""The dominant Floquet multipliers of a periodic orbit read off successive revolutions near it.

Near a periodic orbit the revolution map is linear in the distance to the orbit, so the
changes from one revolution to the next, ``d_k = y_{k+1} - y_k`` of any quantity ``y`` sampled
at the same crank angles (a state vector, or the gauges' strains over a revolution), evolve as
``d_{k+1} = M d_k`` with the monodromy ``M`` seen through that quantity. A dynamic mode
decomposition of a few such changes gives the eigenvalues of ``M`` that dominate them: the
largest Floquet multipliers, without the monodromy itself. Differences rather than distances to
the orbit, so the orbit need not be known more closely than the iterates show it.

Why: the full monodromy of the FE rig's transfer-matrix model (162 columns marched through the
step's exact Jacobian) costs about 25 revolutions of the nonlinear map; a sweep needs only the
largest multiplier of each point. And the same reading compares engines that have no monodromy
at all (exudyn's transients, ``studies/light_damping.py``).

Owns: the reading. Boundaries: the revolutions come from the caller.
"""
from __future__ import annotations

import numpy as np


def dominant_multipliers(snapshots: np.ndarray, rank: int = 6, floor: float = 1e-9) -> tuple[np.ndarray, int]:
    """``(multipliers, changes)``: the Floquet multipliers (largest modulus first) that dominate the
    revolution-to-revolution changes of ``snapshots`` (K, m), one row per revolution, each column
    scaled to a comparable size by the caller, and how many changes they were read from. Changes
    whose largest entry is below ``floor`` (the rounding of a settled orbit) are left out, and
    only the first unbroken run of usable ones is read; the rank is at most ``rank`` and at most
    the changes read minus one (each mode needs one change to map onto the next), and singular
    values below 1e-9 of the largest are cut. Empty when fewer than two changes are usable."""
    changes = np.diff(np.asarray(snapshots, dtype=float), axis=0)
    usable = np.flatnonzero(np.abs(changes).max(axis=1) > floor)
    if len(usable) < 2:
        return np.zeros(0, dtype=complex), int(len(usable))
    # A contiguous run from the first usable change (later ones at the floor would be noise).
    stop = usable[0] + int(np.argmax(np.diff(np.r_[usable, usable[-1] + 2]) > 1)) + 1
    D = changes[usable[0]:stop].T
    if D.shape[1] < 2:
        return np.zeros(0, dtype=complex), int(D.shape[1])
    U, S, Vt = np.linalg.svd(D[:, :-1], full_matrices=False)
    r = min(rank, D.shape[1] - 1, int(np.sum(S > S[0] * 1e-9)))
    r = max(r, 1)
    A = U[:, :r].T @ D[:, 1:] @ Vt[:r].T / S[:r]
    mu = np.linalg.eigvals(A)
    return mu[np.argsort(-np.abs(mu))], int(D.shape[1])
