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
term of the FE thesis) and angular-acceleration (alpha) terms are switched on
with :class:`Coupling`. Centrifugal *stiffening* of bending comes from the axial forces of the
rigid-body inertia loads, i.e. from the beam-column coupling (``beam_column=True``).

Damping (per link, Rayleigh) and the standard-linear-solid material act through effective moduli
in the field matrices plus history loads computed from the exact segment stiffness
(:func:`tmm_core.riccati.segment_stiffness`).

The time domain lives in :mod:`tmm_core.transient` (configurations and the march driver),
:mod:`tmm_core.time_step` (the solution of one step, linear or second-order) and
:mod:`tmm_core.march` (the incremental march); this module holds the quasi-static analysis and
the data types they share.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from .compiled import statics as compiled_statics
from .backend import choose_backend
from .errors import InputError, SingularStructureError, require_finite, require_positive
from .kinematics import FourBarMotion
from .mechanism import FourBarMechanism
from .post import Gauge, gauge_strains
from .statics import solve_static
from .structure_types import LoadCase

GRAVITY = 9.80665


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


def node_mass_arrays(mech: FourBarMechanism):
    """Lumped node masses and rotary inertias of every elastic link, ``{link: (m (n+1,), J (n+1,))}``."""
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


def coupling_stiffness(mech, motion, coupling: Coupling, c_a=0.0, c_v=0.0, mass_damping=None):
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
                 tol: float = 1e-10, backend: str | None = None) -> QuasiStaticResult:
    """Kineto-elastostatic response at the crank positions ``crank_angle`` (array), vectorised.

    ``beam_column``: iterate on the segment axial forces (Shin). ``coupling``: the centrifugal
    and angular-acceleration terms act as stiffness to ground in the rotating frame (Coriolis has
    no quasi-static effect). A speed at which ``K - w^2 M`` is singular raises
    :class:`tmm_core.errors.SingularStructureError`.
    ``backend``: 'compiled' solves in the compiled factorization (:mod:`tmm_core.compiled.structure`)
    where the structure is one it handles (joints and members), 'numpy' in the reference
    (:func:`tmm_core.statics.solve_static`); None: compiled where numba is installed
    (:func:`tmm_core.backend.choose_backend`).
    """
    motion = mech.motion(crank_angle, crank_speed, crank_acceleration)
    loads = rigid_body_loads(mech, motion, gravity)
    stiffness = coupling_stiffness(mech, motion, Coupling(False, coupling.centrifugal, coupling.angular_acceleration),
                                    mass_damping=0.0) if coupling.any else {}
    # The node stiffness above is isotropic or skew in (u, w): the same in every frame.
    case = mech.load_case(motion, loads, None, stiffness)
    try:
        structure = mech.structure()
        solver = solve_static
        if choose_backend(backend) == "compiled" and np.ndim(crank_angle) == 1 \
                and compiled_statics.supported(structure):
            solver = compiled_statics.solve_static
        sol = solver(structure, case, beam_column=beam_column, tol=tol,
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


def linear_axial_forces(mech: FourBarMechanism, motion: FourBarMotion, gravity=None, local_loads=None) -> dict:
    """Segment axial forces [N, tension +] ``{link: (B, n)}`` of the linear kineto-elastostatic
    solution at the B configurations of ``motion`` (rigid-body loads, no coupling terms): those of
    ``quasi_static(..., beam_column=False)``, from the compiled solve's axial forces alone (no
    station states, torque or gauges: the time step's estimate of a revolution). ``local_loads``:
    the rigid-body loads in each link's frame when the caller has them
    (``rigid_body_loads(..., frame="local")``, as the time step does; ~1 ms a revolution not
    recomputed). Needs the compiled factorization (:func:`tmm_core.compiled.statics.supported`)."""
    structure = mech.structure()
    if local_loads is None:
        local_loads = rigid_body_loads(mech, motion, gravity, frame="local")
    case = LoadCase(mech.joint_positions(motion), dict(local_loads), {}, {}, frame="local")
    prep = compiled_statics.prepare(structure, case)
    (_, N, _), *_ = compiled_statics.solve_prepared(prep, np.zeros(prep.factor.shape), check_buckling=False,
                                                      compact_nodes=np.zeros(0, np.int64))
    off = prep.layout.seg_off
    return {m.name: N[:, off[i]:off[i + 1], 0] for i, m in enumerate(structure.members)}


def segment_forces(result) -> np.ndarray:
    """Axial force [N] of every segment of a member result (constant within a segment: the loads
    act at the nodes), ``(..., n)``."""
    return 0.5 * (result.N[..., :-1, 1] + result.N[..., 1:, 0])

