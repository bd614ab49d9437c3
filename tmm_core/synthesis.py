"""Rigid four-bar synthesis (FE thesis Ch. III; docs/validation.md): a crank-rocker from its
rocker swing and limit positions.

Thesis notation (Fig. 1): crank pivot M, crank pin A, coupler-rocker pin B, rocker pivot Q, with
a = crank MA, b = coupler AB, c = rocker QB, d = ground MQ (the bench's A, B, C, D). Lengths are
metres at the interface (the equations use ratios to d), angles radians, CCW positive; the linkage
is the open assembly (B above the ground line M->Q). At the *extended* limit crank and coupler are
in line (MB = a + b), at the *folded* limit folded on each other (MB = b - a); the rocker reverses.

* ``theta1``: crank angle at the extended limit (angle Q-M-B, from the ground line M->Q).
* ``theta3``: angle Q-M-B at the folded limit, i.e. the crank angle there minus pi.
* ``phi2``, ``phi4``: angle M-Q-B at the rocker pivot at the extended / folded limit.
* ``oscillation`` = phi2 - phi4: the rocker swing (Delta phi).
* ``mu2``, ``mu4``: angle M-B-Q (the transmission angle) at the extended / folded limit.
* ``mu1``: transmission angle with the crank along M->Q (crank angle 0), the smallest of a revolution.

Owns: rigid four-bar synthesis (the Grashof class and limit positions it checks are
:mod:`tmm_core.fourbar_limits`'s). Boundaries: no flexible analysis,
no I/O (the bench's ``cosim synthesize`` reads its options and writes its scenario).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq, least_squares

from .errors import ConvergenceError, InputError, require_positive
from .fourbar_limits import grashof_class, limit_positions
from .kinematics import FourBarGeometry

RESIDUAL_TOLERANCE = 1e-10   # of the thesis equations in ratios to d and radians: round-off, not "close"
CHECK_TOLERANCE = 1e-8       # rad: the synthesized linkage through the bench's kinematics


def _deg(x: float) -> str:
    return f"{math.degrees(x):.6g} deg"


@dataclass(frozen=True)
class FourBarSynthesis:
    """A crank-rocker: lengths [m], angles [rad] (module docstring), the largest residual of the
    thesis equations, and its :func:`limit_positions` (bench convention)."""

    case: str
    crank: float
    coupler: float
    rocker: float
    ground: float
    oscillation: float
    phi2: float
    phi4: float
    mu1: float
    mu2: float
    mu4: float
    theta1: float
    theta3: float
    residual: float
    limits: dict


def _require_angle(name: str, value: float) -> float:
    if not (math.isfinite(value) and 0 < value < math.pi):
        raise InputError(f"{name} = {_deg(value)}: must lie strictly between 0 and 180 deg")
    return float(value)


def _polish(equations, start, what: str) -> tuple[np.ndarray, float]:
    """Bounded least squares (3 length ratios > 0, angles in [0, pi]); only a round-off residual passes."""
    n = len(start) - 3
    fit = least_squares(equations, start, bounds=([1e-12] * 3 + [0.0] * n, [np.inf] * 3 + [math.pi] * n),
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    residual = float(np.max(np.abs(fit.fun)))
    if not fit.success or residual > RESIDUAL_TOLERANCE:
        raise ConvergenceError(f"{what}: least squares ended with residual {residual:.3g} ({fit.message})")
    return fit.x, residual


def _case_one_equations(x, oscillation, phi4, mu1):
    """Eqs. 3.4-3.9 in ratios to d (d = 1), with the corrected sign of Eq. 3.5 (angle sum - pi)."""
    a, b, c, phi2, mu2, theta1 = x
    return [phi4 - phi2 + oscillation,
            mu2 + theta1 + phi2 - math.pi,
            c * math.sin(mu2) - math.sin(theta1),
            b - 0.5 * (math.sqrt(c * c + 1 - 2 * c * math.cos(phi2)) + math.sqrt(c * c + 1 - 2 * c * math.cos(phi4))),
            a - 1 + math.sqrt(b * b + c * c - 2 * b * c * math.cos(mu1)),
            theta1 - math.acos(min(1.0, max(-1.0, (1 - c * math.cos(phi2)) / (b + a))))]


def _case_one_start(c, phi2, phi4, mu1):
    """Closed form given the rocker ratio c (MB = a + b and b - a from the limit triangles, theta1
    and mu2 from the extended one), and the residual of Eq. 3.8, the one equation left in c."""
    extended = math.sqrt(c * c + 1 - 2 * c * math.cos(phi2))
    folded = math.sqrt(c * c + 1 - 2 * c * math.cos(phi4))
    a, b = (extended - folded) / 2, (extended + folded) / 2
    theta1 = math.atan2(c * math.sin(phi2), 1 - c * math.cos(phi2))
    x = np.array([a, b, c, phi2, math.pi - theta1 - phi2, theta1])
    return x, a - 1 + math.sqrt(b * b + c * c - 2 * b * c * math.cos(mu1))


def _finish(case, x, ground, oscillation, residual) -> FourBarSynthesis:
    """Derive the other limit angles, classify, and check the linkage through the bench's kinematics."""
    a, b, c, phi2, phi4, mu2, theta1 = x
    theta3 = math.atan2(c * math.sin(phi4), 1 - c * math.cos(phi4))
    mu1 = math.acos((b * b + c * c - (1 - a) ** 2) / (2 * b * c))
    if (kind := grashof_class(a, b, c, 1.0)) != "crank-rocker":
        raise InputError(f"the solution crank {a * ground:.6g} m, coupler {b * ground:.6g} m, rocker "
                         f"{c * ground:.6g} m (ground {ground:.6g} m) is a {kind}, not a crank-rocker")
    limits = limit_positions(FourBarGeometry(a * ground, b * ground, c * ground, ground))
    expected = {"oscillation_rad": oscillation, "crank_angle_extended_rad": theta1,
                "crank_angle_folded_rad": theta3 + math.pi, "rocker_angle_extended_rad": math.pi - phi2,
                "rocker_angle_folded_rad": math.pi - phi4, "transmission_min_rad": mu1}
    for key, value in expected.items():
        if abs(limits[key] - value) > CHECK_TOLERANCE:
            raise ConvergenceError(f"case {case}: the synthesized linkage has {key} = {limits[key]!r} in the bench's "
                                   f"kinematics, the synthesis {value!r}")
    return FourBarSynthesis(case, a * ground, b * ground, c * ground, ground, oscillation, phi2, phi4, mu1, mu2,
                            math.pi - theta3 - phi4, theta1, theta3, residual, limits)


def synthesize_case_one(ground: float, oscillation: float, rocker_limit: float,
                        min_transmission: float) -> FourBarSynthesis:
    """Case I: crank-rocker from the ground length d [m], the rocker swing ``oscillation`` (Delta
    phi), the folded rocker limit ``rocker_limit`` (phi4) and the minimum transmission angle
    ``min_transmission`` (mu1) [rad]: Eqs. 3.4-3.9 for (a, b, c, phi2, mu2, theta1).

    Given c, every unknown follows from the two limit triangles, leaving Eq. 3.8 in c: its roots,
    bracketed on c/d in [1e-3, 1e3], are polished as the full system by bounded least squares. Of
    several crank-rockers, the one with the best worst transmission angle min(mu_min, pi - mu_max)
    is returned; :class:`InputError` names the input when there is none."""
    ground = float(require_positive("ground", ground))
    oscillation = _require_angle("oscillation", oscillation)
    phi4 = _require_angle("rocker_limit", rocker_limit)
    mu1 = _require_angle("min_transmission", min_transmission)
    phi2 = _require_angle("rocker_limit + oscillation (the extended rocker limit phi2)", phi4 + oscillation)
    grid = np.geomspace(1e-3, 1e3, 601)
    f = np.array([_case_one_start(c, phi2, phi4, mu1)[1] for c in grid])
    roots = [brentq(lambda c: _case_one_start(c, phi2, phi4, mu1)[1], grid[i], grid[i + 1], xtol=1e-15)
             for i in np.flatnonzero(f[:-1] * f[1:] <= 0)]
    found, refused = [], []
    for c in roots:
        start = _case_one_start(c, phi2, phi4, mu1)[0]        # a > 0, angles in (0, pi): two real triangles
        x, residual = _polish(lambda x: _case_one_equations(x, oscillation, phi4, mu1), start, "case I")
        a, b, c, phi2_x, mu2, theta1 = x
        try:
            found.append(_finish("I", (a, b, c, phi2_x, phi4, mu2, theta1), ground, oscillation, residual))
        except InputError as exc:
            refused.append(str(exc))
    if not found:
        raise InputError(f"min_transmission = {_deg(mu1)}: no Grashof crank-rocker reaches it with oscillation "
                         f"{_deg(oscillation)}, rocker_limit {_deg(phi4)} and ground {ground:.6g} m"
                         + (f" ({'; '.join(refused)})" if refused else ""))
    return max(found, key=lambda s: min(s.limits["transmission_min_rad"], math.pi - s.limits["transmission_max_rad"]))


def _case_two_equations(x, oscillation, theta1, theta3):
    """Eqs. 3.10-3.17 in ratios to d; G1, G2 (lost in the OCR) restored as in case I, Eq. 3.16
    multiplied through by cos(theta1) so that theta1 = 90 deg is allowed."""
    a, b, c, phi2, phi4, mu2, mu4 = x
    return [phi4 - phi2 + oscillation,
            mu2 + theta1 + phi2 - math.pi,
            mu4 - theta1 + theta3 - oscillation - mu2,
            c * math.sin(mu4) - math.sin(theta3),
            b - 0.5 * c * (math.sin(phi2) / math.sin(theta1) + math.sin(phi4) / math.sin(theta3)),
            a * math.cos(theta1) - (1 - c * math.cos(phi2) - b * math.cos(theta1)),
            math.sin(phi4) - (b - a) * math.sin(theta3) / c]


def synthesize_case_two(ground: float, oscillation: float, theta1: float, theta3: float) -> FourBarSynthesis:
    """Case II: crank-rocker from the ground length d [m], the rocker swing ``oscillation`` and the
    crank's limit positions ``theta1`` (crank angle at the extended limit) and ``theta3`` (crank
    angle at the folded limit minus pi) [rad]: Eqs. 3.10-3.17 for (a, b, c, phi2, phi4, mu2, mu4).
    Start: the law of sines in both limit triangles gives c/d = sin theta1 / sin(theta1 + phi2) =
    sin theta3 / sin(theta3 + phi2 - Delta phi), a sinusoid in phi2 with one root in (0, pi); it is
    polished as the full system by bounded least squares."""
    ground = float(require_positive("ground", ground))
    oscillation = _require_angle("oscillation", oscillation)
    theta1 = _require_angle("theta1 (crank angle at the extended limit)", theta1)
    theta3 = _require_angle("theta3 (crank angle at the folded limit - 180 deg)", theta3)
    beta = theta3 - oscillation
    sin_coeff = math.sin(theta1) * math.cos(beta) - math.sin(theta3) * math.cos(theta1)
    cos_coeff = math.sin(theta1) * math.sin(beta) - math.sin(theta3) * math.sin(theta1)
    phi2 = math.atan2(-cos_coeff, sin_coeff) % math.pi
    phi4 = phi2 - oscillation
    mu2, mu4 = math.pi - theta1 - phi2, math.pi - theta3 - phi4
    c = math.sin(theta1) / math.sin(mu2) if mu2 > 0 else math.nan       # law of sines, extended triangle
    extended, folded = c * math.sin(phi2) / math.sin(theta1), c * math.sin(phi4) / math.sin(theta3)
    if not (math.hypot(sin_coeff, cos_coeff) > 1e-12 and min(phi4, mu4) > 0 and extended > folded > 0):
        raise InputError(f"theta1 = {_deg(theta1)}, theta3 = {_deg(theta3)}, oscillation = {_deg(oscillation)}: "
                         f"no four-bar has these limit positions (the limit triangles close only with phi2 = "
                         f"{_deg(phi2)}, phi4 = {_deg(phi4)}, mu2 = {_deg(mu2)}, mu4 = {_deg(mu4)}, crank + "
                         f"coupler = {extended * ground:.6g} m, coupler - crank = {folded * ground:.6g} m)")
    start = np.array([(extended - folded) / 2, (extended + folded) / 2, c, phi2, phi4, mu2, mu4])
    x, residual = _polish(lambda x: _case_two_equations(x, oscillation, theta1, theta3), start, "case II")
    a, b, c, phi2, phi4, mu2, _ = x
    return _finish("II", (a, b, c, phi2, phi4, mu2, theta1), ground, oscillation, residual)
