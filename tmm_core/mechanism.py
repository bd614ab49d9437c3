"""Mechanism descriptions (SI) and their instantaneous structures.

A four-bar is frozen, at each crank position, into Shin's *instantaneous structure*: the crank
is clamped at its ground pivot A (it carries the drive torque), the coupler is pinned to the
crank at B and to the rocker at C, and the rocker is pinned to the ground at D.

Member orientation (local x) and therefore the local +y ("top") face:
crank A->B, coupler B->C, rocker D->C (from its ground pivot).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_finite, require_nonnegative
from .kinematics import FourBarGeometry, FourBarMotion, LinkMotion, fourbar_motion
from .materials import Damping, StandardLinearSolid
from .sections import Material, Section
from .structure import Joint, LoadCase, Member, Structure

FOURBAR_LINKS = ("crank", "coupler", "rocker")


@dataclass(frozen=True)
class PointMass:
    """A lumped mass on a link (bearing, sleeve, end block) at ``position_m`` from the link's
    start joint [m]: ``mass_kg`` [kg] and rotary inertia about its own centre ``inertia_kg_m2``."""

    position_m: float
    mass_kg: float
    inertia_kg_m2: float = 0.0
    label: str = ""

    def __post_init__(self):
        require_finite(f"point mass '{self.label}': position_m", self.position_m)
        require_nonnegative(f"point mass '{self.label}': mass_kg", self.mass_kg)
        require_nonnegative(f"point mass '{self.label}': inertia_kg_m2", self.inertia_kg_m2)


@dataclass(frozen=True)
class Link:
    """A straight prismatic link: length [m], section, material, number of TMM segments, and its
    mass model (distributed mass from the material density, plus point masses), damping and an
    optional viscoelastic material law for the time domain."""

    name: str
    length_m: float
    section: Section
    material: Material
    n_segments: int = 8
    point_masses: tuple = ()
    damping: Damping = Damping()
    viscoelastic: StandardLinearSolid | None = None

    def __post_init__(self):
        if self.viscoelastic is not None and not np.isclose(self.material.E_Pa,
                                                           self.viscoelastic.instantaneous_modulus_Pa, rtol=1e-9):
            raise InputError(f"link '{self.name}': material E_Pa ({self.material.E_Pa:.6g}) must equal the "
                             f"viscoelastic instantaneous_modulus_Pa ({self.viscoelastic.instantaneous_modulus_Pa:.6g}): "
                             "quasi-static and frequency analyses use the instantaneous modulus")

    def member(self, start: str, end: str, **kw) -> Member:
        return Member.uniform(self.name, start, end, self.length_m, self.n_segments, self.section,
                              self.material, **kw)

    @property
    def stations(self) -> np.ndarray:
        return np.linspace(0.0, self.length_m, self.n_segments + 1)

    def node_masses(self):
        """Lumped mass [kg] and rotary inertia [kg m^2] at each node, shape (n+1,) each.

        The distributed mass rho*A is lumped half a segment to each side (Shin); the rotary
        inertia of the strip itself is neglected (Euler-Bernoulli). Point masses must sit on a node.
        """
        n = self.n_segments
        h = self.length_m / n
        m = np.full(n + 1, self.material.density_kg_m3 * self.section.area_m2 * h)
        m[[0, n]] *= 0.5
        J = np.zeros(n + 1)
        x = self.stations
        for pm in self.point_masses:
            j = int(np.argmin(np.abs(x - pm.position_m)))
            if abs(x[j] - pm.position_m) > 1e-9 * self.length_m:
                raise InputError(f"link '{self.name}': point mass '{pm.label}' at {pm.position_m:.6g} m is not at a "
                                 f"node of the {n}-segment mesh (nodes every {h:.6g} m)")
            m[j] += pm.mass_kg
            J[j] += pm.inertia_kg_m2
        return m, J


@dataclass(frozen=True)
class FourBarMechanism:
    """Four-bar with flexible links. ``ground_m`` is the distance A-D [m]."""

    crank: Link
    coupler: Link
    rocker: Link
    ground_m: float
    pivot: tuple = (0.0, 0.0)
    ground_angle: float = 0.0
    branch: int = 1

    def __post_init__(self):
        for name, link in zip(FOURBAR_LINKS, (self.crank, self.coupler, self.rocker)):
            if link.name != name:
                raise InputError(f"four-bar: the {name} link must be named '{name}', got '{link.name}'")

    @property
    def geometry(self) -> FourBarGeometry:
        return FourBarGeometry(self.crank.length_m, self.coupler.length_m, self.rocker.length_m, self.ground_m,
                               self.pivot, self.ground_angle, self.branch)

    def links(self):
        return (self.crank, self.coupler, self.rocker)

    def structure(self) -> Structure:
        """Instantaneous structure: A clamped (crank welded), B and C revolutes, D pinned."""
        joints = (Joint("A", "clamped"), Joint("B"), Joint("C"), Joint("D", "pinned"))
        members = (self.crank.member("A", "B", start_connection="rigid"),
                   self.coupler.member("B", "C"),
                   self.rocker.member("D", "C"))
        return Structure(joints, members)

    def motion(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0) -> FourBarMotion:
        return fourbar_motion(self.geometry, crank_angle, crank_speed, crank_acceleration)

    drive_joint = "A"

    def joint_positions(self, motion: FourBarMotion):
        return {"A": motion.A, "B": motion.B, "C": motion.C, "D": motion.D}

    def external_loads(self, motion):
        """Applied loads besides inertia and gravity: none on a bare four-bar."""
        return {}

    def load_case(self, motion: FourBarMotion, node_loads=None, distributed_loads=None,
                  node_stiffness=None) -> LoadCase:
        """Load case at the positions of ``motion``; loads are ``{link: array}`` as in :class:`LoadCase`."""
        return LoadCase(self.joint_positions(motion), dict(node_loads or {}), dict(distributed_loads or {}),
                        dict(node_stiffness or {}))

    def gravity_loads(self, g=(0.0, -9.80665)):
        """Distributed self-weight ``{link: (n, 2)}`` [N/m] for gravity vector ``g`` [m/s^2]."""
        out = {}
        for link in self.links():
            w = link.material.density_kg_m3 * link.section.area_m2
            out[link.name] = np.broadcast_to(w * np.asarray(g, dtype=float), (link.n_segments, 2)).copy()
        return out


@dataclass(frozen=True)
class StaticMechanism:
    """A structure whose links do not move: the kineto-elastodynamic machinery then solves
    creep, step-load and free-vibration problems of any structure built from :class:`Link` s.

    ``members``: tuples ``(link, start_joint, end_joint, start_connection, end_connection)``;
    ``joints``: :class:`tmm_core.structure.Joint` s; ``positions``: joint coordinates [m];
    ``loads``: constant applied loads ``{link: (n+1, 3)}`` (global Fx, Fy, Mz), switched on at t = 0.
    The "drive torque" reported is the reaction moment at ``drive_joint``.
    """

    members: tuple
    joints: tuple
    positions: dict
    loads: dict = None
    drive_joint: str = "A"

    def links(self):
        return tuple(m[0] for m in self.members)

    def structure(self) -> Structure:
        return Structure(tuple(self.joints), tuple(link.member(a, b, start_connection=ca, end_connection=cb)
                                                   for link, a, b, ca, cb in self.members))

    def motion(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0):
        shape = np.shape(np.broadcast_arrays(np.asarray(crank_angle, float), np.asarray(crank_speed, float),
                                             np.asarray(crank_acceleration, float))[0])
        return _StaticMotion(self, shape)

    def joint_positions(self, motion):
        return {k: np.broadcast_to(np.asarray(v, dtype=float), motion.shape + (2,)) for k, v in self.positions.items()}

    def external_loads(self, motion):
        return {k: np.broadcast_to(np.asarray(v, dtype=float), motion.shape + np.shape(v))
                for k, v in (self.loads or {}).items()}

    def load_case(self, motion, node_loads=None, distributed_loads=None, node_stiffness=None) -> LoadCase:
        return LoadCase(self.joint_positions(motion), dict(node_loads or {}), dict(distributed_loads or {}),
                        dict(node_stiffness or {}))


@dataclass(frozen=True)
class _StaticMotion:
    mech: StaticMechanism
    shape: tuple

    def link(self, name: str) -> LinkMotion:
        for link, a, b, _, _ in self.mech.members:
            if link.name == name:
                pa = np.broadcast_to(np.asarray(self.mech.positions[a], float), self.shape + (2,))
                pb = np.asarray(self.mech.positions[b], float)
                ang = np.broadcast_to(np.arctan2(pb[1] - pa[..., 1], pb[0] - pa[..., 0]), self.shape)
                z2, z = np.zeros(self.shape + (2,)), np.zeros(self.shape)
                return LinkMotion(pa, z2, z2, ang, z, z)
        raise InputError(f"unknown link '{name}'")
