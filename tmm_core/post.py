"""Post-processing: surface stresses and strains, distortion, safety factors.

Faces: "top" is the local +y surface (y = +h/2), "bottom" the -y surface. With the sign
convention of :mod:`tmm_core.matrices` the surface stress is ``sigma = N/A - M y / I``, so
``sigma_top = N/A - M/Z`` and ``sigma_bottom = N/A + M/Z``; tension is positive. (Shin writes
``N/A + M/Z`` for the top with his clockwise-positive M.)

Owns: stresses, strains, distortion, safety factors from solved states. Boundaries: no solving.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_finite, require_positive
from .matrices import field_matrix
from .structure import MemberResult


def _side_sections(member):
    """Per node, the segment index used for the left and the right side: (n+1, 2)."""
    n = member.n_segments
    j = np.arange(n + 1)
    return np.stack([np.clip(j - 1, 0, n - 1), np.clip(j, 0, n - 1)], -1)


def surface_stresses(result: MemberResult):
    """``(sigma_top, sigma_bottom)`` [Pa], each ``(..., n+1, 2)`` (node, left/right side)."""
    m = result.member
    seg = _side_sections(m)
    A = np.array([s.area_m2 for s in m.sections])[seg]
    Z = np.array([s.section_modulus_m3 for s in m.sections])[seg]
    axial = result.N / A
    bending = result.M / Z
    return axial - bending, axial + bending


def surface_strains(result: MemberResult):
    """Surface strains ``(eps_top, eps_bottom)`` [-], ``(..., n+1, 2)``, tension positive."""
    m = result.member
    E = np.array([mat.E_Pa for mat in m.materials])[_side_sections(m)]
    top, bottom = surface_stresses(result)
    return top / E, bottom / E


def bending_axial_strain(eps_top, eps_bottom):
    """Bending = (top - bottom)/2 and axial = (top + bottom)/2 strain (architecture convention)."""
    return 0.5 * (eps_top - eps_bottom), 0.5 * (eps_top + eps_bottom)


def distortion(result: MemberResult) -> np.ndarray:
    """Distance between the rigid-body and the deformed node position [m], ``(..., n+1)``."""
    return np.hypot(*np.moveaxis(result.displacement, -1, 0))


def static_safety_factor(result: MemberResult, yield_strength_Pa=None) -> np.ndarray:
    """Maximum-normal-stress safety factor ``S_y / max(|sigma_top|, |sigma_bottom|)`` per node.

    Uses each segment's material yield strength unless ``yield_strength_Pa`` is given. Nodes
    with zero stress get ``inf``.
    """
    m = result.member
    if yield_strength_Pa is None:
        ys = [mat.yield_strength_Pa for mat in m.materials]
        if any(v is None for v in ys):
            raise ValueError(f"member '{m.name}': material has no yield_strength_Pa for a safety factor")
        Sy = np.array(ys)[_side_sections(m)]
    else:
        Sy = require_positive("yield_strength_Pa", yield_strength_Pa)
    top, bottom = surface_stresses(result)
    ratio = np.maximum(np.abs(top), np.abs(bottom)) / Sy
    worst = np.max(ratio, axis=-1)
    with np.errstate(divide="ignore"):
        return np.where(worst > 0, 1.0 / worst, np.inf)


def soderberg(stress_history, yield_strength_Pa, endurance_limit_Pa, axis=0):
    """Soderberg fatigue safety factor over a stress history (Shin Eq. 6.6, reconstructed).

    ``S_mean = (S_max + S_min)/2``, ``S_alt = (S_max - S_min)/2`` along ``axis`` (one input-link
    revolution), ``1/SF = |S_mean|/S_y + S_alt/S_n``. Returns ``(SF, S_mean, S_alt)``.
    """
    Sy = require_positive("yield_strength_Pa", yield_strength_Pa)
    Sn = require_positive("endurance_limit_Pa", endurance_limit_Pa)
    s = np.asarray(stress_history, dtype=float)
    smax, smin = s.max(axis=axis), s.min(axis=axis)
    mean, alt = 0.5 * (smax + smin), 0.5 * (smax - smin)
    inv = np.abs(mean) / Sy + alt / Sn
    with np.errstate(divide="ignore"):
        return np.where(inv > 0, 1.0 / inv, np.inf), mean, alt


FACES = ("top", "bottom")


@dataclass(frozen=True)
class Gauge:
    """A strain gauge on ``link`` at ``position_m`` from the link's start joint, on the local
    ``face`` ('top' = +y, 'bottom' = -y). Its bending strain is the face's bending strain
    (positive = tension on the gauged face) and its axial strain the mean strain N/EA."""

    name: str
    link: str
    position_m: float
    face: str = "top"

    def __post_init__(self):
        if self.face not in FACES:
            raise InputError(f"gauge '{self.name}': face must be one of {FACES}, got {self.face!r}")
        require_finite(f"gauge '{self.name}': position_m", self.position_m)


def segment_at(stations: np.ndarray, x: float) -> int:
    """The segment (numbered from the member's start) that a position ``x`` [m] lies in, for node
    coordinates ``stations`` (n + 1,): the one starting at or before ``x``, the last at the end. A
    gauge reads its state there (:func:`state_at`), and the time step samples it from there
    (:func:`tmm_core.discretization.axial_sampling`, :func:`tmm_core.discretization.bending_sampling`)."""
    return int(np.clip(np.searchsorted(stations, x, side="right") - 1, 0, len(stations) - 2))


def state_at(result: MemberResult, x, distributed=(0.0, 0.0)) -> np.ndarray:
    """State ``(..., 6)`` = (u, w, theta, M, V, N) at ``x`` [m] along the member, by carrying the
    right-side state of the node before ``x`` through a partial field matrix (exact within the
    segment). ``distributed`` = (p, q) local distributed load on that segment [N/m]."""
    m = result.member
    st = m.stations
    if not (-1e-12 * m.length <= x <= m.length * (1 + 1e-12)):
        raise InputError(f"member '{m.name}': position {x!r} m is outside the member (length {m.length:.6g} m)")
    j = segment_at(st, x)
    dx = float(x - st[j])
    S = result.state[..., j, 1, :]
    if dx <= 1e-15 * m.length:
        return S.copy()
    f = result.stiffness_factor
    fj = np.asarray(f)[..., j] if np.ndim(f) else f
    T = field_matrix(dx, m.EA[j] * fj, m.EI[j] * fj, result.axial_force[..., j], distributed[1], distributed[0],
                     result.chord_rotation[..., j])
    return np.einsum("...ij,...j->...i", T[..., :6, :6], S) + T[..., :6, 6]


def gauge_strains(result: MemberResult, gauge: Gauge, distributed=(0.0, 0.0), axial_sampling=None):
    """``(bending, axial)`` strain [-] at a gauge, arrays over the batch dimensions.

    ``axial_sampling = ((j, k), (w_j, w_k))`` reads the axial strain as ``w_j`` times segment
    ``j``'s plus ``w_k`` times segment ``k``'s (each its axial force over its stiffness), as a
    lumped-mass model needs (:func:`tmm_core.discretization.axial_sampling`); without it, the
    axial force at the gauge's position."""
    m = result.member
    S = state_at(result, gauge.position_m, distributed)
    j = segment_at(m.stations, gauge.position_m)
    sec, mat = m.sections[j], m.materials[j]
    curvature = S[..., 3] / (mat.E_Pa * sec.inertia_m4 * _stiffness_factor(result, j))
    sign = -1.0 if gauge.face == "top" else 1.0      # sigma = N/A - M y / I
    bending = sign * curvature * 0.5 * sec.depth_m
    if axial_sampling is None:
        return bending, S[..., 5] / (mat.E_Pa * sec.area_m2 * _stiffness_factor(result, j))
    axial = sum(w * result.state[..., s, 1, 5] / (m.materials[s].E_Pa * m.sections[s].area_m2
                                                  * _stiffness_factor(result, s))
                for s, w in zip(*axial_sampling) if w != 0.0)
    return bending, axial


def _stiffness_factor(result: MemberResult, j: int):
    """The stiffness factor of segment ``j`` of a result (a scalar or an array over its batch)."""
    f = result.stiffness_factor
    return np.asarray(f)[..., j] if np.ndim(f) else f
