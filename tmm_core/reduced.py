"""Reduced transfer-matrix model: a few link modes plus a static correction (the basis).

The full time domain (:class:`tmm_core.TimeDomain`, its model a
:class:`tmm_core.discretization.Discretization`) solves, at every step, the instantaneous
structure with all its nodes. In continuous time it is the constrained system, in each link's
local frame (node vector ``q`` of ``(u, w, theta)`` per node, see :mod:`tmm_core.matrices`)::

    M q'' + (D + C_K + G_c) q' + (K + K_c) q + sum_s P_s G_s d_s - S_u F = f(theta, theta', theta'')

with ``q`` in the admissible subspace S(theta) of the joints (it turns with the crank), M the
lumped masses and rotary inertias, D = M a_M and C_K = beta K the link's Rayleigh damping,
``G_c``/``K_c`` the rotating-frame terms (Coriolis 2 m w, centrifugal -m w^2, angular
acceleration m alpha; :mod:`tmm_core.ked`), ``P_s`` the segment axial forces with ``G_s`` the
consistent geometric-stiffness matrices and ``F`` the shortening force of second-order beam
theory (:mod:`tmm_core.second_order`), and ``f`` the rigid-body D'Alembert loads and gravity.

The reduced model writes ``q = T(theta) eta`` with a basis that lies in S(theta) at every crank
angle and varies smoothly with it::

    T(theta) = F(theta) W,    W = [M^(1/2) U, L]

``F(theta)`` is the static flexibility of the instantaneous structure (the TMM's own
factorization, unit loads; linear theory, P = 0), so every column is admissible. ``M^(1/2) U``
are the inertia loads of the link modes: the instantaneous modes of the TMM (``F M phi = phi /
w^2``, i.e. the TMM's static solve at the modes' inertia loads) at crank positions over a
revolution, compressed to ``modes`` shapes (the dominant M-weighted subspace); at a position
where they are the modes, ``F M phi = phi / w^2``: the columns are the modes. ``L`` spans the
rigid-body loads over the revolution (mass-weighted uniform and linear shapes per link, rotary
inertia, applied moments): ``F L`` is the static correction, the residual flexibility of the
inertia loads, so the quasi-static response is represented exactly. Stiffness on the basis is
``T^T K T = W^T F W`` (no stiffness matrix is formed); the geometric stiffness is linear in the
axial force, ``sum_s P_s T^T E_s^T G_s E_s T``. Because ``T`` turns with the crank, ``q' = T eta'
+ T' theta' eta`` and ``q'' = T eta'' + 2 T' theta' eta' + (T'' theta'^2 + T' theta'') eta``
(periodic cubic splines over the crank grid give T' and T'').

Units: SI; ``eta`` has units of sqrt(kg) m (the basis is M-orthonormal at the first grid
position). Angles in radians, crank angle from the ground line, CCW positive.
The propagator and the periodic solve are in :mod:`tmm_core.reduced_periodic`.

Owns: the reduced model's basis over a revolution. Boundaries: no time integration
(tmm_core.reduced_periodic).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from .discretization import Discretization, HoldsModel, as_model
from .errors import InputError
from .ked import rigid_body_loads
from .mechanism import torque_from_terms
from .post import gauge_strains
from .second_order import geometric_matrices
from .structure import LoadCase, factorize, solve_factored

#: Default number of link modes (chosen from the accuracy study, docs/validation.md "Reduced model accuracy").
DEFAULT_MODES = 4
#: The axial coordinates of :class:`ReducedOptions` (``axial``): per segment, or per link.
AXIAL_COORDINATES = ("segment", "link")


@dataclass(frozen=True)
class ReducedOptions:
    """Settings of the reduced model.

    modes : number of mode shapes kept (the dominant subspace of the instantaneous modes of the
        whole linkage over a revolution), beside the static correction.
    positions : crank positions per revolution of the basis grid (the TMM factorizes each).
    mode_positions : positions per revolution whose modes are collected (a subset of the grid).
    steps : propagator steps per revolution (3-stage Radau IIA, order 5), chosen for accuracy: on
        the FE rig 360 steps agree with 720 within 0.02 % on every peak at 241 and 373 rpm (180
        steps: 0.04 % and 0.2 %). Modes far above the crank harmonics (beyond about 8 on the FE
        rig, 1.8 kHz) are damped by the L-stable propagator rather than resolved.
    axial : the second-order axial force (``axial_force = 'dynamic'``). ``"segment"``: one static
        correction per segment (a pair of axial loads on its nodes), so that every segment's
        elongation follows its own shortening from bending, and each segment's own axial force.
        ``"link"`` (prototype of issue 37, numpy backend only): one per flexible link (a pair of
        axial loads on its end nodes), and the link's axial force uniform along it, from the
        link's compatibility: its chord elongation plus the sum of its segments' shortenings over
        its axial compliance ``sum L/EA`` (r = 23 -> 9 on the FE rig).
    """

    modes: int = DEFAULT_MODES
    positions: int = 90
    mode_positions: int = 18
    steps: int = 360
    axial: str = "segment"

    def __post_init__(self):
        if self.axial not in AXIAL_COORDINATES:
            raise InputError(f"reduced model: axial must be one of {', '.join(AXIAL_COORDINATES)}, got {self.axial!r}")
        for name in ("modes", "positions", "mode_positions", "steps"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise InputError(f"reduced model: {name} must be a positive integer, got {v!r}")
        if self.positions % self.mode_positions:
            raise InputError(f"reduced model: mode_positions ({self.mode_positions}) must divide positions "
                             f"({self.positions})")
        if self.positions < 8:
            raise InputError(f"reduced model: positions must be at least 8, got {self.positions}")


@dataclass(frozen=True)
class ReducedBasis:
    """The basis of the reduced model over one revolution (geometry only: valid at every speed).

    angles : (J,) grid crank angles [rad], uniform over a revolution from the start angle.
    T : (J, n_dof, r) node displacements per unit coordinate (stacked local node vector).
    K : (J, r, r) elastic stiffness on the basis, ``W^T F W`` [N/m per coordinate^2].
    torque : (J, n_dof) drive torque per unit local node load [N m per N or N m].
    frequencies_Hz : (mode_positions, modes) instantaneous natural frequencies at the positions
        whose modes were collected (linear theory, no rotating-frame terms).
    strain_per_coordinate : (J, n_gauges, 2, r) gauge bending and axial strain per unit
        coordinate (linear theory; the propagator adds the second-order shortening).
    n_modes, n_static : columns from the modes and from the static correction.
    axial : the axial coordinates, per segment or per link (:class:`ReducedOptions`).
    """

    angles: np.ndarray
    T: np.ndarray
    K: np.ndarray
    torque: np.ndarray
    frequencies_Hz: np.ndarray
    strain_per_coordinate: np.ndarray
    n_modes: int
    n_static: int
    axial: str = "segment"

    @property
    def size(self) -> int:
        return self.T.shape[-1]

    def weights(self, x):
        """The periodic cubic splines in the crank angle over the basis grid as weights:
        ``(B, B', B'')`` (len(x), J) with ``spline(x) = B @ data`` (and its angle derivatives) for
        data over the grid, e.g. ``T``, ``K``, ``torque``, ``strain_per_coordinate`` (a spline is linear in
        its data). One
        matrix product per quantity: 3x faster than evaluating the spline of ``T`` itself (its
        (n, r) values per angle)."""
        J = len(self.angles)
        th = np.concatenate([self.angles, [self.angles[0] + 2 * np.pi]])
        unit = CubicSpline(th, np.concatenate([np.eye(J), np.eye(J)[:1]]), axis=0, bc_type="periodic")
        return unit(x), unit(x, 1), unit(x, 2)


def unit_responses(model: Discretization, angles):
    """Static responses of the instantaneous structures of ``model`` at the crank ``angles`` [rad]
    (linear theory, P = 0, no inertia) to unit local node loads: ``(Z, torque, gauges)`` with ``Z`` (B, n, n) the
    flexibility (column j: displacements under a unit load on DOF j), ``torque`` (B, n) the drive
    torque per unit load (reaction part) and ``gauges`` (B, n_g, 2, n) bending/axial strain per
    unit load. Uses the TMM's own factorization (:func:`tmm_core.structure.factorize`)."""
    mech = model.mech
    angles = np.atleast_1d(np.asarray(angles, dtype=float))
    motion = mech.motion(angles, 0.0, 0.0)
    joints = {k: v[:, None, :] for k, v in mech.joint_positions(motion).items()}
    factor = factorize(model.structure, LoadCase(joints, {}, {}, {}, frame="local"), None, check_buckling=False)
    n = model.n_dof
    unit = {}
    for link in model.links:
        n1 = link.n_nodes
        U = np.zeros((n + 1, n1, 3))
        off = model.offsets[link.name]
        U[off:off + 3 * n1].reshape(n1, 3, n1, 3)[np.arange(n1), :, np.arange(n1), :] = np.eye(3)
        unit[link.name] = U[None]
    sol = solve_factored(factor, unit, frame="local")
    B = len(angles)
    z = np.concatenate([sol.members[l.name].state[..., 0, :3].reshape(B, n + 1, -1) for l in model.links], axis=-1)
    joint, arm, _ = mech.drive_torque_terms(motion)
    torque = torque_from_terms(sol.reactions, joint, arm, np.zeros(B))
    gs = [np.stack(gauge_strains(sol.members[g.link], g, axial_sampling=model.gauge_axial_sampling(k)), -1)
          for k, g in enumerate(model.gauges)]                                        # (B, n+1, 2) each
    gauges = np.stack([g[:, :-1] - g[:, -1:] for g in gs], 1) if gs else np.zeros((B, 0, n, 2))
    return (np.swapaxes(z[:, :-1] - z[:, -1:], 1, 2), torque[:, :-1] - torque[:, -1:],
            np.swapaxes(gauges, -1, -2))


def reduced_frequencies(structure, joint_positions, node_mass, n_modes: int, axial_force=None) -> np.ndarray:
    """Natural frequencies [Hz] of the reduced model of a structure at rest: its lowest
    ``n_modes`` modes in linear theory (the TMM's flexibility, :func:`instantaneous_modes`) with
    the geometric stiffness linear in the axial force, ``K_r + sum_s P_s T^T E_s^T G_s E_s T``.

    ``joint_positions``: ``{joint: (2,)}`` [m]; ``node_mass``: ``{member: (n+1,)}`` lumped masses
    [kg] (translation; no rotary inertia); ``axial_force``: ``{member: (n,)}`` segment forces [N],
    tension positive (default none). The check of the reduced model against the TMM's own
    frequency search (:mod:`tmm_core.frequencies`) at a constant axial load."""
    members = structure.members
    offsets = np.cumsum([0] + [3 * (mb.n_segments + 1) for mb in members])
    n = int(offsets[-1])
    joints = {k: np.asarray(v, dtype=float)[None, :] for k, v in joint_positions.items()}
    factor = factorize(structure, LoadCase(joints, {}, {}, {}, frame="local"), None, check_buckling=False)
    unit = {}
    for mb, off in zip(members, offsets):
        n1 = mb.n_segments + 1
        U = np.zeros((n, n1, 3))
        U[off:off + 3 * n1].reshape(n1, 3, n1, 3)[np.arange(n1), :, np.arange(n1), :] = np.eye(3)
        unit[mb.name] = U
    sol = solve_factored(factor, unit, frame="local")
    Z = np.concatenate([sol.members[mb.name].state[..., 0, :3].reshape(n, -1) for mb in members], axis=-1).T
    m = np.concatenate([np.repeat(np.asarray(node_mass[mb.name], float), 3) * np.tile([1.0, 1.0, 0.0], mb.n_segments + 1)
                        for mb in members])
    _, mphi = instantaneous_modes(Z, m, n_modes)
    W = np.sqrt(m)[:, None] * mphi
    T = Z @ W
    K = W.T @ Z @ W
    if axial_force is not None:
        for mb, off in zip(members, offsets):
            P = np.broadcast_to(np.asarray(axial_force.get(mb.name, 0.0), float), (mb.n_segments,))
            G = geometric_matrices(np.asarray(mb.segment_lengths))
            for j in range(mb.n_segments):
                idx = off + 3 * j + np.array([1, 2, 4, 5])
                K = K + P[j] * T[idx].T @ G[j] @ T[idx]
    Mr = T.T @ (m[:, None] * T)
    lam = np.linalg.eigvals(np.linalg.solve(Mr, K))
    return np.sort(np.sqrt(np.abs(lam.real))) / (2 * np.pi)


def instantaneous_modes(Z: np.ndarray, m: np.ndarray, count: int):
    """Lowest ``count`` modes of ``K phi = w^2 M phi`` from the flexibility ``Z`` = K^+ on the
    admissible subspace and the lumped node masses ``m`` (n,) (zeros allowed): ``(w [rad/s],
    M^(1/2) phi (n, count))``, M-orthonormal. Eigenvalues of the symmetric M^(1/2) Z M^(1/2)."""
    h = np.sqrt(np.asarray(m, dtype=float))
    A = h[:, None] * (0.5 * (Z + Z.T)) * h[None, :]
    lam, psi = np.linalg.eigh(A)
    lam, psi = lam[::-1][:count], psi[:, ::-1][:, :count]
    if np.any(lam <= 0):
        raise InputError("reduced model: fewer massive modes than requested (lower solver.tmm.modes)")
    return 1.0 / np.sqrt(lam), psi


def _load_shapes(model: Discretization, angles, tol=1e-10):
    """Orthonormal basis (n, k) of the rigid-body loads over the revolution: samples at unit
    crank speed, unit crank acceleration and at rest (gravity, applied loads)."""
    mech, samples = model.mech, []
    for speed, accel in ((1.0, 0.0), (0.0, 1.0), (0.0, 0.0)):
        motion = mech.motion(angles, speed, accel)
        samples.append(model.stack(rigid_body_loads(mech, motion, model.gravity if speed == accel == 0 else None,
                                                 frame="local")))
    X = np.concatenate(samples, axis=0).T
    U, s, _ = np.linalg.svd(X, full_matrices=False)
    keep = s > tol * s[0] if len(s) and s[0] > 0 else np.zeros(len(s), bool)
    return U[:, keep]


def build_basis(source: Discretization | HoldsModel, start_angle: float = 0.0,
                options: ReducedOptions = ReducedOptions()) -> ReducedBasis:
    """The reduced basis of the model ``source`` (a :class:`tmm_core.discretization.Discretization`
    or the one a :class:`tmm_core.TimeDomain` holds: its mass model, gauges and node layout) over
    one revolution from ``start_angle`` [rad]."""
    model = as_model(source)
    J = options.positions
    angles = start_angle + 2 * np.pi * np.arange(J) / J
    Z, torque, gmaps = unit_responses(model, angles)
    m = model.m_vec
    h = np.sqrt(m)
    # Modes at every (positions / mode_positions)-th grid point, compressed to the dominant subspace.
    every = J // options.mode_positions
    freqs, shapes = [], []
    for j in range(0, J, every):
        w, mphi = instantaneous_modes(Z[j], m, options.modes)
        freqs.append(w / (2 * np.pi))
        shapes.append(mphi)
    U, _, _ = np.linalg.svd(np.concatenate(shapes, axis=1), full_matrices=False)
    W_modes = h[:, None] * U[:, :options.modes]                  # inertia loads of the mode shapes
    W_static = _load_shapes(model, angles)
    if model.axial_force == "dynamic":
        # Second order: the shortening of each segment acts as a pair of axial loads on its nodes.
        # Their static responses let every segment's elongation follow its own shortening, so the
        # axial forces come out in equilibrium (a smooth axial field alone would lock them).
        seg = model.segments
        pairs = np.zeros((model.n_dof, len(seg.length)))
        pairs[seg.start, np.arange(len(seg.length))] = 1.0
        pairs[seg.end, np.arange(len(seg.length))] = -1.0
        if options.axial == "link":
            # One pair per link, on its end nodes: the sum of its segments' pairs.
            pairs = pairs @ segment_links(model).T
        W_static = np.concatenate([W_static, pairs * float(np.linalg.norm(W_static[:, 0]))], axis=1)
    W = np.concatenate([W_modes, W_static], axis=1)
    T = Z @ W                                                     # (J, n, r)
    # One constant transformation makes the basis M-orthonormal at the first grid point (dropping
    # directions that are dependent there); being constant, it keeps T smooth in the angle.
    G0 = T[0].T @ (m[:, None] * T[0])
    lam, V = np.linalg.eigh(0.5 * (G0 + G0.T))
    keep = lam > 1e-12 * lam.max()
    Q = V[:, keep] / np.sqrt(lam[keep])
    T, W = T @ Q, W @ Q
    K = W.T @ T                                                   # W^T Z W (T = Z W)
    K = 0.5 * (K + np.swapaxes(K, 1, 2))
    # Gauge strains per unit coordinate at every grid position: those of the static solutions the
    # columns are (T = Z W: the responses to the loads W). Exact at the grid positions, for any
    # gauge: a map from the node displacements fitted at one position (as before) was wrong for a
    # gauge at a joint, whose strain per unit displacement changes with the crank angle (the Watt
    # six-bar's rocker_E: 14 % over a revolution, its peaks 8-57 % off the full model's).
    strain_per_coordinate = gmaps @ W[None]                        # (J, n_g, 2, r)
    n_modes = int(min(options.modes, keep.sum()))
    return ReducedBasis(angles, T, K, torque, np.array(freqs), strain_per_coordinate, n_modes,
                        int(keep.sum()) - n_modes, options.axial)


def segment_links(model: Discretization) -> np.ndarray:
    """``(n_links, n_seg)``: 1 where the segment (stacked, :attr:`Discretization.segments`) belongs
    to the link (:attr:`Discretization.links`, in order)."""
    counts = [link.total_segments for link in model.links]
    return np.repeat(np.eye(len(counts)), counts, axis=1)
