"""Mechanism descriptions (SI) and their instantaneous structures.

A four-bar is frozen, at each crank position, into Shin's *instantaneous structure*: the crank
is clamped at its ground pivot A (it carries the drive torque), the coupler is pinned to the
crank at B and to the rocker at C, and the rocker is pinned to the ground at D.

Member orientation (local x) and therefore the local +y ("top") face:
crank A->B, coupler B->C, rocker D->C (from its ground pivot).

Owns: the four-bar and slider-crank descriptions and their instantaneous structures. Does not:
no analysis.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_finite, require_nonnegative
from .kinematics import (FourBarGeometry, FourBarMotion, LinkMotion, SliderCrankGeometry, SliderCrankMotion,
                         fourbar_motion, slider_crank_motion)
from .materials import Damping, StandardLinearSolid
from .sections import Material, Section
from .structure import Joint, LoadCase, Member, Structure

FOURBAR_LINKS = ("crank", "coupler", "rocker")


def torque_from_terms(reactions, joint, arm, offset):
    """Drive torque from support reactions and :meth:`FourBarMechanism.drive_torque_terms`; the
    reactions may carry extra trailing batch axes beyond ``arm``'s (unit-load columns)."""
    R = np.asarray(reactions[joint])
    if arm is None:
        # The offset's batch axes lead; the reactions' extra ones (unit-load columns) follow.
        extra = max(R.ndim - 1 - np.ndim(offset), 0)
        return R[..., 2] + np.reshape(offset, np.shape(offset) + (1,) * extra)
    extra = R.ndim - np.ndim(arm)
    a = np.reshape(arm, np.shape(arm)[:-1] + (1,) * extra + (2,))
    o = np.reshape(offset, np.shape(offset) + (1,) * extra)
    return a[..., 0] * R[..., 1] - a[..., 1] * R[..., 0] + o


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
class EndBlock:
    """A stiff block at one end of a link (bearing housing, clamp): ``length_m`` along the link
    from the joint, its own section and material. It is one segment of the link's mesh."""

    length_m: float
    section: Section
    material: Material

    def __post_init__(self):
        if not (np.isfinite(self.length_m) and self.length_m > 0):
            raise InputError(f"end block length_m must be positive and finite, got {self.length_m!r}")


@dataclass(frozen=True)
class Link:
    """A straight link: length [m], section and material of its span, number of TMM segments of
    the span, optional end blocks, and its mass model (distributed mass from the densities, plus
    point masses), damping and an optional viscoelastic law (span only) for the time domain.

    ``rigid``: the link does not deform. Its mesh still lumps its mass (for drawing and the
    reflected inertia), but it has no elastic degrees of freedom: a rigid crank is welded to its
    clamped pivot, so its far joint is a fixed pin of the instantaneous structure and its own
    inertia goes straight into the drive torque (:meth:`FourBarMechanism.drive_torque`). Only the
    crank may be rigid in the transfer-matrix model; damping or a viscoelastic law on a rigid link
    is refused (it would be ignored)."""

    name: str
    length_m: float
    section: Section
    material: Material
    n_segments: int = 8
    point_masses: tuple = ()
    damping: Damping = Damping()
    viscoelastic: StandardLinearSolid | None = None
    start_block: EndBlock | None = None
    end_block: EndBlock | None = None
    rigid: bool = False

    def __post_init__(self):
        if self.rigid and (self.damping.stiffness_s > 0 or self.damping.mass_per_s > 0):
            raise InputError(f"link '{self.name}': a rigid link has no elastic motion to damp; remove its damping")
        if self.rigid and self.viscoelastic is not None:
            raise InputError(f"link '{self.name}': a rigid link cannot be viscoelastic")
        if self.viscoelastic is not None and not np.isclose(self.material.E_Pa,
                                                           self.viscoelastic.instantaneous_modulus_Pa, rtol=1e-9):
            raise InputError(f"link '{self.name}': material E_Pa ({self.material.E_Pa:.6g}) must equal the "
                             f"viscoelastic instantaneous_modulus_Pa ({self.viscoelastic.instantaneous_modulus_Pa:.6g}): "
                             "quasi-static and frequency analyses use the instantaneous modulus")
        if int(self.n_segments) != self.n_segments or self.n_segments < 1:
            raise InputError(f"link '{self.name}': n_segments must be a positive integer, got {self.n_segments!r}")
        blocks = sum(b.length_m for b in (self.start_block, self.end_block) if b is not None)
        if not (np.isfinite(self.length_m) and self.length_m > blocks):
            raise InputError(f"link '{self.name}': length_m ({self.length_m!r}) must be positive and longer than its "
                             f"end blocks ({blocks:.6g} m)")

    @property
    def _layout(self):
        """(lengths, sections, materials, flexible) of all segments, start joint first."""
        span = self.length_m - sum(b.length_m for b in (self.start_block, self.end_block) if b is not None)
        n = int(self.n_segments)
        L = [span / n] * n
        secs, mats, flex = [self.section] * n, [self.material] * n, [True] * n
        if self.start_block is not None:
            b = self.start_block
            L, secs, mats, flex = [b.length_m] + L, [b.section] + secs, [b.material] + mats, [False] + flex
        if self.end_block is not None:
            b = self.end_block
            L, secs, mats, flex = L + [b.length_m], secs + [b.section], mats + [b.material], flex + [False]
        return tuple(L), tuple(secs), tuple(mats), np.array(flex)

    @property
    def total_segments(self) -> int:
        """Segments of the mesh: the span's plus one per end block."""
        return len(self._layout[0])

    @property
    def n_nodes(self) -> int:
        return self.total_segments + 1

    @property
    def flexible(self) -> np.ndarray:
        """Per segment: True for the span, False for end blocks."""
        return self._layout[3]

    def member(self, start: str, end: str, **kw) -> Member:
        L, secs, mats, _ = self._layout
        return Member(self.name, start, end, L, secs, mats, **kw)

    @property
    def stations(self) -> np.ndarray:
        return np.concatenate([[0.0], np.cumsum(self._layout[0])])

    def segment_mass_per_length(self) -> np.ndarray:
        """rho * A of every segment [kg/m]."""
        _, secs, mats, _ = self._layout
        return np.array([m.density_kg_m3 * s.area_m2 for s, m in zip(secs, mats)])

    def distributed_node_masses(self) -> np.ndarray:
        """The distributed mass lumped half a segment to each side (Shin), shape (n_nodes,)."""
        seg = self.segment_mass_per_length() * np.asarray(self._layout[0])
        m = np.zeros(self.n_nodes)
        m[:-1] += 0.5 * seg
        m[1:] += 0.5 * seg
        return m

    def rigid_body(self):
        """Exact rigid-body mass properties ``(mass [kg], centre of mass x [m] from the start
        joint, z inertia about the centre of mass [kg m^2])``: every mesh segment (span and end
        blocks) as a uniform rod (m = rho A h, I = m h^2 / 12), plus the point masses with their
        own rotary inertia."""
        x = self.stations
        h = np.diff(x)
        m = np.concatenate([self.segment_mass_per_length() * h, [p.mass_kg for p in self.point_masses]])
        xc = np.concatenate([0.5 * (x[1:] + x[:-1]), [p.position_m for p in self.point_masses]])
        Jc = np.concatenate([m[:len(h)] * h**2 / 12.0, [p.inertia_kg_m2 for p in self.point_masses]])
        mass = float(m.sum())
        if not mass > 0:
            raise InputError(f"link '{self.name}' has no mass")
        com = float(m @ xc / mass)
        return mass, com, float(Jc.sum() + m @ (xc - com) ** 2)

    def node_masses(self):
        """Lumped mass [kg] and rotary inertia [kg m^2] at each node, shape (n_nodes,) each.

        The distributed mass is lumped half a segment to each side (Shin); the rotary inertia of
        the strip itself is neglected (Euler-Bernoulli). Point masses must sit on a node.
        """
        m = self.distributed_node_masses()
        J = np.zeros(self.n_nodes)
        x = self.stations
        for pm in self.point_masses:
            j = int(np.argmin(np.abs(x - pm.position_m)))
            if abs(x[j] - pm.position_m) > 1e-9 * self.length_m:
                raise InputError(f"link '{self.name}': point mass '{pm.label}' at {pm.position_m:.6g} m is not at a "
                                 f"node of the mesh (nodes at {np.round(x, 6).tolist()} m)")
            m[j] += pm.mass_kg
            J[j] += pm.inertia_kg_m2
        return m, J


class LinkageMethods:
    """What every moving single-loop linkage shares (four-bar, slider-crank): loads, load cases,
    self-weight and the rigid linkage's reflected inertia at the crank."""

    def external_loads(self, motion):
        """Applied loads besides inertia and gravity: none on a bare linkage."""
        return {}

    def elastic_links(self):
        """The links that deform: the members of the instantaneous structure, in its order."""
        return tuple(link for link in self.links() if not link.rigid)

    def _check_rigid(self):
        for link in self.links()[1:]:
            if link.rigid:
                raise InputError(f"link '{link.name}': only the crank can be rigid in the transfer-matrix model (it is "
                                 "welded to its clamped pivot, so its far joint becomes a fixed pin)")

    def rigid_link_moment(self, link, motion, gravity=None, about=None):
        """Moment [N m] about the point ``about`` ((..., 2), default the link's start joint) of a
        rigid link's D'Alembert loads and weight: ``-J_G alpha + m (r_G - P) x (g - a_G)``,
        exact rigid-body mass properties (:meth:`Link.rigid_body`)."""
        m, xc, Jc = link.rigid_body()
        lm = motion.link(link.name)
        rG, _, aG = lm.point(xc)
        P = lm.origin if about is None else about
        g = np.zeros(2) if gravity is None else np.asarray(gravity, dtype=float)
        d, f = rG - P, m * (g - aG)
        return -Jc * lm.alpha + d[..., 0] * f[..., 1] - d[..., 1] * f[..., 0]

    def drive_torque_terms(self, motion, gravity=None):
        """How the drive torque follows from the support reactions of the instantaneous
        structure: ``(joint, arm, offset)``. With an elastic crank the torque is the clamp moment
        at A (``arm`` None, ``offset`` 0). With a rigid crank it balances the crank: the moment of
        the pin reaction at B (the force the crank applies to the coupler) about A plus the
        crank's own D'Alembert loads and weight, ``T = arm x R_B + offset`` with ``arm = r_B - r_A``
        ((..., 2) [m]) and ``offset = -M_A`` ((...,) [N m])."""
        if not self.crank.rigid:
            return "A", None, 0.0
        return "B", motion.B - motion.A, -self.rigid_link_moment(self.crank, motion, gravity)

    def drive_torque(self, reactions, motion, gravity=None):
        """Drive torque [N m, CCW +]: the moment the drive applies to the crank at its pivot, from
        the support reactions ``{joint: (..., 3)}`` (see :meth:`drive_torque_terms`)."""
        return torque_from_terms(reactions, *self.drive_torque_terms(motion, gravity))

    def load_case(self, motion: FourBarMotion, node_loads=None, distributed_loads=None,
                  node_stiffness=None) -> LoadCase:
        """Load case at the positions of ``motion``; loads are ``{link: array}`` as in :class:`LoadCase`."""
        return LoadCase(self.joint_positions(motion), dict(node_loads or {}), dict(distributed_loads or {}),
                        dict(node_stiffness or {}))

    def crank_inertia(self, crank_angle, gravity=None, lumped: bool = False):
        """Rigid linkage seen at the crank (equivalent-inertia form of its equation of motion,
        ``J(q) q'' + J'(q) q'^2 / 2 - Q_g(q) = T_drive``), at crank angles ``q`` [rad] (array):
        ``(J [kg m^2], dJ/dq [kg m^2/rad], Q_g [N m])``. J is twice the kinetic energy at unit
        crank speed; Q_g is the generalized gravity force (CCW positive) for ``gravity`` [m/s^2].
        ``lumped``: the transfer-matrix mass model (node masses and rotary inertias,
        :meth:`Link.node_masses`) instead of the exact distributed mass."""
        q = np.atleast_1d(np.asarray(crank_angle, dtype=float))
        mo = self.motion(q, 1.0, 0.0)   # at unit speed and zero crank acceleration: v = dr/dq, a = dv/dq
        J = np.zeros(q.shape)
        dJ = np.zeros(q.shape)
        Qg = np.zeros(q.shape)
        g = np.zeros(2) if gravity is None else np.asarray(gravity, dtype=float)
        for link in self.links():
            if lumped and not link.rigid:
                m, Jc = link.node_masses()
                xc = link.stations
            else:
                m, xc, Jc = link.rigid_body()
                m, xc, Jc = np.array([m]), np.array([xc]), np.array([Jc])
            lm = mo.link(link.name)
            _, v, a = lm.point(xc)
            w, al = lm.omega[..., None], lm.alpha[..., None]
            J += np.sum(m * np.sum(v * v, -1) + Jc * w**2, -1)
            dJ += 2.0 * np.sum(m * np.sum(v * a, -1) + Jc * w * al, -1)
            Qg += np.sum(m * (v @ g), -1)
        return J, dJ, Qg

    def gravity_loads(self, g=(0.0, -9.80665)):
        """Distributed self-weight ``{link: (n, 2)}`` [N/m] for gravity vector ``g`` [m/s^2]."""
        out = {}
        for link in self.links():
            out[link.name] = link.segment_mass_per_length()[:, None] * np.asarray(g, dtype=float)
        return out


@dataclass(frozen=True)
class FourBarMechanism(LinkageMethods):
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
        """Instantaneous structure: A clamped (crank welded), B and C revolutes, D pinned. With a
        rigid crank, B is a fixed pin and the crank is no member."""
        self._check_rigid()
        if self.crank.rigid:
            return Structure((Joint("B", "pinned"), Joint("C"), Joint("D", "pinned")),
                             (self.coupler.member("B", "C"), self.rocker.member("D", "C")))
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

@dataclass(frozen=True)
class SliderCrankMechanism(LinkageMethods):
    """Slider-crank with a flexible crank and coupler. The slide runs through the line at
    ``offset_m`` from the crank pivot, in the direction ``ground_angle`` [rad]; the crank angle is
    measured from the slide direction. The slider block (``slider_mass_kg``) translates with the
    coupler's end C; it is carried as a point mass at the coupler's last node (it does not
    rotate, and a point mass has no rotary inertia, so the two are the same).

    Instantaneous structure (Shin §5.4, with its inconsistent support conditions resolved): A
    clamped (the crank carries the drive torque), B a revolute, C a *pinned slider block* on a
    frictionless guide -- displacement normal to the slide zero, force along the slide zero,
    moment zero. Shin's Eq. 5.23 instead fixes the rotation at D (a sliding clamp), which would
    weld the coupler to the block; a block on a pin is the physical joint.
    """

    crank: Link
    coupler: Link
    offset_m: float = 0.0
    pivot: tuple = (0.0, 0.0)
    ground_angle: float = 0.0
    branch: int = 1
    slider_mass_kg: float = 0.0

    def __post_init__(self):
        for name, link in (("crank", self.crank), ("coupler", self.coupler)):
            if link.name != name:
                raise InputError(f"slider-crank: the {name} link must be named '{name}', got '{link.name}'")
        require_nonnegative("slider-crank slider_mass_kg", self.slider_mass_kg)

    @property
    def geometry(self) -> SliderCrankGeometry:
        return SliderCrankGeometry(self.crank.length_m, self.coupler.length_m, self.offset_m, self.pivot,
                                   self.ground_angle, self.branch)

    def links(self):
        coupler = self.coupler
        if self.slider_mass_kg > 0:
            import dataclasses
            coupler = dataclasses.replace(coupler, point_masses=tuple(coupler.point_masses) + (
                PointMass(coupler.length_m, self.slider_mass_kg, 0.0, "slider block"),))
        return (self.crank, coupler)

    def structure(self) -> Structure:
        self._check_rigid()
        crank, coupler = self.links()
        if crank.rigid:
            return Structure((Joint("B", "pinned"), Joint("C", "slider", self.ground_angle)),
                             (coupler.member("B", "C"),))
        joints = (Joint("A", "clamped"), Joint("B"), Joint("C", "slider", self.ground_angle))
        return Structure(joints, (crank.member("A", "B", start_connection="rigid"), coupler.member("B", "C")))

    def motion(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0) -> SliderCrankMotion:
        return slider_crank_motion(self.geometry, crank_angle, crank_speed, crank_acceleration)

    drive_joint = "A"

    def joint_positions(self, motion: SliderCrankMotion):
        return {"A": motion.A, "B": motion.B, "C": motion.C}


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

    def elastic_links(self):
        return self.links()

    def drive_torque_terms(self, motion, gravity=None):
        """The reaction moment at ``drive_joint`` (see FourBarMechanism.drive_torque_terms)."""
        return self.drive_joint, None, 0.0

    def drive_torque(self, reactions, motion, gravity=None):
        """The reaction moment at ``drive_joint`` [N m]."""
        return reactions[self.drive_joint][..., 2]

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
