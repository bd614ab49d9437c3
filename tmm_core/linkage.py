"""General planar linkages: the mechanism behind every engine (kinematics by modules:
:mod:`tmm_core.linkage_kinematics`, whose names are re-exported here).

Mechanism (:class:`LinkageMechanism`): the flexible links (members, each a straight part of a
link between two joints), rigid plates, slider blocks, springs and constant loads, with the
protocol the transfer-matrix time domain uses (``links``, ``elastic_links``, ``structure``,
``motion``, ``joint_positions``, ``drive_torque_terms``, ``external_loads``, ``crank_inertia``).
Its instantaneous structure is Shin's: the crank clamped at its ground pivot (a rigid crank is
welded there, so its far joint is a fixed pin), revolutes elsewhere unless a link is welded, ground
pivots pinned, ground slides as ``slider`` supports (``sliding_clamp`` where links are welded to
the block: they slide without turning), plates as :class:`RigidBody`, blocks on a moving guide as
:class:`SliderJoint`. A plate's mass and rotary inertia sit on a strain-free
*carrier* member from its centre of mass (the plate's master joint) to its first vertex, welded to
the master: Shin's rigid element 9->3 carrying the plate's lumped mass, so the plate's inertia
enters the time domain exactly.

:func:`as_linkage` gives the same description of a :class:`FourBarMechanism` or
:class:`SliderCrankMechanism`, so the exudyn and MuJoCo engines build every mechanism from one
description.

Owns: ``LinkageMechanism`` and ``as_linkage``. Boundaries: the kinematics are
tmm_core.linkage_kinematics.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .errors import InputError
from .mechanism import (FourBarMechanism, Link, PointMass, SliderCrankMechanism, LinkageMethods,
                        torque_from_terms)
from .sections import Material, Section
from .structure import Joint, LoadCase, RigidBody, SliderJoint, Structure
from .linkage_kinematics import (LOCK_TOLERANCE, MODULE_KINDS, MODULE_LINKS, SHIN_TYPES, SINGLE_ASSEMBLY,  # noqa: F401
                                 BodyMotion, LinkageKinematics, LinkageMotion, LinkageState, Module)
from .plane import angle as _angle, dot as _dot


@dataclass(frozen=True)
class Plate:
    """A rigid plate: vertices, the master joint at its centre of mass, mass [kg] and rotary
    inertia about the centre of mass [kg m^2]; ``carrier`` names the strain-free member that
    carries them (the plate's own link in :meth:`LinkageMechanism.links`)."""

    name: str
    vertices: tuple
    master: str
    mass_kg: float
    inertia_kg_m2: float
    carrier: str


@dataclass(frozen=True)
class GuidedSlider:
    """A block at joint ``block`` sliding along the member ``along`` of a moving guide link, guided
    at the guide link's joint ``guide`` (a fixed station of the guide: the block rides the guide's
    tangent there, see :class:`tmm_core.structure.SliderJoint`)."""

    name: str
    block: str
    guide: str
    along: str


@dataclass(frozen=True)
class LinkageMechanism(LinkageMethods):
    """A general planar linkage with flexible links (see the module docstring).

    kinematics : :class:`LinkageKinematics` (bodies, modules, the crank).
    members : ``(Link, start joint, end joint, start connection, end connection)`` for every link
        part (a straight piece of a link between two joints), plates' carriers included, in the
        order of the instantaneous structure. Connections: 'pin' (revolute) or 'rigid' (welded).
    frames : ``{link: body}``: the kinematic body each member belongs to.
    supports : ``{joint: 'pinned' | 'slider'}`` of the ground joints (slider: along
        ``kinematics.ground_slides``; a slider whose block carries welded links, a body of
        ``kinematics.sliding_blocks``, is a ``sliding_clamp`` in the instantaneous structure); the
        crank pivot is clamped in the instantaneous structure.
    plates, sliders, springs : :class:`Plate`, :class:`GuidedSlider`, :class:`Spring` s.
    loads : ``{link: (n+1, 3)}`` constant applied loads (global Fx, Fy, Mz) at the member nodes.
    """

    kinematics: LinkageKinematics
    members: tuple
    frames: Mapping[str, str]
    supports: Mapping[str, str]
    plates: tuple = ()
    sliders: tuple = ()
    springs: tuple = ()
    loads: Mapping[str, np.ndarray] = field(default_factory=dict)
    name: str = "linkage"

    def __post_init__(self):
        names = [m[0].name for m in self.members]
        if len(set(names)) != len(names):
            raise InputError(f"{self.name}: duplicate link names {names}")
        kin = self.kinematics
        frames = {}
        for link, a, b, ca, cb in self.members:
            body = self.frames.get(link.name)
            if body is None or body not in kin.bodies:
                raise InputError(f"{self.name}: link '{link.name}' belongs to no body")
            for j in (a, b):
                if j not in kin.bodies[body]:
                    raise InputError(f"{self.name}: link '{link.name}': joint '{j}' is not on its body '{body}'")
            d = kin.reference_position(b) - kin.reference_position(a)
            L = float(np.hypot(*d))
            if abs(L - link.length_m) > 1e-9 * max(L, 1.0):
                raise InputError(f"{self.name}: link '{link.name}' is {link.length_m:.9g} m long but its joints "
                                 f"'{a}' and '{b}' are {L:.9g} m apart")
            # The link's local x axis, from its start joint to its end joint, in the reference.
            frames[link.name] = (body, a, b, float(_angle(d)))
        object.__setattr__(self, "_frames", frames)
        crank = self.crank
        rigid = [l.name for l in self.links() if l.rigid and l is not crank]
        if rigid:
            raise InputError(f"{self.name}: link(s) {rigid}: only the crank can be rigid in the transfer-matrix model "
                             "(it is welded to its clamped pivot, so its far joint becomes a fixed pin)")
        if crank.rigid and len(kin.bodies[kin.crank]) != 2:
            raise InputError(f"{self.name}: a rigid crank must be a binary link (pivot and tip)")

    # -- topology ------------------------------------------------------------------------------
    def links(self):
        return tuple(m[0] for m in self.members)

    @property
    def crank(self) -> Link:
        """The crank's member from its pivot (the driven link)."""
        kin = self.kinematics
        for link, a, b, _, _ in self.members:
            if self.frames[link.name] == kin.crank and a == kin.pivot:
                return link
        raise InputError(f"{self.name}: no member of the crank '{kin.crank}' starts at its pivot '{kin.pivot}'")

    @property
    def drive_joint(self) -> str:
        return self.kinematics.pivot

    @property
    def pivot(self) -> tuple:
        return tuple(float(x) for x in self.kinematics.reference_position(self.kinematics.pivot))

    @property
    def ground_angle(self) -> float:
        """The direction the crank angle is measured from [rad]."""
        return self.kinematics.crank_zero

    def member_ends(self, name: str) -> tuple:
        """(start joint, end joint, start connection, end connection) of a member."""
        for link, a, b, ca, cb in self.members:
            if link.name == name:
                return a, b, ca, cb
        raise InputError(f"{self.name}: unknown link '{name}'")

    def joint_support(self, joint: str) -> str:
        """'free', 'pinned' or 'slider' (the crank pivot is 'pinned' here; the instantaneous
        structure clamps it)."""
        return self.supports.get(joint, "free")

    def structure(self) -> Structure:
        kin = self.kinematics
        crank = self.crank
        pins = set(kin.bodies[kin.crank]) - {kin.pivot} if crank.rigid else set()
        members = [link.member(a, b, start_connection=ca, end_connection=cb)
                   for link, a, b, ca, cb in self.members if not link.rigid]
        used = {m.start for m in members} | {m.end for m in members} | {s.a for s in self.springs} | \
            {s.b for s in self.springs}
        for p in self.plates:
            used |= {p.master, *p.vertices}
        for s in self.sliders:
            used |= {s.block, s.guide}
        joints = []
        clamps = kin.sliding_blocks
        for j in kin.joint_names:
            if j not in used:
                continue
            if j == kin.pivot and not crank.rigid:
                joints.append(Joint(j, "clamped"))
            elif j in pins:
                joints.append(Joint(j, "pinned"))
            elif self.supports.get(j) == "slider":
                # A block carrying welded links slides without turning: the links keep their angle.
                joints.append(Joint(j, "sliding_clamp" if j in clamps else "slider", kin.ground_slides[j]))
            elif self.supports.get(j) == "pinned":
                joints.append(Joint(j, "pinned"))
            else:
                joints.append(Joint(j))
        return Structure(tuple(joints), tuple(members), tuple(self.springs),
                         tuple(RigidBody(p.name, p.master, tuple(p.vertices)) for p in self.plates),
                         tuple(SliderJoint(s.name, s.block, s.guide, s.along) for s in self.sliders))

    # -- motion --------------------------------------------------------------------------------
    def motion(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0) -> LinkageMotion:
        return LinkageMotion(self.kinematics.solve(crank_angle, crank_speed, crank_acceleration), self._frames)

    def joint_positions(self, motion: LinkageMotion):
        return {j: v[0] for j, v in motion.state.joints.items()}

    def external_loads(self, motion):
        shape = np.shape(motion.state.crank_angle)
        return {k: np.broadcast_to(np.asarray(v, dtype=float), shape + np.shape(v)) for k, v in self.loads.items()}

    def drive_torque_terms(self, motion, gravity=None):
        """Elastic crank: the clamp moment at the pivot. Rigid crank: the moment about the pivot
        of the pin reaction at its tip plus the crank's own D'Alembert loads and weight (see
        :meth:`FourBarMechanism.drive_torque_terms`)."""
        kin = self.kinematics
        crank = self.crank
        if not crank.rigid:
            return kin.pivot, None, 0.0
        tip = self.member_ends(crank.name)[1]
        return tip, motion.position(tip) - motion.position(kin.pivot), -self.rigid_link_moment(crank, motion, gravity)

    def drive_torque(self, reactions, motion, gravity=None):
        return torque_from_terms(reactions, *self.drive_torque_terms(motion, gravity))

    def load_case(self, motion, node_loads=None, distributed_loads=None, node_stiffness=None) -> LoadCase:
        return LoadCase(self.joint_positions(motion), dict(node_loads or {}), dict(distributed_loads or {}),
                        dict(node_stiffness or {}))

    def applied_generalized_force(self, crank_angle) -> np.ndarray:
        """Generalized force at the crank [N m] of the springs and the constant loads, at crank
        angles ``q`` (virtual power with unit crank speed: ``sum F . dr/dq + M dphi/dq``)."""
        q = np.atleast_1d(np.asarray(crank_angle, dtype=float))
        mo = self.motion(q, 1.0, 0.0)
        Q = np.zeros(q.shape)
        for name, F in self.loads.items():
            link = next(l for l in self.links() if l.name == name)
            lm = mo.link(name)
            _, v, _ = lm.point(link.stations)
            Q += np.sum(v * F[:, :2], axis=(-1, -2)) + lm.omega * np.sum(F[:, 2])
        for sp in self.springs:
            (pa, va, _), (pb, vb, _) = mo.joint(sp.a), mo.joint(sp.b)
            d = pb - pa
            L = np.hypot(d[..., 0], d[..., 1])
            Q -= sp.k * (L - sp.free_length) * _dot(d, vb - va) / L
        return Q


# --------------------------------------------------------------------------------------------
def as_linkage(mech) -> LinkageMechanism:
    """The :class:`LinkageMechanism` of any mechanism the bench runs: a linkage itself, or the
    same four-bar / slider-crank (same links, names and branch; crank angle from its ground line)."""
    if isinstance(mech, LinkageMechanism):
        return mech
    if isinstance(mech, FourBarMechanism):
        mo = mech.motion(0.0)
        ref = {k: np.asarray(v, float) for k, v in mech.joint_positions(mo).items()}
        kin = LinkageKinematics(ref, {"crank": ("A", "B"), "coupler": ("B", "C"), "rocker": ("D", "C")}, ("A", "D"),
                                "crank", "A", "B",
                                (Module("crank", "B", ("crank",)),
                                 Module("rrr", "C", ("coupler", "rocker"), mech.branch)),
                                crank_zero=mech.ground_angle, name="four-bar")
        links = mech.links()
        members = ((links[0], "A", "B", "rigid", "pin"), (links[1], "B", "C", "pin", "pin"),
                   (links[2], "D", "C", "pin", "pin"))
        return LinkageMechanism(kin, members, {"crank": "crank", "coupler": "coupler", "rocker": "rocker"},
                                {"A": "pinned", "D": "pinned"}, name="four-bar")
    if isinstance(mech, SliderCrankMechanism):
        mo = mech.motion(0.0)
        ref = {k: np.asarray(v, float) for k, v in mech.joint_positions(mo).items()}
        kin = LinkageKinematics(ref, {"crank": ("A", "B"), "coupler": ("B", "C")}, ("A",), "crank", "A", "B",
                                (Module("crank", "B", ("crank",)), Module("rrp", "C", ("coupler",), mech.branch)),
                                crank_zero=mech.ground_angle, ground_slides={"C": mech.ground_angle},
                                name="slider-crank")
        links = mech.links()
        members = ((links[0], "A", "B", "rigid", "pin"), (links[1], "B", "C", "pin", "pin"))
        return LinkageMechanism(kin, members, {"crank": "crank", "coupler": "coupler"},
                                {"A": "pinned", "C": "slider"}, name="slider-crank")
    raise InputError(f"no linkage description of a {type(mech).__name__}")


def polygon_properties(points, thickness_m: float, density_kg_m3: float):
    """Mass [kg], centre of mass (2,) [m] and z inertia about it [kg m^2] of a uniform plate
    over the polygon ``points`` (k, 2), in order around it."""
    p = np.asarray(points, dtype=float)
    q = np.roll(p, -1, axis=0)
    cr = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    area = 0.5 * cr.sum()
    if abs(area) <= 0:
        raise InputError("plate: its vertices enclose no area")
    c = np.array([((p[:, 0] + q[:, 0]) * cr).sum(), ((p[:, 1] + q[:, 1]) * cr).sum()]) / (6.0 * area)
    # Second moments about the origin, then shifted to the centroid.
    Ixx = ((p[:, 1]**2 + p[:, 1] * q[:, 1] + q[:, 1]**2) * cr).sum() / 12.0
    Iyy = ((p[:, 0]**2 + p[:, 0] * q[:, 0] + q[:, 0]**2) * cr).sum() / 12.0
    rho_t = density_kg_m3 * thickness_m
    mass = rho_t * abs(area)
    J0 = rho_t * abs(Ixx + Iyy)
    return mass, c, J0 - mass * float(c @ c)


#: A plate's carrier is this much softer than the links it is scaled from (see :func:`carrier_link`).
CARRIER_SOFTNESS = 1e-6


def carrier_link(name: str, length_m: float, section: Section, mass_kg: float, inertia_kg_m2: float,
                 E_Pa: float) -> Link:
    """The strain-free member that carries a plate's mass and rotary inertia at its start node (the
    plate's centre of mass), one segment, massless itself. Both its ends move with the plate
    (the rigid-body constraint), so it needs no stiffness of its own: its modulus is
    ``CARRIER_SOFTNESS`` times ``E_Pa``. A stiff carrier would pick up the fictitious strain that
    the time step's second-order terms (strain u' + w'^2/2) read from the plate's linearized
    elastic rotation theta (theta^2 / 2, 2.6 kN in a steel bar at 0.0125 rad) and feed it back
    as a moment on the plate."""
    return Link(name, length_m, section, Material(f"{name} (plate carrier)", CARRIER_SOFTNESS * E_Pa, 0.0), 1,
                (PointMass(0.0, mass_kg, inertia_kg_m2, f"plate {name}"),))
