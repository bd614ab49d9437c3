"""Closed-form rigid-body kinematics of the four-bar and the slider-crank.

Angles in radians, counter-clockwise positive, lengths in metres; all functions broadcast over
arrays of crank angle, speed and acceleration (one entry per crank position).

Four-bar: ground pivots A (crank) and D (rocker); crank A-B, coupler B-C, rocker D-C. The
crank angle is measured from the ground line A->D (architecture convention). ``branch = +1``
puts C on the left of the directed line B->D (the "open", upper assembly when A->D points
along +x), ``-1`` on the right.

Slider-crank: crank A-B, coupler B-C, slider C on a line parallel to the ground direction at
signed offset ``offset`` (left of the ground direction positive). ``branch = +1`` puts the
slider ahead of B along the ground direction.

Owns: closed-form four-bar and slider-crank kinematics. Boundaries: no dynamics.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import AssemblyError, InputError, require_finite, require_positive


def _e(a):
    return np.stack([np.cos(a), np.sin(a)], -1)


def _eperp(a):
    return np.stack([-np.sin(a), np.cos(a)], -1)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _check_branch(branch):
    if branch not in (1, -1):
        raise InputError(f"branch must be +1 or -1, got {branch!r}")


@dataclass(frozen=True)
class LinkMotion:
    """Rigid-body motion of one link: start point kinematics and angular motion (arrays)."""

    origin: np.ndarray        # (..., 2) position of the link's start joint [m]
    velocity: np.ndarray      # (..., 2) [m/s]
    acceleration: np.ndarray  # (..., 2) [m/s^2]
    angle: np.ndarray         # (...,) [rad]
    omega: np.ndarray         # (...,) [rad/s]
    alpha: np.ndarray         # (...,) [rad/s^2]

    def point(self, x, y=0.0):
        """Position, velocity and acceleration of material points at local ``(x, y)`` [m].

        ``x`` may be an array of stations (shape ``(k,)``); results have shape ``(..., k, 2)``
        (or ``(..., 2)`` for scalar x): ``a = a0 + alpha k x r - omega^2 r``.
        """
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        scalar = x.ndim == 0 and y.ndim == 0
        x, y = np.atleast_1d(x), np.atleast_1d(y)
        e, n = _e(self.angle)[..., None, :], _eperp(self.angle)[..., None, :]
        r = x[:, None] * e + y[:, None] * n
        kr = np.stack([-r[..., 1], r[..., 0]], -1)
        w, a = self.omega[..., None, None], self.alpha[..., None, None]
        pos = self.origin[..., None, :] + r
        vel = self.velocity[..., None, :] + w * kr
        acc = self.acceleration[..., None, :] + a * kr - w**2 * r
        if scalar:
            return pos[..., 0, :], vel[..., 0, :], acc[..., 0, :]
        return pos, vel, acc


@dataclass(frozen=True)
class FourBarGeometry:
    """Four-bar link lengths [m], ground pivot A and ground direction angle [rad], branch."""

    crank: float
    coupler: float
    rocker: float
    ground: float
    pivot: tuple = (0.0, 0.0)
    ground_angle: float = 0.0
    branch: int = 1

    def __post_init__(self):
        for name in ("crank", "coupler", "rocker", "ground"):
            require_positive(f"four-bar {name} length", getattr(self, name))
        require_finite("four-bar pivot", self.pivot)
        require_finite("four-bar ground_angle", self.ground_angle)
        _check_branch(self.branch)

    def describe(self) -> str:
        return (f"four-bar (crank {self.crank:.6g} m, coupler {self.coupler:.6g} m, rocker {self.rocker:.6g} m, "
                f"ground {self.ground:.6g} m)")

    def grashof_crank(self) -> bool:
        """True if the crank can turn fully (Grashof with the crank shortest)."""
        links = sorted([self.crank, self.coupler, self.rocker, self.ground])
        return links[0] + links[3] <= links[1] + links[2] and self.crank == links[0]


@dataclass(frozen=True)
class FourBarMotion:
    """Kinematics of a four-bar at a set of crank positions (arrays over positions)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    crank: LinkMotion
    coupler: LinkMotion
    rocker: LinkMotion

    def link(self, name: str) -> LinkMotion:
        return {"crank": self.crank, "coupler": self.coupler, "rocker": self.rocker}[name]


def fourbar_motion(geom: FourBarGeometry, crank_angle, crank_speed=0.0, crank_acceleration=0.0,
                   toggle_tolerance: float = 1e-9) -> FourBarMotion:
    """Closed-form position, velocity and acceleration of a four-bar.

    ``crank_angle`` [rad] from the ground line A->D, ``crank_speed`` [rad/s] and
    ``crank_acceleration`` [rad/s^2], CCW positive. Raises :class:`AssemblyError` where the
    linkage cannot assemble or where coupler and rocker are collinear (toggle), naming the
    geometry and the crank angle.
    """
    th = require_finite("crank_angle", crank_angle)
    w2 = require_finite("crank_speed", crank_speed)
    a2 = require_finite("crank_acceleration", crank_acceleration)
    th, w2, a2 = np.broadcast_arrays(th, w2, a2)
    g = geom
    A = np.broadcast_to(np.asarray(g.pivot, dtype=float), th.shape + (2,))
    D = A + g.ground * _e(np.full(th.shape, g.ground_angle))
    t2 = g.ground_angle + th
    B = A + g.crank * _e(t2)
    d = D - B
    r = np.hypot(d[..., 0], d[..., 1])
    slack = 1e-12 * (g.coupler + g.rocker)  # a dead point hit exactly is reported as a toggle below
    bad = (r > g.coupler + g.rocker + slack) | (r < abs(g.coupler - g.rocker) - slack)
    if np.any(bad):
        i = np.flatnonzero(bad.ravel())[0]
        ri = r.ravel()[i]
        why = ("longer than coupler + rocker" if ri > g.coupler + g.rocker else "shorter than |coupler - rocker|")
        raise AssemblyError(f"{g.describe()} cannot assemble at crank angle {np.degrees(th.ravel()[i]):.6g} deg: "
                            f"distance B-D = {ri:.6g} m is {why}")
    cos_g = np.clip((g.coupler**2 + r**2 - g.rocker**2) / (2 * g.coupler * r), -1.0, 1.0)
    t3 = np.arctan2(d[..., 1], d[..., 0]) + g.branch * np.arccos(cos_g)
    C = B + g.coupler * _e(t3)
    t4 = np.arctan2(C[..., 1] - D[..., 1], C[..., 0] - D[..., 0])

    # Loop B + b e3 = D + c e4 differentiated: [b e3perp, -c e4perp] (w3, w4) = -a w2 e2perp.
    col1 = g.coupler * _eperp(t3)
    col2 = -g.rocker * _eperp(t4)
    det = _cross(col1, col2)
    toggle = np.abs(det) <= toggle_tolerance * g.coupler * g.rocker
    if np.any(toggle):
        i = np.flatnonzero(toggle.ravel())[0]
        raise AssemblyError(f"{g.describe()} is at a toggle at crank angle {np.degrees(th.ravel()[i]):.6g} deg: "
                            "coupler and rocker are collinear, so the rocker motion is undefined")

    def solve(rhs):
        return _cross(rhs, col2) / det, _cross(col1, rhs) / det

    w3, w4 = solve(-g.crank * w2[..., None] * _eperp(t2))
    rhs = -(g.crank * a2[..., None] * _eperp(t2) - g.crank * (w2**2)[..., None] * _e(t2)
            - g.coupler * (w3**2)[..., None] * _e(t3) + g.rocker * (w4**2)[..., None] * _e(t4))
    a3, a4 = solve(rhs)

    zero = np.zeros(th.shape + (2,))
    crank = LinkMotion(A, zero, zero, t2, w2, a2)
    vB = g.crank * w2[..., None] * _eperp(t2)
    aB = g.crank * a2[..., None] * _eperp(t2) - g.crank * (w2**2)[..., None] * _e(t2)
    coupler = LinkMotion(B, vB, aB, t3, w3, a3)
    rocker = LinkMotion(D, zero, zero, t4, w4, a4)
    return FourBarMotion(A, B, C, D, crank, coupler, rocker)


@dataclass(frozen=True)
class SliderCrankGeometry:
    """Slider-crank: crank and coupler lengths [m], slider-line offset [m], pivot, ground direction."""

    crank: float
    coupler: float
    offset: float = 0.0
    pivot: tuple = (0.0, 0.0)
    ground_angle: float = 0.0
    branch: int = 1

    def __post_init__(self):
        require_positive("slider-crank crank length", self.crank)
        require_positive("slider-crank coupler length", self.coupler)
        require_finite("slider-crank offset", self.offset)
        require_finite("slider-crank pivot", self.pivot)
        require_finite("slider-crank ground_angle", self.ground_angle)
        _check_branch(self.branch)

    def describe(self) -> str:
        return (f"slider-crank (crank {self.crank:.6g} m, coupler {self.coupler:.6g} m, "
                f"offset {self.offset:.6g} m)")


@dataclass(frozen=True)
class SliderCrankMotion:
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray              # slider pin position [m]
    slider_position: np.ndarray      # s along the slide direction from the foot of A [m]
    slider_velocity: np.ndarray
    slider_acceleration: np.ndarray
    crank: LinkMotion
    coupler: LinkMotion

    def link(self, name: str) -> LinkMotion:
        return {"crank": self.crank, "coupler": self.coupler}[name]


def slider_crank_motion(geom: SliderCrankGeometry, crank_angle, crank_speed=0.0, crank_acceleration=0.0,
                        toggle_tolerance: float = 1e-9) -> SliderCrankMotion:
    """Closed-form kinematics of an (offset) slider-crank; crank angle from the slide direction."""
    th = require_finite("crank_angle", crank_angle)
    w2 = require_finite("crank_speed", crank_speed)
    a2 = require_finite("crank_acceleration", crank_acceleration)
    th, w2, a2 = np.broadcast_arrays(th, w2, a2)
    g = geom
    # Work in the ground frame (x along the slide), rotate at the end.
    bx, by = g.crank * np.cos(th), g.crank * np.sin(th)
    h = g.offset - by
    disc = g.coupler**2 - h**2
    if np.any(disc < -1e-12 * g.coupler**2):
        i = np.flatnonzero((disc < -1e-12 * g.coupler**2).ravel())[0]
        raise AssemblyError(f"{g.describe()} cannot assemble at crank angle {np.degrees(th.ravel()[i]):.6g} deg: "
                            f"the slider line is {abs(h.ravel()[i]):.6g} m from B, farther than the coupler")
    s = bx + g.branch * np.sqrt(np.maximum(disc, 0.0))
    t3 = np.arctan2(h, s - bx)
    c3 = np.cos(t3)
    if np.any(np.abs(c3) <= toggle_tolerance):
        i = np.flatnonzero((np.abs(c3) <= toggle_tolerance).ravel())[0]
        raise AssemblyError(f"{g.describe()} is at a toggle at crank angle {np.degrees(th.ravel()[i]):.6g} deg: "
                            "the coupler is perpendicular to the slide")
    vbx, vby = -g.crank * w2 * np.sin(th), g.crank * w2 * np.cos(th)
    abx = -g.crank * (a2 * np.sin(th) + w2**2 * np.cos(th))
    aby = g.crank * (a2 * np.cos(th) - w2**2 * np.sin(th))
    w3 = -vby / (g.coupler * c3)
    sd = vbx - g.coupler * w3 * np.sin(t3)
    a3 = (-aby + g.coupler * w3**2 * np.sin(t3)) / (g.coupler * c3)
    sdd = abx - g.coupler * a3 * np.sin(t3) - g.coupler * w3**2 * c3

    ga = g.ground_angle
    rot = np.array([[np.cos(ga), -np.sin(ga)], [np.sin(ga), np.cos(ga)]])
    A = np.broadcast_to(np.asarray(g.pivot, dtype=float), th.shape + (2,))

    def glob(x, y):
        return np.stack([x, y], -1) @ rot.T

    B = A + glob(bx, by)
    C = A + glob(s, np.broadcast_to(g.offset, s.shape))
    zero = np.zeros(th.shape + (2,))
    crank = LinkMotion(A, zero, zero, ga + th, w2, a2)
    coupler = LinkMotion(B, glob(vbx, vby), glob(abx, aby), ga + t3, w3, a3)
    return SliderCrankMotion(A, B, C, s, sd, sdd, crank, coupler)
