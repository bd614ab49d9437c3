"""Natural frequencies of an instantaneous structure by a transfer-matrix frequency search.

Each segment gets the *exact* dynamic field matrix of a uniform Euler-Bernoulli beam-column with
distributed mass rho*A (free harmonic vibration at circular frequency w)::

    u' = N/EA,  w' = theta,  theta' = M/EI,  M' = -V + P theta,  V' = -rho A w^2 w,  N' = -rho A w^2 u

i.e. ``expm(A(w) L)``, evaluated in dimensionless variables. Point masses and rotary inertias act
as negative stiffness ``-m w^2``, ``-J w^2`` at their nodes. The frequencies are then located by
the Wittrick-Williams algorithm: the number of natural frequencies below w equals the number of
negative eigenvalues of the dynamic stiffness (counted in the Riccati elimination and the joint
system) plus those of the segments with clamped ends (J0). Segments are subdivided so that J0 = 0
up to the highest frequency sought. Bisection on that count never misses or duplicates a mode,
and the answer is exact for the distributed-mass model, independent of the segment count.

Rotary inertia of the strip and shear are neglected (Euler-Bernoulli, as in Shin and the FE
thesis); the rigid-body motion of the mechanism is frozen (no rotating-frame terms).

Owns: natural frequencies of an instantaneous structure. Boundaries: no time stepping.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np
from scipy.linalg import expm

from .errors import InputError, require_finite, require_positive
from .matrices import M, N, TH, U, V, W
from .mechanism import FourBarMechanism, Link
from .structure import LoadCase, Member, Structure, factorize

_STATE = (U, W, TH, M, V, N)


def dynamic_field_matrix(length, EA, EI, mass_per_length, omega, axial_force=0.0):
    """Exact free-vibration field matrix ``(..., 7, 7)`` of a uniform segment at circular
    frequency ``omega`` [rad/s] (no load column)."""
    L = np.asarray(length, dtype=float)
    EA, EI = np.asarray(EA, dtype=float), np.asarray(EI, dtype=float)
    mu = np.asarray(mass_per_length, dtype=float)
    w2 = np.asarray(omega, dtype=float) ** 2
    P = np.asarray(axial_force, dtype=float)
    shape = np.broadcast_shapes(L.shape, EA.shape, EI.shape, mu.shape, w2.shape, P.shape)
    # Dimensionless state: u, w, L*theta, L^2 M/EI, L^3 V/EI, L N/EA (order u, w, th, M, V, N).
    A = np.zeros(shape + (6, 6))
    A[..., 0, 5] = 1.0
    A[..., 1, 2] = 1.0
    A[..., 2, 3] = 1.0
    A[..., 3, 4] = -1.0
    A[..., 3, 2] = P * L**2 / EI
    A[..., 4, 1] = -mu * w2 * L**4 / EI
    A[..., 5, 0] = -mu * w2 * L**2 / EA
    E = expm(A)
    scale = np.stack(np.broadcast_arrays(np.ones(shape), np.ones(shape), L, L**2 / EI, L**3 / EI, L / EA), -1)
    T6 = E / scale[..., :, None] * scale[..., None, :]
    T = np.zeros(shape + (7, 7))
    idx = np.array(_STATE)
    T[..., idx[:, None], idx[None, :]] = T6
    T[..., 6, 6] = 1.0
    return T


def _refined(member: Member, point_masses: np.ndarray, point_inertia: np.ndarray, omega_max: float):
    """Subdivide every segment so that no segment has a clamped-clamped mode below omega_max
    (bending: beta L < 4.0 < 4.730; axial: w L / c < 3.0 < pi). Returns the refined member and
    the node masses/inertias on the refined mesh."""
    subs = []
    for L, sec, mat in zip(member.segment_lengths, member.sections, member.materials):
        mu = mat.density_kg_m3 * sec.area_m2
        if mu == 0:
            subs.append(1)
            continue
        beta = (mu * omega_max**2 / (mat.E_Pa * sec.inertia_m4)) ** 0.25
        c = math.sqrt(mat.E_Pa / mat.density_kg_m3)
        subs.append(max(1, math.ceil(beta * L / 4.0), math.ceil(omega_max * L / (3.0 * c))))
    seg_L, secs, mats = [], [], []
    m_new, J_new = [point_masses[0]], [point_inertia[0]]
    for j, k in enumerate(subs):
        seg_L += [member.segment_lengths[j] / k] * k
        secs += [member.sections[j]] * k
        mats += [member.materials[j]] * k
        m_new += [0.0] * (k - 1) + [point_masses[j + 1]]
        J_new += [0.0] * (k - 1) + [point_inertia[j + 1]]
    return replace(member, segment_lengths=tuple(seg_L), sections=tuple(secs), materials=tuple(mats)), \
        np.array(m_new), np.array(J_new)


@dataclass(frozen=True)
class FrequencyModel:
    """A structure with its distributed and point masses, ready for counting."""

    structure: Structure
    joint_positions: Mapping[str, np.ndarray]
    point_mass: Mapping[str, np.ndarray]      # {member: (n+1,)} kg at the (refined) nodes
    point_inertia: Mapping[str, np.ndarray]   # {member: (n+1,)} kg m^2
    axial_force: Mapping[str, np.ndarray] | None = None

    def count(self, omega) -> np.ndarray:
        """Number of natural frequencies below ``omega`` [rad/s] (array, batched)."""
        omega = np.asarray(omega, dtype=float)
        batch = omega.shape
        fields, stiff = {}, {}
        for m in self.structure.members:
            mu = np.array([mat.density_kg_m3 * sec.area_m2 for sec, mat in zip(m.sections, m.materials)])
            P = 0.0 if self.axial_force is None else self.axial_force.get(m.name, 0.0)
            fields[m.name] = dynamic_field_matrix(np.asarray(m.segment_lengths), m.EA, m.EI, mu, omega[..., None], P)
            K = np.zeros(batch + (m.n_segments + 1, 3, 3))
            w2 = omega[..., None] ** 2
            K[..., 0, 0] = -self.point_mass[m.name] * w2
            K[..., 1, 1] = -self.point_mass[m.name] * w2
            K[..., 2, 2] = -self.point_inertia[m.name] * w2
            stiff[m.name] = K
        case = LoadCase({k: np.broadcast_to(v, batch + (2,)) for k, v in self.joint_positions.items()},
                        node_stiffness=stiff, frame="local")
        f = factorize(self.structure, case, check_buckling=False, check_singular=False, field_matrices=fields,
                      count_inertia=True)
        return f.negative_eigenvalues


def frequency_model(structure: Structure, joint_positions: Mapping[str, np.ndarray], omega_max: float,
                    point_mass: Mapping[str, np.ndarray] | None = None,
                    point_inertia: Mapping[str, np.ndarray] | None = None,
                    axial_force: Mapping[str, np.ndarray] | None = None) -> FrequencyModel:
    """Refine a structure for a frequency search up to ``omega_max`` [rad/s]. Point masses are
    given per member node of the unrefined mesh (default none)."""
    members, pm, pj = [], {}, {}
    for m in structure.members:
        n1 = m.n_segments + 1
        mass = np.zeros(n1) if point_mass is None or m.name not in point_mass else np.asarray(point_mass[m.name], float)
        iner = np.zeros(n1) if point_inertia is None or m.name not in point_inertia else np.asarray(point_inertia[m.name], float)
        if axial_force is not None and m.name in axial_force:
            mm, ms, js = m, mass, iner   # keep the mesh that the axial forces belong to
        else:
            mm, ms, js = _refined(m, mass, iner, omega_max)
        members.append(mm)
        pm[m.name], pj[m.name] = ms, js
    return FrequencyModel(Structure(structure.joints, tuple(members)), dict(joint_positions), pm, pj, axial_force)


def natural_frequencies(model: FrequencyModel, n_modes: int, omega_max: float, rtol: float = 1e-12) -> np.ndarray:
    """The first ``n_modes`` natural frequencies [Hz] below ``omega_max`` [rad/s], by bisection on
    the Wittrick-Williams count. Fewer are returned if fewer exist below ``omega_max``."""
    if int(n_modes) != n_modes or n_modes < 1:
        raise InputError(f"n_modes must be a positive integer, got {n_modes!r}")
    require_positive("omega_max", omega_max)
    total = int(model.count(np.array(omega_max)))
    k = min(int(n_modes), total)
    if k == 0:
        return np.zeros(0)
    lo = np.zeros(k)
    hi = np.full(k, float(omega_max))
    target = np.arange(1, k + 1)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        below = model.count(mid)
        hi = np.where(below >= target, mid, hi)
        lo = np.where(below >= target, lo, mid)
        if np.all(hi - lo <= rtol * hi):
            break
    return 0.5 * (lo + hi) / (2 * np.pi)


def fourbar_frequencies(mech: FourBarMechanism, crank_angle, n_modes: int = 4, f_max_Hz: float = 2000.0,
                        rtol: float = 1e-10, axial_force: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
    """First natural frequencies [Hz] of the four-bar's instantaneous structure (crank clamped at
    its pivot) at each crank angle [rad]; shape ``(len(crank_angle), n_modes)`` (NaN where fewer
    modes exist below ``f_max_Hz``). ``axial_force`` optionally adds beam-column pre-load
    (``{link: (n,)}`` on the link's own mesh, one crank angle only)."""
    angles = np.atleast_1d(np.asarray(require_finite("crank_angle", crank_angle), dtype=float))
    motion = mech.motion(angles)
    out = np.full((len(angles), n_modes), np.nan)
    masses = {}
    for link in mech.links():
        m, J = link.node_masses()
        # The distributed part of node_masses is replaced by the exact distributed mass.
        masses[link.name] = (m - link.distributed_node_masses(), J)
    wmax = 2 * np.pi * f_max_Hz
    for i in range(len(angles)):
        joints = {k: v[i] for k, v in mech.joint_positions(motion).items()}
        model = frequency_model(mech.structure(), joints, wmax, {k: v[0] for k, v in masses.items()},
                                {k: v[1] for k, v in masses.items()}, axial_force)
        f = natural_frequencies(model, n_modes, wmax, rtol)
        out[i, :len(f)] = f
    return out
