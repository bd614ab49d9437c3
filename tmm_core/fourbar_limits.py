"""Grashof class, limit positions and transmission-angle range of a given four-bar (rigid
kinematics, closed form).

At a limit position of a crank-rocker the crank and the coupler are in line and the rocker
reverses: *extended* when the crank pin lies between the crank pivot and the rocker pin (A-C =
crank + coupler), *folded* when they overlap (A-C = coupler - crank). Each limit is a triangle
A-C-D with three known sides, so its crank angle follows from the law of cosines: no root
search (and no scipy, which a run would otherwise import to print its summary).

Bench kinematics and conventions (:func:`tmm_core.fourbar_motion`): crank angles [rad] from the
ground line A->D, CCW; rocker angles [rad] of D->C from that line; the geometry's assembly branch.

Owns: the Grashof class and the limit positions of a four-bar. Boundaries: no synthesis (that
is :mod:`tmm_core.synthesis`), no flexible analysis, no I/O.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .kinematics import FourBarGeometry, fourbar_motion

TWO_PI = 2 * math.pi


def wrap_angle(x):
    """Angle(s) [rad] wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(x)))


def grashof_class(crank: float, coupler: float, rocker: float, ground: float, rtol: float = 1e-12) -> str:
    """Grashof class: shortest s and longest l with s + l <= p + q give a link that turns fully.

    'crank-rocker' (crank shortest), 'double-crank' (ground shortest), 'double-rocker' (coupler
    shortest), 'rocker-crank' (rocker shortest); ' (change point)' is appended when s + l = p + q
    (the links can fall in line, a toggle); 'non-Grashof triple-rocker' when s + l > p + q.
    """
    named = {"crank": crank, "coupler": coupler, "rocker": rocker, "ground": ground}
    s, p, q, l = sorted(named.values())
    excess = s + l - (p + q)
    if excess > rtol * l:
        return "non-Grashof triple-rocker"
    shortest = min(("ground", "crank", "coupler", "rocker"), key=lambda k: named[k])   # ties: ground first
    kind = {"crank": "crank-rocker", "ground": "double-crank", "coupler": "double-rocker",
            "rocker": "rocker-crank"}[shortest]
    return kind + (" (change point)" if abs(excess) <= rtol * l else "")


def limit_crank_angle(geometry: FourBarGeometry, folded: bool) -> float:
    """Crank angle [rad, 0..2 pi) of a limit position, where crank and coupler are in line and
    the rocker pin C lies ``reach`` [m] from the crank pivot: ``crank + coupler`` at the extended
    limit, ``coupler - crank`` at the ``folded`` one (the crank pointing away from C).

    The triangle A-C-D (sides ``reach``, rocker, ground) gives the angle of A->C from the ground
    line up to its sign; of the two mirror positions the one on the geometry's assembly branch is
    taken, i.e. the one where the bench's kinematics puts C at ``reach`` from A."""
    g = geometry
    reach = g.coupler - g.crank if folded else g.crank + g.coupler
    cos_angle = (reach ** 2 + g.ground ** 2 - g.rocker ** 2) / (2 * reach * g.ground)
    angle = math.acos(min(1.0, max(-1.0, cos_angle)))
    turn = math.pi if folded else 0.0          # folded: the crank points opposite A->C
    candidates = np.mod(np.array([angle, -angle]) + turn, TWO_PI)
    m = fourbar_motion(g, candidates)
    miss = np.abs(np.hypot(*(m.C - m.A).T) - reach)
    return float(candidates[int(np.argmin(miss))])


def limit_positions(geometry: FourBarGeometry) -> dict:
    """Limit positions and transmission-angle range of a four-bar whose crank turns fully.

    The limits are where crank and coupler fall in line (:func:`limit_crank_angle`), which is
    where the rocker's speed changes sign. The transmission angle (interior angle at C, 0..pi)
    grows with the distance B-D, i.e. from crank angle 0 (minimum) to pi (maximum).

    Keys: ``grashof`` (:func:`grashof_class`), ``crank_angle_{extended,folded}_rad``,
    ``rocker_angle_{extended,folded}_rad``, ``oscillation_rad``, ``time_ratio`` (longer over shorter
    crank arc between the limits; these six are None for a double-crank, whose rocker never
    reverses), ``transmission_{min,max}_rad``, ``crank_angle_transmission_{min,max}_rad``. Raises
    :class:`InputError` if the crank cannot turn fully, :class:`tmm_core.AssemblyError` at a toggle.
    """
    g = geometry
    kind = grashof_class(g.crank, g.coupler, g.rocker, g.ground)
    if kind not in ("crank-rocker", "double-crank"):
        raise InputError(f"limit positions need a crank that turns a full revolution without a toggle; "
                         f"{g.describe()} is a {kind}")
    ends = fourbar_motion(g, np.array([0.0, math.pi]))      # interior angle B-C-D = angle of coupler to rocker
    mu_min, mu_max = np.abs(wrap_angle(ends.coupler.angle - ends.rocker.angle)).tolist()
    out = {"grashof": kind, "transmission_min_rad": mu_min, "transmission_max_rad": mu_max,
           "crank_angle_transmission_min_rad": 0.0, "crank_angle_transmission_max_rad": math.pi}
    names = ("crank_angle_extended_rad", "crank_angle_folded_rad", "rocker_angle_extended_rad",
             "rocker_angle_folded_rad", "oscillation_rad", "time_ratio")
    if kind == "double-crank":
        return out | dict.fromkeys(names)
    extended = limit_crank_angle(g, folded=False)
    folded = limit_crank_angle(g, folded=True)
    rocker = wrap_angle(fourbar_motion(g, np.array([extended, folded])).rocker.angle - g.ground_angle).tolist()
    arc = (folded - extended) % TWO_PI
    return out | dict(zip(names, (extended, folded, rocker[0], rocker[1], abs(float(wrap_angle(rocker[0] - rocker[1]))),
                                  max(arc, TWO_PI - arc) / min(arc, TWO_PI - arc))))
