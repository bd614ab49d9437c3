"""The buckling checks the numpy and the compiled factorizations share.

A segment's own clamped-clamped buckling loads are the J0 term of the Wittrick-Williams count
(the factorization's negative pivots count the rest); a member at or beyond its buckling load is
refused with one message naming the most compressed member.

Owns: the clamped-clamped count and the buckling refusal. Boundaries: no factorization.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .closed_forms import euler_load_N


def clamped_clamped_buckling_count(s) -> np.ndarray:
    """Number of clamped-clamped buckling loads of a segment below ``s = P L^2/EI`` (P < 0).

    The roots are ``k L = 2 pi n`` (symmetric modes) and ``k L = 2 x`` with ``tan x = x``
    (antisymmetric). This is the J0 term of the Wittrick-Williams count for condensed segments.
    """
    s = np.asarray(s, dtype=float)
    if np.min(s, initial=0.0) > -4.0 * np.pi**2:      # kL < 2 pi everywhere, below the first root
        return np.zeros(s.shape, dtype=int)            # (the usual case; a NaN falls through)
    kl = np.sqrt(np.maximum(-s, 0.0))
    count = np.floor(kl / (2 * np.pi))
    x = kl / 2.0
    m = np.floor(x / np.pi)        # antisymmetric roots lie in (m pi, m pi + pi/2), m >= 1
    frac = x - m * np.pi
    past_root = (frac >= np.pi / 2) | ((frac > 0) & (np.tan(np.minimum(frac, np.pi / 2 - 1e-12)) > x))
    count = count + np.maximum(m - 1, 0) + np.where((m >= 1) & past_root, 1, 0)
    return count.astype(int)


def buckling_message(structure, axial_force: Mapping[str, np.ndarray], negative) -> str:
    """The refusal of a member at or beyond its buckling load: the negative-eigenvalue count
    ``negative`` (per batch entry) and the most compressed member against its pinned-pinned Euler
    load (an orientation for the user); ``axial_force``: {member: segment forces [N]}. The numpy
    and the compiled factorization (:mod:`tmm_core.compiled.statics`) refuse with it."""
    worst_name, worst_ratio, worst_P, worst_Pcr = None, -np.inf, 0.0, 0.0
    for m in structure.members:
        P = np.asarray(axial_force[m.name])
        Pmin = float(np.min(P)) if P.size else 0.0
        Pcr = euler_load_N(float(np.min(m.EI)), m.length)
        if -Pmin / Pcr > worst_ratio:
            worst_name, worst_ratio, worst_P, worst_Pcr = m.name, -Pmin / Pcr, Pmin, Pcr
    negative = np.asarray(negative)
    where = f" (batch entries affected: {int(np.sum(negative > 0))} of {negative.size})" if negative.ndim else ""
    return (f"a member is at or beyond its buckling load: the stiffness has {int(np.max(negative))} negative "
            f"eigenvalue(s){where}; most compressed member '{worst_name}' carries P = {worst_P:.4g} N "
            f"against its pinned-pinned Euler load {worst_Pcr:.4g} N")
