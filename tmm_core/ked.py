"""Kineto-elastodynamics (KED) of a flexible four-bar by the transfer-matrix method.

The rigid-body motion is prescribed by the crank motion (closed-form kinematics); the elastic
deformation of the links is superposed on it (Shin ch. 6, Wang, the FE crank-rocker thesis).

Mass model (per link, :meth:`tmm_core.mechanism.Link.node_masses`): the distributed mass lumped
to the nodes, plus point masses (bearings, end blocks with rotary inertia).

Quasi-static analysis (Shin's kineto-elastostatics): at every crank position the instantaneous
structure carries the rigid-body D'Alembert loads ``-m a_P`` and ``-J alpha``; all positions are
solved in one batched call.

Time-domain analysis: the elastic motion adds inertia ``m (q_ddot + coupling)`` at every lumped
mass. With an implicit integrator (:mod:`tmm_core.integrators`) each step is again a static
solution of the instantaneous structure, with a "dynamic stiffness" ``m c_a`` at each mass and
history loads (Shin Eq. 3.47). In the link's rotating frame the elastic acceleration of a mass
is (local components, link angular speed w and acceleration alpha)::

    a_u = u_ddot - 2 w w_dot - w^2 u - alpha w
    a_w = w_ddot + 2 w u_dot - w^2 w + alpha u

Shin and Wang keep only ``u_ddot, w_ddot``; the Coriolis (2 w), centrifugal (w^2, the -theta_dot^2 [MD]
term of the FE thesis, notes seed002 §2.5) and angular-acceleration (alpha) terms are switched on
with :class:`Coupling`. Centrifugal *stiffening* of bending comes from the axial forces of the
rigid-body inertia loads, i.e. from the beam-column coupling (``beam_column=True``).

Damping (per link, Rayleigh) and the standard-linear-solid material act through effective moduli
in the field matrices plus history loads computed from the exact segment stiffness
(:func:`tmm_core.riccati.segment_stiffness`).

Speed: a step is linear in its loads, so for every distinct crank position the solver stores
the dense maps from nodal loads to nodal displacements, drive torque and gauge strains
(computed once, batched over positions, by pushing unit loads through the Riccati
factorization). A constant-speed run re-uses the maps of one revolution; other crank histories
are processed in chunks.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

from .errors import (ConvergenceError, DynamicStabilityError, InputError, SingularStructureError,
                     require_finite, require_positive)
from .integrators import get_integrator
from .kinematics import FourBarMotion
from .matrices import field_matrix
from .mechanism import FourBarMechanism, StaticMechanism, torque_from_terms
from .post import Gauge, gauge_strains
from .riccati import segment_stiffness
from . import kernels
from .second_order import Segments, pseudo_loads, shape_products
from .statics import solve_static
from .structure import LoadCase, factorize, solve_factored

GRAVITY = 9.80665
AXIAL_FORCE_MODELS = ("dynamic", "quasi_static", "none")
ANDERSON_DEPTH = 4          # iterates mixed by the second-order step iteration
AXIAL_RESTARTS = 3          # refactorizations of a second-order step that does not converge
DYNAMIC_TERMS = ("shortening", "axial_force")


@dataclass(frozen=True)
class Coupling:
    """Rotating-frame terms that Shin and Wang dropped (FE crank-rocker thesis, notes §2.5)."""

    coriolis: bool = False
    centrifugal: bool = False
    angular_acceleration: bool = False

    @classmethod
    def all(cls) -> "Coupling":
        return cls(True, True, True)

    @property
    def any(self) -> bool:
        return self.coriolis or self.centrifugal or self.angular_acceleration


@dataclass(frozen=True)
class CrankMotion:
    """Prescribed crank motion at each time step: time [s], angle [rad], speed [rad/s],
    acceleration [rad/s^2] (angle from the ground line, CCW positive). Times are
    ``t0 + k*dt`` for an integer step count k."""

    t: np.ndarray
    angle: np.ndarray
    speed: np.ndarray
    acceleration: np.ndarray

    def __post_init__(self):
        n = len(self.t)
        for name in ("t", "angle", "speed", "acceleration"):
            arr = require_finite(f"crank motion {name}", getattr(self, name))
            if arr.shape != (n,):
                raise InputError(f"crank motion {name} must have shape ({n},), got {arr.shape}")
        if n < 2:
            raise InputError(f"crank motion needs at least 2 steps, got {n}")
        dt = np.diff(self.t)
        if np.any(dt <= 0):
            raise InputError("crank motion times must increase strictly")
        if np.max(np.abs(dt - dt[0])) > 1e-9 * dt[0]:
            raise InputError("crank motion times must be uniform (t0 + k dt)")

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @classmethod
    def constant_speed(cls, speed_rad_s: float, *, step_s: float | None = None, step_deg: float | None = None,
                       revolutions: float = 1.0, start_angle: float = 0.0, t0: float = 0.0) -> "CrankMotion":
        """Constant crank speed. Give the step in seconds or as a crank-angle increment in degrees."""
        w = float(require_finite("crank speed_rad_s", speed_rad_s))
        if w == 0.0:
            raise InputError("crank speed_rad_s must be non-zero for a time-domain run")
        if (step_s is None) == (step_deg is None):
            raise InputError("give exactly one of step_s and step_deg")
        dt = float(require_positive("step_s", step_s)) if step_s is not None else \
            math.radians(float(require_positive("step_deg", step_deg))) / abs(w)
        require_positive("revolutions", revolutions)
        n = int(round(revolutions * 2 * math.pi / (abs(w) * dt))) + 1
        k = np.arange(n)
        t = t0 + k * dt
        return cls(t, start_angle + w * (t - t0), np.full(n, w), np.zeros(n))

    def steps_per_revolution(self) -> int | None:
        """Steps per revolution if the speed is constant and a revolution is a whole number of steps."""
        if np.any(self.acceleration != 0) or np.any(self.speed != self.speed[0]) or self.speed[0] == 0:
            return None
        n = 2 * math.pi / (abs(self.speed[0]) * self.dt)
        return int(round(n)) if abs(n - round(n)) < 1e-6 and round(n) >= 2 else None


@dataclass(frozen=True)
class QuasiStaticResult:
    """Quasi-static (kineto-elastostatic) response at a set of crank positions."""

    motion: FourBarMotion
    solution: object                 # StaticSolution over the positions
    drive_torque: np.ndarray         # (n,) moment applied to the crank by the drive [N m], CCW +
    gauges: Mapping[str, tuple]      # {gauge: (bending, axial)} strains [-], (n,) each


@dataclass(frozen=True)
class KEDResult:
    """Time history of a time-domain run. Every array has one entry per step."""

    t: np.ndarray
    crank_angle: np.ndarray
    crank_speed: np.ndarray
    crank_acceleration: np.ndarray
    drive_torque: np.ndarray                  # [N m], CCW +, moment applied to the crank at its pivot
    gauges: Mapping[str, tuple]               # {gauge: (bending, axial)} strains [-]
    displacements: Mapping[str, np.ndarray]   # {link: (steps, n+1, 3)} local (u, w, theta) [m, m, rad]
    steady: bool                              # steady-state criterion met
    cycle_change: float                       # last revolution-to-revolution change (relative)
    revolutions: float
    integrator: str
    info: dict = field(default_factory=dict)


def _node_mass_arrays(mech: FourBarMechanism):
    out = {}
    for link in mech.elastic_links():
        m, J = link.node_masses()
        out[link.name] = (m, J)
    return out


def rigid_body_loads(mech: FourBarMechanism, motion: FourBarMotion, gravity=None, frame: str = "global"):
    """D'Alembert loads ``(-m a_P, -J alpha)`` (+ gravity ``m g``) at every node of every elastic
    link, ``{link: (..., n+1, 3)}`` in the global frame or each link's local frame (a rigid crank's
    loads enter the drive torque instead, :meth:`FourBarMechanism.drive_torque_terms`)."""
    g = np.zeros(2) if gravity is None else np.asarray(gravity, dtype=float)
    out = {}
    applied = mech.external_loads(motion)
    for link in mech.elastic_links():
        m, J = link.node_masses()
        lm = motion.link(link.name)
        _, _, acc = lm.point(link.stations)
        F = np.zeros(acc.shape[:-1] + (3,))
        F[..., :2] = m[:, None] * (g - acc)
        F[..., 2] = -J * lm.alpha[..., None]
        if link.name in applied:
            F = F + applied[link.name]
        if frame == "local":
            c, s = np.cos(lm.angle)[..., None], np.sin(lm.angle)[..., None]
            F[..., 0], F[..., 1] = c * F[..., 0] + s * F[..., 1], -s * F[..., 0] + c * F[..., 1]
        out[link.name] = F
    return out


def _coupling_stiffness(mech, motion, coupling: Coupling, c_a=0.0, c_v=0.0, mass_damping=None):
    """Local node stiffness ``{link: (..., n+1, 3, 3)}`` of inertia and rotating-frame terms."""
    out = {}
    for link in mech.elastic_links():
        m, J = link.node_masses()
        lm = motion.link(link.name)
        w, al = lm.omega[..., None], lm.alpha[..., None]
        aM = link.damping.mass_per_s if mass_damping is None else mass_damping
        K = np.zeros(np.shape(lm.omega) + (link.n_nodes, 3, 3))
        diag = m * (c_a + aM * c_v - (w**2 if coupling.centrifugal else 0.0))
        cross = m * ((2.0 * w * c_v if coupling.coriolis else 0.0) + (al if coupling.angular_acceleration else 0.0))
        K[..., 0, 0] = diag
        K[..., 1, 1] = diag
        K[..., 0, 1] = -cross
        K[..., 1, 0] = cross
        K[..., 2, 2] = J * (c_a + aM * c_v)
        out[link.name] = K
    return out


def quasi_static(mech: FourBarMechanism, crank_angle, crank_speed, crank_acceleration=0.0, *, beam_column: bool = True,
                 coupling: Coupling = Coupling(), gravity=None, gauges: Sequence[Gauge] = (),
                 tol: float = 1e-10) -> QuasiStaticResult:
    """Kineto-elastostatic response at the crank positions ``crank_angle`` (array), vectorised.

    ``beam_column``: iterate on the segment axial forces (Shin). ``coupling``: the centrifugal
    and angular-acceleration terms act as stiffness to ground in the rotating frame (Coriolis has
    no quasi-static effect). A speed at which ``K - w^2 M`` is singular raises
    :class:`tmm_core.errors.SingularStructureError`.
    """
    motion = mech.motion(crank_angle, crank_speed, crank_acceleration)
    loads = rigid_body_loads(mech, motion, gravity)
    stiffness = _coupling_stiffness(mech, motion, Coupling(False, coupling.centrifugal, coupling.angular_acceleration),
                                    mass_damping=0.0) if coupling.any else {}
    # The node stiffness above is isotropic or skew in (u, w): the same in every frame.
    case = mech.load_case(motion, loads, None, stiffness)
    try:
        sol = solve_static(mech.structure(), case, beam_column=beam_column, tol=tol,
                           count_inertia=True if coupling.centrifugal else None)
    except SingularStructureError as exc:
        if not coupling.centrifugal:
            raise
        speed = float(np.max(np.abs(crank_speed)))
        raise SingularStructureError(
            f"crank speed {speed:.6g} rad/s ({speed / (2 * np.pi):.6g} Hz) is at or above a natural frequency of the "
            f"instantaneous structure: with the centrifugal term its stiffness K - w^2 M is no longer positive "
            f"definite ({exc})") from None
    torque = mech.drive_torque(sol.reactions, motion, gravity)
    out = {g.name: gauge_strains(sol.members[g.link], g) for g in gauges}
    return QuasiStaticResult(motion, sol, torque, out)


# The dense load-to-response maps cost O(n_dof^2) per configuration to build (once per revolution
# of a periodic run) and a mat-vec per step to apply; without them every step runs the Riccati load
# sweep, O(n_dof) but ~5 ms of Python per step. Measured (FE crank-rocker, one revolution at 1 deg,
# maps built in chunks vs sweeps): 0.92 / 1.53 s at 81 dof (8 segments per link), 1.42 / 2.42 s at
# 153 dof, 4.9 / 5.1 s at 297 dof (peak 509 MB; 13.2 s and 1.1 GB when built in one batch); each
# further revolution costs the maps almost nothing. So the maps are used up to 32 segments per
# link (and within max_map_bytes); beyond, the sweeps keep the cost linear in the segment count.
MAP_MAX_DOF = 320
MAP_CHUNK_BYTES = 64e6       # working memory of one chunk of the map solve


class TimeDomain:
    """Time-domain analysis of a four-bar under a prescribed crank motion.

    Parameters
    ----------
    mech : the mechanism (links carry their mass model, damping and viscoelastic law).
    integrator : 'newmark' (average acceleration) or 'houbolt' (Shin).
    coupling : rotating-frame terms, see :class:`Coupling`.
    beam_column : include the axial-force (beam-column) coupling of bending; False is linear
        theory (``axial_force='none'``).
    axial_force : how the axial force enters the bending equations when ``beam_column``:
        'dynamic' (default): second-order beam theory (:mod:`tmm_core.second_order`): the
        step's own axial force, including the axial shortening from bending, iterated within
        every step on the cached factorization; it agrees with geometrically exact beams near
        buckling (FE crank-rocker at 373 rpm, within a few per cent of exudyn where
        'quasi_static' is 8-24 % off). A transient excursion past the static Euler load is
        integrated as long as the dynamic system stays positive definite.
        'quasi_static': the quasi-static (rigid-body) axial force of each crank position, fixed
        in the field matrices; linear per step and cheaper; good far from buckling.
    axial_tolerance, axial_iterations : relative tolerance and iteration limit of the 'dynamic'
        step iteration.
    dynamic_terms : the second-order terms of the 'dynamic' step: 'shortening' (axial shortening
        from bending) and 'axial_force' (the step's own axial force in the bending equations).
    compiled : march configurations with cached maps in the compiled kernel
        (:mod:`tmm_core.kernels`); the numpy path is the reference and the fallback.
    gravity : gravity vector [m/s^2] in the mechanism plane, or None.
    gauges : gauges whose strains are recorded.
    max_map_bytes : memory budget for the stored load-to-response maps; above it each step
        runs the Riccati load sweep instead (same result, slower).
    """

    def __init__(self, mech: FourBarMechanism, *, integrator: str = "newmark", coupling: Coupling = Coupling(),
                 beam_column: bool = True, gravity=None, gauges: Sequence[Gauge] = (),
                 max_map_bytes: float = 400e6, axial_force: str = "dynamic", axial_tolerance: float = 1e-8,
                 axial_iterations: int = 60, dynamic_terms: tuple = DYNAMIC_TERMS, compiled: bool = True):
        self.mech = mech
        #: March cached configurations in the compiled kernel (tmm_core.kernels) when numba is
        #: installed; False keeps the numpy reference path.
        self.compiled = bool(compiled) and kernels.AVAILABLE
        if not set(dynamic_terms) <= set(DYNAMIC_TERMS):
            raise InputError(f"dynamic_terms must be a subset of {DYNAMIC_TERMS}, got {dynamic_terms!r}")
        #: The second-order terms the 'dynamic' step carries (both by default; one alone is for
        #: the experiment that separates them, scenarios/engines_agree_experiment.py).
        self.dynamic_terms = tuple(dynamic_terms)
        self.integrator = get_integrator(integrator)
        self.coupling = coupling
        self.beam_column = beam_column
        if axial_force == "iterated":
            raise InputError("axial_force 'iterated' was replaced by 'dynamic' (the step's own axial force together "
                             "with the axial shortening from bending; the axial force alone was measured to be worse)")
        if axial_force not in AXIAL_FORCE_MODELS:
            raise InputError(f"axial_force must be one of {AXIAL_FORCE_MODELS}, got {axial_force!r}")
        self.axial_force = "none" if not beam_column else axial_force
        self.axial_tolerance = float(require_positive("axial_tolerance", axial_tolerance))
        self.axial_iterations = int(axial_iterations)
        self.gravity = None if gravity is None else np.asarray(gravity, dtype=float)
        self.gauges = tuple(gauges)
        for g in self.gauges:
            if g.link not in {l.name for l in mech.elastic_links()}:
                raise InputError(f"gauge '{g.name}': unknown or rigid link '{g.link}' (a rigid link has no strain)")
        self.max_map_bytes = max_map_bytes
        self.structure = mech.structure()
        self.links = mech.elastic_links()
        # Node layout: every link's nodes, local (u, w, theta), concatenated.
        self.offsets, off = {}, 0
        for link in self.links:
            self.offsets[link.name] = off
            off += 3 * link.n_nodes
        self.n_dof = off
        masses = _node_mass_arrays(mech)
        self.m_vec = np.concatenate([np.repeat(masses[l.name][0], 3) * np.tile([1.0, 1.0, 0.0], l.n_nodes)
                                     + np.repeat(masses[l.name][1], 3) * np.tile([0.0, 0.0, 1.0], l.n_nodes)
                                     for l in self.links])
        self.aM_vec = np.concatenate([np.full(3 * l.n_nodes, l.damping.mass_per_s) for l in self.links])
        self._build_segment_operators()
        if self.axial_force == "dynamic" and any(l.viscoelastic is not None for l in self.links):
            raise InputError("axial_force 'dynamic' is not available with viscoelastic (standard-linear-solid) links; "
                             "use 'quasi_static'")
        starts, lengths, EA, beta = [], [], [], []
        for link in self.links:
            m = link.member("s", "e")
            starts.append(self.offsets[link.name] + 3 * np.arange(link.total_segments))
            lengths.append(np.asarray(m.segment_lengths))
            EA.append(m.EA)
            beta.append(np.full(link.total_segments, link.damping.stiffness_s))
        starts = np.concatenate(starts)
        #: Segment data of the node vector (second-order terms, axial forces).
        self.segments = Segments(starts, starts + 3, np.concatenate(lengths), np.concatenate(EA), np.concatenate(beta))
        seg_offset = np.cumsum([0] + [l.total_segments for l in self.links])
        self._gauge_segment = np.array([
            seg_offset[[l.name for l in self.links].index(g.link)] + int(np.clip(
                np.searchsorted(l.stations, g.position_m, side="right") - 1, 0, l.total_segments - 1))
            for g in self.gauges for l in self.links if l.name == g.link], dtype=int)

    # -- material history operators -------------------------------------------------------
    def _build_segment_operators(self):
        """Sparse operators on the node vector: gather of segment end displacements, the block
        diagonal of segment stiffnesses (material, at the material's E), and per-segment data."""
        import scipy.sparse as sp          # here: importing it costs 0.2 s that most users never need

        rows, blocks, visco_E1 = [], [], []
        for link in self.links:
            m = link.member("s", "e")
            K, _ = segment_stiffness(field_matrix(np.asarray(m.segment_lengths), m.EA, m.EI))
            off = self.offsets[link.name]
            for j in range(link.total_segments):
                rows.append(off + 3 * j + np.arange(6))
                blocks.append(K[j])
                sls = link.viscoelastic if link.flexible[j] else None
                visco_E1.append(0.0 if sls is None else sls.maxwell_modulus_Pa / link.material.E_Pa)
        self.n_seg = len(blocks)
        cols = np.concatenate(rows)
        self.gather = sp.csr_matrix((np.ones(len(cols)), (np.arange(len(cols)), cols)), shape=(len(cols), self.n_dof))
        self.seg_K = sp.block_diag(blocks, format="csr")
        self.seg_blocks = np.ascontiguousarray(np.array(blocks))     # (n_seg, 6, 6), for the compiled step
        # Maxwell modulus / reference modulus per segment entry (0 for elastic segments).
        self.seg_E1 = np.repeat(np.array(visco_E1), 6)
        # Material stiffness in local frames, assembled member by member (no joint coupling needed:
        # the history loads are computed per member and applied at its own nodes).
        self.K_local = (self.gather.T @ self.seg_K @ self.gather).tocsr()

    def _link_factor(self, c_v: float, dt: float):
        """Effective-modulus factor of every segment ``{link: (n,)}`` and, per link, the
        viscoelastic step coefficients ``(decay, g)`` of its span."""
        factors, visco = {}, {}
        for link in self.links:
            f = np.full(link.total_segments, 1.0 + link.damping.stiffness_s * c_v)
            if link.viscoelastic is not None:
                sls = link.viscoelastic
                decay, g = sls.step_coefficients(dt)
                f[link.flexible] = ((sls.relaxed_modulus_Pa + g * sls.maxwell_modulus_Pa) / link.material.E_Pa
                                    + link.damping.stiffness_s * c_v)
                visco[link.name] = (decay, g)
            factors[link.name] = f
        return factors, visco

    # -- per-configuration maps -------------------------------------------------------------
    def _configurations(self, angle, speed, accel, dt, maps: bool | str = "auto", axial_force=None):
        """Factorize the instantaneous structures of a batch of crank states and return the
        affine maps from nodal loads (local, stacked) to nodal displacements, drive torque and
        gauge strains (and, for the 'dynamic' axial force, segment axial forces). ``maps``: True,
        False, or "auto" (only for models up to MAP_MAX_DOF). ``axial_force``: stacked segment
        forces ``(B, n_seg)`` [N] for the field matrices instead of the quasi-static estimate."""
        mech = self.mech
        motion = mech.motion(angle, speed, accel)
        c_a, c_v = self.integrator.coefficients(dt)
        Kn = _coupling_stiffness(mech, motion, self.coupling, c_a, c_v)
        factors, _ = self._link_factor(c_v, dt)
        P = None
        if axial_force is not None:
            cuts = np.cumsum([l.total_segments for l in self.links])[:-1]
            P = dict(zip([l.name for l in self.links], np.split(np.asarray(axial_force, dtype=float), cuts, axis=-1)))
        elif self.axial_force != "none":
            # The axial forces only enter the field matrices: 1e-8 relative is ample. The dynamic
            # step iterates from the linear (rigid-body) estimate, which exists beyond the static
            # Euler load too; the quasi-static model uses the beam-column one.
            qs = quasi_static(mech, angle, speed, accel, beam_column=self.axial_force == "quasi_static",
                              coupling=Coupling(), gravity=self.gravity, tol=1e-8)
            # The segment forces of the solution (for the beam-column solve they equal the ones in
            # its field matrices; a linear solve has none there).
            P = {k: _segment_forces(r) for k, r in qs.solution.members.items()}
        # Batch (B, 1): the second axis carries the unit loads. Gravity acts through the lumped
        # node masses (rigid_body_loads), like every other inertial load.
        joints = {k: v[:, None, :] for k, v in mech.joint_positions(motion).items()}
        case = LoadCase(joints, {}, {}, {k: v[:, None] for k, v in Kn.items()}, frame="local")
        factor = factorize(self.structure, case, None if P is None else {k: v[:, None] for k, v in P.items()},
                           check_buckling=False, stiffness_factor=factors, count_inertia=True)
        indefinite = np.any(np.reshape(factor.negative_eigenvalues, (len(angle), -1)) > 0, axis=-1)
        if np.any(indefinite) and (self.axial_force != "dynamic" or axial_force is not None):
            # The axial forces are those the step uses: the step's dynamic system is indefinite.
            raise DynamicStabilityError(
                f"the dynamic system of the time step (stiffness with the axial forces, plus the step's inertia) is "
                f"not positive definite at crank angle {math.degrees(float(angle[np.argmax(indefinite)])):.6g} deg: "
                "the links buckle even with their inertia; the transfer-matrix model cannot continue (a smaller step "
                "adds inertia)")
        loads_local = rigid_body_loads(mech, motion, self.gravity, frame="local")
        drive = mech.drive_torque_terms(motion, self.gravity)
        P0 = None if P is None else np.concatenate([P[l.name] for l in self.links], axis=-1)
        B = len(angle)
        n_rows = self.n_dof + 1 + 2 * len(self.gauges) + (len(self.segments.length) if self.axial_force == "dynamic" else 0)
        n_bytes = 8.0 * B * self.n_dof * n_rows
        base = {"factor": factor, "rigid": self._stack(loads_local), "motion": motion, "maps": None, "drive": drive,
                "P0": P0, "crank": (np.asarray(angle, float), np.asarray(speed, float), np.asarray(accel, float)),
                # Configurations whose estimated axial forces leave the step indefinite: the
                # dynamic step refactorizes them at its own axial forces.
                "indefinite": indefinite}
        if not maps or n_bytes > self.max_map_bytes or (maps == "auto" and self.n_dof > MAP_MAX_DOF):
            return base
        unit = {}
        for link in self.links:
            n1 = link.n_nodes
            U = np.zeros((self.n_dof, n1, 3))
            off = self.offsets[link.name]
            U[off:off + 3 * n1].reshape(n1, 3, n1, 3)[np.arange(n1), :, np.arange(n1), :] = np.eye(3)
            unit[link.name] = U
        # Unit loads plus one zero-load column (the response to gravity and other base loads).
        unit = {k: np.concatenate([v, np.zeros((1,) + v.shape[1:])])[None] for k, v in unit.items()}
        # Solved in chunks of configurations: the station states of every unit load take about
        # 32 n_dof^2 bytes per configuration (0.5 GB for a revolution at 0.5 deg, 16 segments per link).
        chunk = max(1, int(MAP_CHUNK_BYTES // (32.0 * self.n_dof ** 2)))
        n_out = 1 + 2 * len(self.gauges)
        maps = {"Z": np.empty((B, self.n_dof, self.n_dof)), "z0": np.empty((B, self.n_dof)),
                "O": np.empty((B, n_out, self.n_dof)), "o0": np.empty((B, n_out))}
        axial = self.axial_force == "dynamic"
        if axial:
            n_seg = len(self.segments.length)
            maps["A"], maps["a0"] = np.empty((B, n_seg, self.n_dof)), np.empty((B, n_seg))
        for c0 in range(0, B, chunk):
            sl = slice(c0, min(B, c0 + chunk))
            sol = solve_factored(factor if (sl.start, sl.stop) == (0, B) else _select(factor, sl), unit, frame="local")
            z = np.concatenate([sol.members[l.name].state[..., 0, :3].reshape(sl.stop - sl.start, self.n_dof + 1, -1)
                                for l in self.links], axis=-1)                 # (b, loads+1, n_dof)
            torque = torque_from_terms(sol.reactions, *_terms_at(drive, sl))   # (b, loads+1)
            g_out = [np.stack(gauge_strains(sol.members[g.link], g), -1) for g in self.gauges]
            outs = np.concatenate([torque[..., None]] + g_out, axis=-1) if g_out else torque[..., None]
            maps["Z"][sl] = np.swapaxes(z[:, :-1] - z[:, -1:], 1, 2)
            maps["z0"][sl] = z[:, -1]
            maps["O"][sl] = np.swapaxes(outs[:, :-1] - outs[:, -1:], 1, 2)
            maps["o0"][sl] = outs[:, -1]
            if axial:
                N = np.concatenate([_segment_forces(sol.members[l.name]) for l in self.links], axis=-1)
                maps["A"][sl] = np.swapaxes(N[:, :-1] - N[:, -1:], 1, 2)
                maps["a0"][sl] = N[:, -1]
            del sol
        return {**base, "maps": maps}

    def stack(self, per_link):
        """Stack per-link arrays ``{link: (..., n+1, 3)}`` into the node vector ``(..., n_dof)``."""
        return self._stack(per_link)

    def _stack(self, per_link):
        return np.concatenate([per_link[l.name].reshape(per_link[l.name].shape[:-2] + (-1,)) for l in self.links], -1)

    def _solve_one(self, cfg, k, loads):
        """Response to the stacked local loads at configuration index k (map or sweep):
        ``(z, out, N)`` with ``N`` the solver's segment axial forces (None without them)."""
        maps = cfg["maps"]
        if maps is not None:
            N = maps["A"][k] @ loads + maps["a0"][k] if "A" in maps else None
            return maps["Z"][k] @ loads + maps["z0"][k], maps["O"][k] @ loads + maps["o0"][k], N
        node_loads = self._node_loads(loads)
        if cfg["factor"].batch[0] == 1:
            factor = cfg["factor"]
        else:
            # Selecting one configuration walks the whole factor (4 ms at 32 segments per link):
            # keep each selection (views, no copies) for the following revolutions.
            chosen = cfg.setdefault("selected", {})
            factor = chosen.get(k)
            if factor is None:
                factor = chosen[k] = _select(cfg["factor"], k)
        return self._response(solve_factored(factor, node_loads, frame="local"), _terms_at(cfg["drive"], k))

    def _response(self, sol, drive):
        """``(z, out, N)`` of a single-configuration solution: node displacements, outputs and the
        segment axial forces; ``drive``: the configuration's drive-torque terms
        (:meth:`FourBarMechanism.drive_torque_terms`)."""
        z = np.concatenate([sol.members[l.name].state[..., 0, :3].reshape(-1) for l in self.links])
        out = [np.reshape(torque_from_terms(sol.reactions, *drive), ())]
        for g in self.gauges:
            b, a = gauge_strains(sol.members[g.link], g)
            out += [b.reshape(()), a.reshape(())]
        N = np.concatenate([_segment_forces(sol.members[l.name]).reshape(-1) for l in self.links])
        return z, np.array(out), N

    def solve_step(self, cfg, k, loads, state, dt, axial_guess=None):
        """Displacements ``z``, outputs and segment axial forces [N] of one time step at
        configuration ``k`` of ``cfg`` for the stacked local ``loads`` (inertia history included)
        and the integrator ``state`` before the step. Linear for 'quasi_static' and 'none';
        for 'dynamic' the second-order pseudo-loads are iterated to convergence on the cached
        factorization, starting from ``axial_guess`` (e.g. the previous step's forces). Where the
        axial forces move far from the cached ones (a strong transient) that iteration can fail;
        the step is then factorized afresh at the latest axial forces and iterated again."""
        if self.axial_force != "dynamic":
            return self._solve_one(cfg, k, loads)
        guess = axial_guess
        diag = (0, float("nan"), float("nan"))
        for attempt in range(AXIAL_RESTARTS + 1):
            if cfg["indefinite"][k]:
                if guess is None:
                    break
                result, guess_new = None, guess
            else:
                result, guess_new, diag = self._iterate(cfg, k, loads, state, dt, guess)
            if result is not None:
                self.last_iterations = diag[0]
                return result
            # Refactorize this step at the best axial forces known: the previous step's, then
            # the failed iteration's last finite estimate.
            guess = guess if attempt == 0 and guess is not None else guess_new
            if guess is None or not np.all(np.isfinite(guess)):
                break
            angle, speed, accel = (x[k:k + 1] for x in cfg["crank"])
            cfg, k = self._configurations(angle, speed, accel, dt, maps=False, axial_force=guess[None]), 0
        crank = math.degrees(float(cfg["crank"][0][k]))
        raise ConvergenceError(
            f"the second-order (axial_force 'dynamic') step did not converge at crank angle {crank:.6g} deg "
            f"(after {AXIAL_RESTARTS} refactorizations; last relative changes: displacement {diag[1]:.3g}, axial "
            f"force {diag[2]:.3g}); the links are near a dynamic instability or the step is too large (reduce "
            "solver.tmm.step)")

    def _iterate(self, cfg, k, loads, state, dt, axial_guess):
        """The fixed-point iteration of :meth:`solve_step` on one factorization: ``((z, out, P),
        None, (iterations, 0, 0))`` when converged, else ``(None, last finite P, (iterations,
        displacement change, axial-force change))``."""
        seg = self.segments
        c_a, c_v = self.integrator.coefficients(dt)
        _, h_v = self.integrator.history(state, dt)
        # Kelvin-Voigt: the physical axial force adds beta EA/L times the history part of the
        # relative axial velocity (the solver's own force carries EA (1 + beta c_v) (u1 - u0)/L).
        damping = seg.beta * seg.stiffness * (h_v[seg.end] - h_v[seg.start])
        P0 = cfg["P0"][k]
        P = P0 if axial_guess is None else axial_guess
        z = state["d"] + dt * state["v"] + 0.5 * dt**2 * state["a"]
        # Anderson acceleration of the fixed point on x = (z, P L/EA): the axial force scaled to
        # the axial displacement it causes, so that both parts weigh alike in the mixing.
        n, to_len = len(z), seg.length / seg.EA
        x = np.concatenate([z, P * to_len])
        history, previous, last_finite = [], None, None
        scale_P = 1e-9 * float(np.max(seg.EA))
        dz = dP = float("nan")
        shorten, own_force = "shortening" in self.dynamic_terms, "axial_force" in self.dynamic_terms
        for it in range(self.axial_iterations):
            z, P = x[:n], x[n:] / to_len
            f, F, delta = pseudo_loads(seg, z, c_v * z + h_v, P if own_force else P0, P0, shorten)
            z_new, out, N = self._solve_one(cfg, k, loads + f)
            P_new = N + damping + F
            if not (np.all(np.isfinite(z_new)) and np.all(np.isfinite(P_new))):
                break
            last_finite = P_new
            dz = float(np.max(np.abs(z_new - z))) / (float(np.max(np.abs(z_new))) + 1e-300)
            dP = float(np.max(np.abs(P_new - P))) / (float(np.max(np.abs(P_new))) + scale_P)
            # The axial force only feeds the geometric stiffness: 1e-6 is ample (and its round-off
            # floor, a difference of large nodal forces, sits near 1e-8).
            if dz < self.axial_tolerance and dP < 1e-6:
                if len(self._gauge_segment) and shorten:
                    # Gauge axial strain = the full axial strain, with the shortening from bending.
                    delta = shape_products(seg, z_new)[0]
                    out = out.copy()
                    out[2::2] += delta[self._gauge_segment] / seg.length[self._gauge_segment]
                return (z_new, out, P_new), None, (it + 1, dz, dP)
            if dz > 1e3 or dP > 1e3:       # diverging: refactorize rather than iterate on
                break
            gx = np.concatenate([z_new, P_new * to_len])
            r = gx - x
            if previous is not None:
                history.append((r - previous[0], gx - previous[1]))
                history = history[-ANDERSON_DEPTH:]
            previous = (r, gx)
            x = gx
            if history:
                dR = np.stack([h[0] for h in history], axis=1)
                dG = np.stack([h[1] for h in history], axis=1)
                try:
                    gamma = np.linalg.lstsq(dR, r, rcond=None)[0]
                    x = gx - dG @ gamma
                except np.linalg.LinAlgError:
                    history = []
        return None, last_finite, (self.axial_iterations, dz, dP)

    def _kernel_data(self, cfg):
        """The arrays of a configuration batch the compiled march reads (cached in the batch)."""
        data = cfg.get("kernel")
        if data is None:
            maps = cfg["maps"]
            B = len(cfg["rigid"])
            ns = len(self.segments.length)
            dynamic = self.axial_force == "dynamic"
            omega = np.stack([self._node_omega(cfg, i) for i in range(B)]) if self.coupling.coriolis else \
                np.zeros((1, self.n_dof))
            data = cfg["kernel"] = tuple(np.ascontiguousarray(x, dtype=float) for x in (
                maps["Z"], maps["z0"], maps["O"], maps["o0"],
                maps["A"] if dynamic else np.zeros((1, ns, self.n_dof)), maps["a0"] if dynamic else np.zeros((1, ns)),
                cfg["P0"] if dynamic else np.zeros((1, ns)), cfg["rigid"], omega))
        return data

    def _node_loads(self, loads):
        return {l.name: loads[self.offsets[l.name]:self.offsets[l.name] + 3 * l.n_nodes]
                .reshape(l.n_nodes, 3)[None, None] for l in self.links}

    # -- marching -----------------------------------------------------------------------------
    def begin(self, dt: float, angle: float, speed: float, acceleration: float = 0.0, *, start: str = "rest",
              initial: Mapping[str, np.ndarray] | None = None) -> "March":
        """Start an incremental march at a crank state (step ``dt`` [s]); see :class:`March`."""
        return March(self, float(require_positive("time step dt_s", dt)), float(angle), float(speed),
                     float(acceleration), start, initial)

    def run(self, crank: CrankMotion, *, start: str = "rest", steady_tol: float | None = None,
            min_revolutions: int = 2, record_displacements: bool = True,
            callback: Callable[[int, float], bool] | None = None, chunk: int = 720,
            initial: Mapping[str, np.ndarray] | None = None) -> KEDResult:
        """March through the crank history.

        ``start``: 'rest' (zero elastic state, Shin) or 'quasi_static' (elastic state of the
        quasi-static solution at the first positions). ``steady_tol``: stop when the
        revolution-to-revolution change of the drive torque and gauge strains, relative to their
        peak-to-peak, falls below it (needs a constant-speed history); the change is reported.
        ``callback(step, t)`` returning False stops the run early (partial results kept).
        ``initial``: explicit initial state instead of ``start``: ``{'d', 'v', 'a', 'previous'}``
        with stacked local node vectors (see :attr:`offsets`) and ``previous = (d_-1, d_-2)``.
        """
        dt = crank.dt
        n_steps = len(crank.t)
        N = crank.steps_per_revolution()
        if steady_tol is not None:
            require_positive("steady_tol", steady_tol)
            if N is None:
                raise InputError("steady_tol needs a constant-speed crank history with a whole number of steps per "
                                 "revolution")
        march = self.begin(dt, crank.angle[0], crank.speed[0], crank.acceleration[0], start=start, initial=initial)
        outputs = np.full((n_steps, march.n_out), np.nan)
        disp = np.full((n_steps, self.n_dof), np.nan) if record_displacements else None
        outputs[0] = march.out
        if disp is not None:
            disp[0] = march.z

        cfg, cfg_start, cfg_len = None, -1, 0
        steady, change, done = False, float("nan"), n_steps
        k = 1
        while k < n_steps:
            # Configurations are factorized in batches: one revolution when the history is periodic,
            # chunks of consecutive steps otherwise. Steps are marched in blocks that end at a
            # revolution (the steady-state check) or at the end of a chunk; one by one with a callback.
            if N is not None:
                if cfg is None:
                    cfg = self._configurations(crank.angle[:N], crank.speed[:N], crank.acceleration[:N], dt)
                end = min(n_steps, (k // N + 1) * N)
                indices = np.arange(k, end) % N
            else:
                if cfg is None or k >= cfg_start + cfg_len:
                    cfg_start, cfg_len = k, min(chunk, n_steps - k)
                    sl = slice(k, k + cfg_len)
                    cfg = self._configurations(crank.angle[sl], crank.speed[sl], crank.acceleration[sl], dt)
                end = cfg_start + cfg_len
                indices = np.arange(k, end) - cfg_start
            if callback is not None:
                indices, end = indices[:1], k + 1
            zs, outs = march.step_many(cfg, indices, record_z=disp is not None)
            outputs[k:end] = outs
            if disp is not None:
                disp[k:end] = zs
            if not np.all(np.isfinite(outs)):
                bad = k + int(np.argmax(~np.all(np.isfinite(outs), axis=1)))
                raise InputError(f"time-domain solution became non-finite at step {bad} (t = {crank.t[bad]:.6g} s)")
            k = end
            last = k - 1
            if N is not None and last >= N and k % N == 0 and k // N >= min_revolutions:
                rev = outputs[k - N:k]
                prev = outputs[k - 2 * N:k - N]
                ptp = np.maximum(np.ptp(rev, axis=0), 1e-300)
                change = float(np.max(np.max(np.abs(rev - prev), axis=0) / ptp))
                if steady_tol is not None and change < steady_tol:
                    steady, done = True, k
                    break
            if callback is not None and callback(last, float(crank.t[last])) is False:
                done = k
                break

        sl = slice(0, done)
        gauges = {g.name: (outputs[sl, 1 + 2 * i], outputs[sl, 2 + 2 * i]) for i, g in enumerate(self.gauges)}
        displacements = {}
        if disp is not None:
            displacements = self.unstack(disp[sl])
        revs = (crank.angle[done - 1] - crank.angle[0]) / (2 * math.pi)
        return KEDResult(crank.t[sl], crank.angle[sl], crank.speed[sl], crank.acceleration[sl], outputs[sl, 0],
                         gauges, displacements, steady, change, abs(float(revs)), self.integrator.name,
                         {"dt_s": dt, "steps": done, "steps_per_revolution": N, "start": start,
                          "maps": cfg["maps"] is not None if cfg else None})

    def unstack(self, vectors: np.ndarray):
        """Split node vectors ``(..., n_dof)`` into ``{link: (..., n_nodes, 3)}``."""
        out = {}
        for l in self.links:
            off = self.offsets[l.name]
            out[l.name] = vectors[..., off:off + 3 * l.n_nodes].reshape(vectors.shape[:-1] + (l.n_nodes, 3))
        return out

    def _loads(self, cfg, idx, state, dt, beta_vec, has_kv, q_sls, decay, gain, has_visco, is_u, is_w):
        """Stacked local nodal loads of a step: D'Alembert, inertia history, material history."""
        m = self.m_vec
        loads = cfg["rigid"][idx].copy()
        h_a, h_v = self.integrator.history(state, dt)
        loads -= m * (h_a + self.aM_vec * h_v)
        if self.coupling.coriolis:
            w = self._node_omega(cfg, idx)
            hv_w = np.roll(h_v, -1)   # at u rows: the w-velocity history of the same node
            hv_u = np.roll(h_v, 1)    # at w rows: the u-velocity history of the same node
            loads += np.where(is_u, 2.0 * m * w * hv_w, 0.0) - np.where(is_w, 2.0 * m * w * hv_u, 0.0)
        if has_kv:
            loads -= beta_vec * (self.K_local @ h_v)
        if has_visco:
            loads -= self.gather.T @ (decay * q_sls - gain * (self.seg_K @ (self.gather @ state["d"])))
        return loads

    def _rest_acceleration(self, loads, motion):
        """Accelerations of the lumped masses under ``loads`` (stacked local) with the structure at
        rest and undeformed: each mass alone, except at joints, where all member ends share the
        translation (and, for rigid connections, the rotation); supported DOFs stay at rest."""
        m = self.m_vec
        a = np.divide(loads, m, out=np.zeros_like(loads), where=m > 0)
        structure = self.structure
        for joint in structure.joints:
            ends = []
            for link, member in zip(self.links, structure.members):
                n = link.total_segments
                if member.start == joint.name:
                    ends.append((link, self.offsets[link.name], member.start_connection))
                if member.end == joint.name:
                    ends.append((link, self.offsets[link.name] + 3 * n, member.end_connection))
            F, M_sum = np.zeros(2), 0.0
            for link, i, _ in ends:
                c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
                R = np.array([[c, -s_], [s_, c]])           # local -> global
                F += R @ loads[i:i + 2]
                M_sum += m[i]
            acc = F / M_sum if M_sum > 0 and joint.support == "free" else np.zeros(2)
            rigid = [e for e in ends if e[2] == "rigid"]
            J_sum = sum(m[i + 2] for _, i, _ in rigid)
            Mz = sum(loads[i + 2] for _, i, _ in rigid)
            for link, i, conn in ends:
                c, s_ = np.cos(motion.link(link.name).angle[0]), np.sin(motion.link(link.name).angle[0])
                a[i:i + 2] = np.array([[c, s_], [-s_, c]]) @ acc
                if conn == "rigid":
                    a[i + 2] = Mz / J_sum if J_sum > 0 and joint.support != "clamped" else 0.0
        return a

    def _node_omega(self, cfg, idx):
        motion = cfg["motion"]
        return np.concatenate([np.full(3 * l.n_nodes, float(motion.link(l.name).omega[idx]))
                               for l in self.links])

    def _quasi_static_start(self, th, w, a, dt):
        """Elastic state of the quasi-static solution at the first crank positions."""
        angles = th + np.array([-2.0, -1.0, 0.0, 1.0]) * w * dt
        qs = quasi_static(self.mech, angles, w, a, beam_column=self.beam_column, coupling=Coupling(),
                          gravity=self.gravity)
        z = np.concatenate([qs.solution.members[l.name].state[:, :, 0, :3].reshape(4, -1) for l in self.links], -1)
        d2, d1, d0, dp = z
        v0 = (dp - d1) / (2 * dt)
        a0 = (dp - 2 * d0 + d1) / dt**2
        return d0, v0, a0, (d1, d2)


class March:
    """Incremental time-domain march of a :class:`TimeDomain` (one step at a time).

    Built by :meth:`TimeDomain.begin` at a crank state; :meth:`advance` takes the crank state at
    the end of the next step. ``z`` holds the current nodal displacements (stacked, local) and
    ``out`` the current outputs (drive torque [N m], then bending and axial strain per gauge).
    """

    def __init__(self, td: TimeDomain, dt, angle, speed, accel, start, initial):
        if start not in ("rest", "quasi_static"):
            raise InputError(f"start must be 'rest' or 'quasi_static', got {start!r}")
        if initial is not None:
            for key in ("d", "v", "a"):
                if np.shape(initial.get(key)) != (td.n_dof,):
                    raise InputError(f"initial['{key}'] must have shape ({td.n_dof},)")
        self.td, self.dt = td, dt
        integ = td.integrator
        c_a, c_v = integ.coefficients(dt)
        _, visco = td._link_factor(c_v, dt)
        a1 = np.array([angle])
        d0 = v0 = np.zeros(td.n_dof)
        previous = (d0, d0)
        if initial is not None:
            d0, v0, a0 = (np.asarray(initial[k], dtype=float) for k in ("d", "v", "a"))
            previous = initial.get("previous", (d0, d0))
        elif start == "quasi_static":
            d0, v0, a0, previous = td._quasi_static_start(angle, speed, accel, dt)
        else:
            # Consistent initial acceleration from rest: M a0 = F(t0) (Newmark and generalized-alpha
            # are only first order otherwise; Houbolt does not use it).
            first = td._configurations(a1, np.array([speed]), np.array([accel]), dt, maps=False)
            a0 = td._rest_acceleration(first["rigid"][0], first["motion"])
        self.state = integ.initial(d0, v0, a0, previous)
        # Outputs of step 0: the quasi-static state for a quasi-static start; from rest the links
        # are undeformed (zero strain) and the drive torque is the rigid-body one.
        qs0 = quasi_static(td.mech, a1, speed, accel, beam_column=td.beam_column, gravity=td.gravity, gauges=td.gauges)
        out = np.concatenate([qs0.drive_torque] + [np.r_[b, a] for b, a in qs0.gauges.values()])
        if start == "rest" and initial is None:
            out[1:] = 0.0
        self.out, self.z = out, d0
        self.n_out = len(out)
        self.decay = np.ones(6 * td.n_seg)
        self.gain = np.zeros(6 * td.n_seg)
        off = 0
        for link in td.links:
            if link.name in visco:
                decay, g = visco[link.name]
                sel = slice(off, off + 6 * link.total_segments)
                self.decay[sel] = np.where(td.seg_E1[sel] > 0, decay, 1.0)
                self.gain[sel] = g * td.seg_E1[sel]
            off += 6 * link.total_segments
        self.beta = np.concatenate([np.full(3 * l.n_nodes, l.damping.stiffness_s) for l in td.links])
        self.has_visco = bool(visco)
        self.has_kv = bool(np.any(self.beta > 0))
        self.q_sls = np.zeros(6 * td.n_seg)
        if self.has_visco and (start == "quasi_static" or initial is not None):
            # Instantaneous elastic state: the Maxwell arms carry (E_0 - E_inf)/E * K d_0.
            self.q_sls = td.seg_E1 * (td.seg_K @ (td.gather @ d0))
        #: Segment axial forces of the last step [N] (the next step's starting guess).
        self.axial = None
        # Coriolis cross terms: u rows take the w-velocity history of the same node and back.
        self.is_u = np.tile([True, False, False], td.n_dof // 3)
        self.is_w = np.tile([False, True, False], td.n_dof // 3)

    def advance(self, angle: float, speed: float, acceleration: float = 0.0):
        """One step to the crank state (angle [rad], speed [rad/s], acceleration [rad/s^2]) at
        the end of the step. Returns ``(z, out)``."""
        args = (np.array([angle], dtype=float), np.array([speed], dtype=float), np.array([acceleration], dtype=float),
                self.dt)
        return self.step_with(self.td._configurations(*args, maps=False), 0)

    def step_with(self, cfg, idx):
        """One step using configuration ``idx`` of a precomputed batch (see TimeDomain._configurations)."""
        td = self.td
        loads = td._loads(cfg, idx, self.state, self.dt, self.beta, self.has_kv, self.q_sls, self.decay, self.gain,
                          self.has_visco, self.is_u, self.is_w)
        z, out, P = td.solve_step(cfg, idx, loads, self.state, self.dt, self.axial)
        self.axial = P
        return self._commit(z, out)

    def step_many(self, cfg, indices, record_z: bool = True, record_axial: bool = False):
        """Steps through configurations ``indices`` of a batch, compiled when the batch has
        cached maps (:mod:`tmm_core.kernels`), else one by one in numpy. Returns ``(zs, outs)``:
        displacements ``(k, n_dof)`` (None unless ``record_z``) and outputs ``(k, n_out)``; with
        ``record_axial`` also the segment axial forces ``(k, n_seg)`` of the 'dynamic' step."""
        indices = np.asarray(indices, dtype=np.int64)
        td = self.td
        if td.compiled and cfg["maps"] is not None and not self.has_visco and td.integrator.name in kernels.INTEGRATOR_CODES:
            return self._compiled(cfg, indices, record_z, record_axial)
        zs = np.empty((len(indices), td.n_dof)) if record_z else None
        outs = np.empty((len(indices), self.n_out))
        Ps = np.empty((len(indices), len(td.segments.length))) if record_axial else None
        for j, i in enumerate(indices):
            z, outs[j] = self.step_with(cfg, int(i))
            if record_z:
                zs[j] = z
            if record_axial:
                Ps[j] = self.axial
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _compiled(self, cfg, indices, record_z, record_axial=False):
        td, n, integ = self.td, self.td.n_dof, self.td.integrator
        data = td._kernel_data(cfg)
        code = kernels.INTEGRATOR_CODES[integ.name]
        params = np.array(integ.parameters if code == kernels.GENERALIZED_ALPHA else (0.0, 0.0, 0.0, 0.0), float)
        c_a, c_v = integ.coefficients(self.dt)
        st = self.state
        zero = np.zeros(n)
        arrays = [np.array(st.get(key, zero), dtype=float) for key in ("d", "v", "a", "acc", "d1", "d2")]
        seg = td.segments
        dynamic = td.axial_force == "dynamic"
        P = np.array(self.axial if self.axial is not None else
                     (cfg["P0"][indices[0]] if dynamic else np.zeros(len(seg.length))), dtype=float)
        outs = np.empty((len(indices), self.n_out))
        zs = np.empty((len(indices), n)) if record_z else np.empty((0, n))
        Ps = np.empty((len(indices), len(seg.length))) if record_axial else np.empty((0, len(seg.length)))
        iterations = np.zeros(len(indices), dtype=np.int64)
        j = 0
        while j < len(indices):
            done = kernels.compiled_march()(
                code, params, self.dt, c_a, c_v, indices[j:], *data, td.m_vec, td.aM_vec, self.beta, seg.start,
                seg.end, seg.length, seg.EA, seg.beta, td.seg_blocks, td._gauge_segment, td.coupling.coriolis,
                self.has_kv, dynamic, "shortening" in td.dynamic_terms, "axial_force" in td.dynamic_terms,
                td.axial_tolerance, 1e-6, td.axial_iterations, ANDERSON_DEPTH, *arrays, P, outs[j:],
                zs[j:] if record_z else zs, Ps[j:] if record_axial else Ps, iterations[j:])
            self.state = {key: arr.copy() for key, arr in zip(("d", "v", "a", "acc", "d1", "d2"), arrays) if key in st}
            self.axial = P.copy() if dynamic else self.axial
            j += done
            if j < len(indices):
                # A step the kernel hands back: the numpy path refactorizes it at its own axial forces.
                z, outs[j] = self.step_with(cfg, int(indices[j]))
                if record_z:
                    zs[j] = z
                if record_axial:
                    Ps[j] = self.axial
                arrays = [np.array(self.state.get(key, zero), dtype=float) for key in ("d", "v", "a", "acc", "d1", "d2")]
                P = np.array(self.axial, dtype=float) if dynamic else P
                j += 1
        self.z = self.state["d"]
        self.out = outs[-1]
        zs = zs if record_z else None
        return (zs, outs, Ps) if record_axial else (zs, outs)

    def _commit(self, z, out):
        td = self.td
        if self.has_visco:
            self.q_sls = self.decay * self.q_sls + self.gain * (td.seg_K @ (td.gather @ (z - self.state["d"])))
        self.state = td.integrator.advance(self.state, z, self.dt)
        self.z, self.out = z, out
        return z, out


def _segment_forces(result) -> np.ndarray:
    """Axial force [N] of every segment of a member result (constant within a segment: the loads
    act at the nodes), ``(..., n)``."""
    return 0.5 * (result.N[..., :-1, 1] + result.N[..., 1:, 0])


def _terms_at(terms, k):
    """Drive-torque terms of configuration ``k`` (an index or a slice) of a batch."""
    joint, arm, offset = terms
    if arm is None:
        return terms
    return joint, arm[k], np.asarray(offset)[k]


def _select(factor, k):
    """Configuration ``k`` (an index or a slice) of a factor with batch (B, 1): views, no copies."""
    import dataclasses
    sl = k if isinstance(k, slice) else slice(k, k + 1)
    n = len(range(*sl.indices(factor.batch[0])))

    def take(x):
        if isinstance(x, np.ndarray) and x.ndim >= 2 and x.shape[0] == factor.batch[0] and x.shape[1] == 1:
            return x[sl]
        if isinstance(x, tuple):
            return tuple(take(v) for v in x)
        if isinstance(x, list):
            return [take(v) for v in x]
        if isinstance(x, dict):
            return {kk: take(v) for kk, v in x.items()}
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return dataclasses.replace(x, **{f.name: take(getattr(x, f.name)) for f in dataclasses.fields(x)
                                            if f.name not in ("structure", "case")})
        return x

    out = take(factor)
    return dataclasses.replace(out, batch=(n, 1))


def time_domain(mech: FourBarMechanism, crank: CrankMotion, **kw) -> KEDResult:
    """Convenience wrapper: ``TimeDomain(mech, ...).run(crank, ...)``; keyword arguments are split
    between the constructor and :meth:`TimeDomain.run`."""
    run_keys = {"start", "steady_tol", "min_revolutions", "record_displacements", "callback", "chunk"}
    run_kw = {k: v for k, v in kw.items() if k in run_keys}
    init_kw = {k: v for k, v in kw.items() if k not in run_keys}
    return TimeDomain(mech, **init_kw).run(crank, **run_kw)
