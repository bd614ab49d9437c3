"""General planar linkages: closed-form kinematics by modules, and the mechanism behind every engine.

Kinematics (Shin 1986, Ch. 2 and App. A, the component-module approach; notes seed000 §4). A
linkage is a set of rigid *bodies* (each a list of joints that keep their relative positions: a
straight link through its path of joints, a plate through its vertices, a slider block with the
links welded to it), joined at joints, and described at one assembled *reference* configuration
(joint coordinates). Its motion is solved, for any crank angle, by an ordered list of closed-form
modules; each closes one loop from joints already known and fixes the bodies that meet there. The
modules are the five planar dyads with lower pairs (R revolute, P prismatic: RRR, RRP, RPR, PRP,
RPP; PPR is RPP seen from its other end, PPP does not fix a position) behind the input link:

=========  =========================================================================================
``crank``  Shin type 1, the input link: the driven body turns about its ground pivot by the crank
           angle (measured from the global direction ``crank_zero``).
``rrr``    Shin type 2, the RRR dyad: joint C shared by two bodies, each with one known joint (P,
           Q): the intersection of two circles; branch = the side of P->Q on which C lies.
``rrp``    Shin types 3, 5, 6, the RRP dyad: joint C of a body with one known joint P, sliding on
           a line, either fixed to the ground (a joint with a ``slider`` support, or a block
           sliding along the ground with links welded to it) or carried by a guide body placed
           before (C belongs to a block body that slides along the guide and turns with it; type 5
           with C on an arm of the block, type 6 with C at the block); branch = the sign of
           (C - P) along the slide.
``rpr``    Shin types 7 and 8, the RPR dyad (inverted slider-crank): a block body with one known
           joint P slides along a guide body that turns about its one known joint Q; the two turn
           together. With u = P - Q and the slide direction e in the reference, P - Q = R(phi)
           (u + s e): s from |u + s e| = |P - Q| (a quadratic: two branches, the sign of the
           component of P - Q along the slide), phi from the directions. Type 8: the block pinned
           at P (Shin's "slider input": P placed by an earlier module, e.g. an rrp's slider).
           Type 7: the block carries a link that ends at P (and the slide line may pass off the
           pivot): P moves in the guide's frame along the line through its reference position
           parallel to the slide, so type 7 is type 8 on that line followed by type 4 for the
           block's other joints; the module solves both at once.
``prp``    The PRP dyad: joint C on two slides (its ``slider`` support, and blocks through C
           sliding along the ground or along guides placed before): the intersection of two lines,
           one assembly. The blocks are posed by the module (they turn with their guides).
``rpp``    The RPP dyad (Scotch yoke): a block body with one known joint P slides along a body
           ``mid`` that itself slides along the ground or a placed guide; both keep the guide's
           rotation, and the two slides follow from a linear 2x2 system (one assembly).
=========  =========================================================================================

Shin's type 4 (a further point of a body whose pose is known: "solid link") is applied
automatically: a module fixes whole bodies, and every joint of a body follows from its pose.
:data:`SHIN_TYPES` maps each of Shin's eight types to its module. Branches default to the
reference configuration's, so a linkage drawn assembled moves on the branch it is drawn in.
Velocities and accelerations come from the differentiated closure relations of each module
(linear 2x2 systems), exactly; the tests check them against finite differences. A module that
cannot assemble (a dyad beyond its stretched or folded limit, a link too short to reach its slide
line, a joint closer to a guide's pivot than the guide's slide line passes) or that locks (the two
links of a dyad collinear, a link perpendicular to its slide, the line from a guide's pivot square
to its slide, two slides parallel) raises :class:`tmm_core.errors.AssemblyError` naming the module
and the crank angle.

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
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .errors import AssemblyError, InputError, require_finite
from .kinematics import LinkMotion
from .mechanism import (FourBarMechanism, Link, PointMass, SliderCrankMechanism, _LinkageMethods,
                        torque_from_terms)
from .sections import Material, Section
from .structure import Joint, LoadCase, RigidBody, SliderJoint, Structure

MODULE_KINDS = ("crank", "rrr", "rrp", "rpr", "prp", "rpp")
#: The number of links each kind of module names (a prp names none: its slides are its joint's).
MODULE_LINKS = {"crank": 1, "rrr": 2, "rrp": 1, "rpr": 2, "prp": 0, "rpp": 2}
#: Kinds with one assembly (a closure linear in its unknowns, or the crank): no branch.
SINGLE_ASSEMBLY = ("crank", "prp", "rpp")
#: Shin's eight component types (1986, Fig. 2.1 and App. A) and the module that solves each;
#: type 4 needs none (every joint of a posed body follows from its pose).
SHIN_TYPES = {
    1: ("crank", "input link: the crank's tip from its pivot and the crank angle"),
    2: ("rrr", "dyad: two links meeting at a revolute, each with one known joint"),
    3: ("rrp", "sliding end: a link's joint on a ground slide"),
    4: (None, "solid link: further joints of a posed body (automatic)"),
    5: ("rrp", "slider dyad / oscillating slider: a link's joint on an arm of a block sliding along a moving guide"),
    6: ("rrp", "sliding revolute: a link pinned at a block sliding along a moving guide"),
    7: ("rpr", "slider and follower: a block carrying a link to a known joint, sliding along a follower turning "
               "about a known pivot (the slide line offset from the pivot): type 8 on the line the known joint "
               "traces in the follower, then type 4"),
    8: ("rpr", "sliding revolute and follower: a block pinned at a known joint (Shin's slider input) sliding along "
               "a follower turning about a known pivot"),
}
#: A module is reported locked where the sine of the angle of its toggle falls below this: between
#: a dyad's two links (rrr), between a link and its slide's normal (rrp), between the line from
#: the known joint to the pivot and the guide's normal (rpr), between two slides (prp, rpp); an rpr
#: also locks where its joint comes within this fraction of its reference distance of the pivot.
LOCK_TOLERANCE = 1e-9


def _perp(v):
    return np.stack([-v[..., 1], v[..., 0]], -1)


def _cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a, b):
    return np.sum(a * b, -1)


def _rot(v, angle):
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    return np.concatenate([c * v[..., :1] - s * v[..., 1:], s * v[..., :1] + c * v[..., 1:]], -1)


def _angle(v):
    return np.arctan2(v[..., 1], v[..., 0])


def _asin_deg(x) -> float:
    x = float(x)
    return math.degrees(math.asin(min(1.0, abs(x)))) if math.isfinite(x) else 0.0


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


@dataclass(frozen=True)
class Module:
    """One closed-form step: ``kind`` (one of :data:`MODULE_KINDS`), its ``joint``, the bodies it
    poses (``links``) and the assembly ``branch`` (+1/-1; 0 = the reference configuration's).

    crank: ``joint`` the crank's tip, ``links`` (crank,). rrr: ``joint`` the revolute it places,
    ``links`` the dyad's two bodies. rrp: ``joint`` the joint it places on a slide, ``links`` (the
    link with its known joint,). rpr: ``joint`` the known joint of the block, ``links`` (block,
    guide). prp: ``joint`` the joint it places on two slides, no ``links`` (its blocks are the
    sliding bodies at the joint). rpp: ``joint`` the known joint of the block, ``links`` (block,
    the body the block slides along, which itself slides along the ground or a placed guide)."""

    kind: str
    joint: str
    links: tuple = ()
    branch: int = 0

    def __post_init__(self):
        if self.kind not in MODULE_KINDS:
            raise InputError(f"module kind must be one of {MODULE_KINDS}, got {self.kind!r}")
        object.__setattr__(self, "links", tuple(self.links))
        n = MODULE_LINKS[self.kind]
        if len(self.links) != n:
            raise InputError(f"module '{self.kind}' at joint '{self.joint}' needs {n} link(s), got {list(self.links)}"
                             + (" (its slides are the joint's: a slider support, blocks at the joint)"
                                if self.kind == "prp" else ""))
        if self.branch not in (-1, 0, 1):
            raise InputError(f"module '{self.kind}' at joint '{self.joint}': branch must be +1, -1 or 0, got "
                             f"{self.branch!r}")
        if self.branch and self.kind in SINGLE_ASSEMBLY:
            raise InputError(f"module '{self.kind}' at joint '{self.joint}' has a single assembly (its closure is "
                             f"linear): it takes no branch, got {self.branch!r}")

    def label(self, index: int) -> str:
        links = (f", link{'s' if len(self.links) > 1 else ''} {', '.join(repr(b) for b in self.links)}"
                 if self.links else "")
        return f"module {index + 1} ({self.kind} at joint '{self.joint}'{links})"


@dataclass(frozen=True)
class BodyMotion:
    """Pose of a body: its rotation from the reference configuration [rad], angular speed and
    acceleration (arrays over the batch)."""

    rotation: np.ndarray
    omega: np.ndarray
    alpha: np.ndarray


@dataclass(frozen=True)
class LinkageState:
    """Solved kinematics: ``joints[name] = (position, velocity, acceleration)``, each (..., 2);
    ``bodies[name]`` a :class:`BodyMotion`; ``slides[joint] = (s, s_dot, s_ddot)``: the slide of
    an rrp module's joint along its line, or of a prp module's joint along its ground slide, from
    the reference position [m, m/s, m/s^2]; ``block_slides[body]``: the same for every sliding
    body (a block along its guide, a body along the ground)."""

    crank_angle: np.ndarray
    joints: Mapping[str, tuple]
    bodies: Mapping[str, BodyMotion]
    slides: Mapping[str, tuple]
    block_slides: Mapping[str, tuple] = field(default_factory=dict)


@dataclass(frozen=True)
class LinkageKinematics:
    """Closed-form kinematics of a planar linkage (see the module docstring).

    reference : ``{joint: (x, y)}`` [m], an assembled configuration.
    bodies : ``{body: (joint, ...)}``; a joint may belong to several bodies (a revolute).
    ground : joints fixed to the ground.
    crank, pivot, tip : the driven body, its ground pivot and the joint whose direction from the
        pivot is the crank direction; the crank angle is measured from ``crank_zero`` [rad].
    modules : the ordered :class:`Module` s.
    ground_slides : ``{joint: direction [rad]}``: the joint moves on the ground line through its
        reference position.
    guided : ``{block body: (guide body, direction [rad])}``: the block slides along the guide on
        the line through its reference position with that direction at the reference, and turns
        with the guide. Guide ``None``: the block slides along the ground without turning (the
        links welded to a ground slider's block); one of its joints is that ground slide's, in
        ``ground_slides`` with the same direction.
    """

    reference: Mapping[str, tuple]
    bodies: Mapping[str, tuple]
    ground: tuple
    crank: str
    pivot: str
    tip: str
    modules: tuple
    crank_zero: float = 0.0
    ground_slides: Mapping[str, float] = field(default_factory=dict)
    guided: Mapping[str, tuple] = field(default_factory=dict)
    name: str = "linkage"

    def __post_init__(self):
        ref = {k: np.asarray(require_finite(f"{self.name}: joint '{k}' position", v), dtype=float)
               for k, v in self.reference.items()}
        for k, v in ref.items():
            if v.shape != (2,):
                raise InputError(f"{self.name}: joint '{k}' position must have two coordinates, got {v.tolist()}")
        object.__setattr__(self, "_ref", ref)
        object.__setattr__(self, "_steps", self._plan())

    # -- planning ------------------------------------------------------------------------------
    def _plan(self):
        """Check the module order and precompute each step's fixed data; every body must be
        posed by exactly one module and every joint placed."""
        ref, name = self._ref, self.name
        for b, joints in self.bodies.items():
            if len(joints) < 1:
                raise InputError(f"{name}: body '{b}' has no joints")
            for j in joints:
                if j not in ref:
                    raise InputError(f"{name}: body '{b}' refers to joint '{j}', which has no position")
        for j in list(self.ground) + list(self.ground_slides):
            if j not in ref:
                raise InputError(f"{name}: ground joint '{j}' has no position")
        for s, (g, d) in self.guided.items():
            if s not in self.bodies or (g is not None and g not in self.bodies):
                raise InputError(f"{name}: guided body '{s}' or its guide '{g}' is not a body")
            if g == s:
                raise InputError(f"{name}: body '{s}' cannot slide along itself")
            if g is None and not any(j in self.ground_slides and abs(math.sin(self.ground_slides[j] - d)) < 1e-12
                                     for j in self.bodies[s]):
                raise InputError(f"{name}: body '{s}' slides along the ground but none of its joints is a ground "
                                 "slide in that direction (its block)")
        if self.crank not in self.bodies:
            raise InputError(f"{name}: the crank '{self.crank}' is not a link")
        known = set(self.ground)
        posed = set()
        steps = []

        def known_joints(body, exclude=None):
            return [j for j in self.bodies[body] if j in known and j != exclude]

        def known_joint(body, exclude, label):
            ks = known_joints(body, exclude)
            if not ks:
                raise InputError(f"{name}: {label}: link '{body}' has no joint placed yet (place one of "
                                 f"{list(self.bodies[body])} by an earlier module)")
            if len(ks) > 1:
                raise InputError(f"{name}: {label}: link '{body}' already has joints {ks} placed by other links: it is "
                                 "over-constrained (a link placed by a module has exactly one joint known before it)")
            return ks[0]

        def guide_text(g):
            return "the ground" if g is None else f"link '{g}'"

        def pose(body, label, slide=False):
            if body in posed:
                raise InputError(f"{name}: {label}: link '{body}' is already placed by an earlier module")
            if body in self.guided and not slide:
                raise InputError(f"{name}: {label}: link '{body}' slides along {guide_text(self.guided[body][0])}: "
                                 "place it by a module that keeps its slide (rrp, prp, rpr or rpp)")
            posed.add(body)
            known.update(self.bodies[body])

        def slide_lines(C):
            """The slides of joint C not placed yet: (block body or None, guide body or None for
            the ground, direction). A ground slider's block carrying welded links is one slide."""
            out = [(s, g, d) for s, (g, d) in self.guided.items() if C in self.bodies[s] and s not in posed]
            if C in self.ground_slides:
                d = self.ground_slides[C]
                if not any(g is None and abs(math.sin(dd - d)) < 1e-12 for _, g, dd in out):
                    out.append((None, None, d))
            return out

        def describe(lines):
            return ", ".join("its ground slide" if s is None else
                             f"block '{s}' along {guide_text(g)}" for s, g, _ in lines) or "none"

        def fresh(body, label):
            kj = known_joints(body)
            if kj:
                raise InputError(f"{name}: {label}: link '{body}' already has joint(s) {kj} placed by other links: it "
                                 "is over-constrained")

        def block_on(block, guide, label):
            if block not in self.guided or self.guided[block][0] != guide:
                raise InputError(f"{name}: {label}: link '{block}' is not a block sliding along link '{guide}'")
            return self.guided[block][1]

        for i, m in enumerate(self.modules):
            label = m.label(i)
            for b in m.links:
                if b not in self.bodies:
                    raise InputError(f"{name}: {label}: unknown link '{b}' (links: {', '.join(self.bodies)})")
            on = m.links[:1] if m.kind in ("rpr", "rpp") else m.links
            for b in on:
                if m.joint not in self.bodies[b]:
                    raise InputError(f"{name}: {label}: joint '{m.joint}' is not on link '{b}'")
            if m.kind in ("rpr", "rpp"):
                if m.joint not in known:
                    raise InputError(f"{name}: {label}: joint '{m.joint}' is not placed yet (an {m.kind} module "
                                     "moves a block pinned at a joint placed by an earlier module)")
                if m.joint in self.bodies[m.links[1]]:
                    raise InputError(f"{name}: {label}: joint '{m.joint}' is on link '{m.links[1]}' too")
                if m.links[0] == m.links[1]:
                    raise InputError(f"{name}: {label}: the block and its guide must be different links")
            elif m.joint in known:
                raise InputError(f"{name}: {label}: joint '{m.joint}' is already placed by an earlier module")
            elif m.joint not in ref:
                raise InputError(f"{name}: {label}: unknown joint '{m.joint}'")
            if m.kind == "crank":
                if i != 0:
                    raise InputError(f"{name}: {label}: the crank module must come first")
                body = m.links[0]
                if body != self.crank or m.joint != self.tip:
                    raise InputError(f"{name}: {label}: the crank module must place the tip '{self.tip}' of the crank "
                                     f"'{self.crank}'")
                if self.pivot not in self.ground or self.pivot not in self.bodies[body]:
                    raise InputError(f"{name}: {label}: the crank pivot '{self.pivot}' must be a ground joint of "
                                     "the crank")
                d = ref[self.tip] - ref[self.pivot]
                if np.hypot(*d) <= 0:
                    raise InputError(f"{name}: {label}: crank pivot and tip coincide")
                steps.append(dict(kind="crank", label=label, body=body, theta_ref=float(_angle(d))))
                pose(body, label)
            elif m.kind == "rrr":
                b1, b2 = m.links
                if b1 == b2:
                    raise InputError(f"{name}: {label}: the dyad needs two different links")
                P = known_joint(b1, m.joint, label)
                Q = known_joint(b2, m.joint, label)
                C = m.joint
                r1, r2 = (float(np.hypot(*(ref[C] - ref[X]))) for X in (P, Q))
                if r1 <= 0 or r2 <= 0:
                    raise InputError(f"{name}: {label}: joint '{C}' coincides with a known joint")
                side = float(_cross(ref[Q] - ref[P], ref[C] - ref[P]))
                branch = m.branch or (1 if side > 0 else -1 if side < 0 else 0)
                if branch == 0:
                    raise InputError(f"{name}: {label}: joints '{P}', '{Q}' and '{C}' are collinear in the reference "
                                     "configuration (a toggle); give the module a branch")
                steps.append(dict(kind="rrr", label=label, b1=b1, b2=b2, P=P, Q=Q, C=C, r1=r1, r2=r2, branch=branch))
                pose(b1, label)
                pose(b2, label)
            elif m.kind == "rrp":
                b1 = m.links[0]
                C = m.joint
                P = known_joint(b1, C, label)
                lines = slide_lines(C)
                if any(s == b1 for s, _, _ in lines):
                    raise InputError(f"{name}: {label}: the link '{b1}' cannot be its own sliding block")
                ready = [x for x in lines if x[1] is None or x[1] in posed]
                if not ready:
                    waiting = [x for x in lines if x not in ready]
                    if waiting:
                        raise InputError(f"{name}: {label}: the guide '{waiting[0][1]}' of block '{waiting[0][0]}' is "
                                         "not placed yet")
                    raise InputError(f"{name}: {label}: joint '{C}' has no slide (give it a slider support, or put it "
                                     "on a block that slides along a guide)")
                if len(ready) > 1:
                    raise InputError(f"{name}: {label}: joint '{C}' is on two slides ({describe(ready)}): a joint on "
                                     "two slides is placed by a 'prp' module, with no link")
                block, guide, direction = ready[0]
                if block is not None:
                    fresh(block, label)
                e = _unit(direction)
                r1 = float(np.hypot(*(ref[C] - ref[P])))
                if r1 <= 0:
                    raise InputError(f"{name}: {label}: joint '{C}' coincides with joint '{P}'")
                along = float((ref[C] - ref[P]) @ e)
                branch = m.branch or (1 if along > 0 else -1 if along < 0 else 0)
                if branch == 0:
                    raise InputError(f"{name}: {label}: link '{b1}' is perpendicular to its slide in the reference "
                                     "configuration (it locks there); give the module a branch")
                steps.append(dict(kind="rrp", label=label, b1=b1, P=P, C=C, r1=r1, branch=branch, guide=guide,
                                  block=block, e_ref=e))
                pose(b1, label)
                if block is not None:
                    pose(block, label, slide=True)
            elif m.kind == "rpr":
                block, guide = m.links
                P = m.joint
                direction = block_on(block, guide, label)
                if guide in self.guided:
                    raise InputError(f"{name}: {label}: the guide '{guide}' slides along "
                                     f"{guide_text(self.guided[guide][0])}: an rpr module turns its guide about a "
                                     "pivot (use rpp for a guide that slides)")
                for b in (block, guide):
                    if b in posed:
                        raise InputError(f"{name}: {label}: link '{b}' is already placed by an earlier module")
                if known_joints(block) != [P]:
                    raise InputError(f"{name}: {label}: block '{block}' already has joints "
                                     f"{known_joints(block)} placed: it is over-constrained (its one known joint is "
                                     f"'{P}')")
                Q = known_joint(guide, None, label)
                u = ref[P] - ref[Q]
                if np.hypot(*u) <= 0:
                    raise InputError(f"{name}: {label}: joint '{P}' coincides with the pivot '{Q}' of the guide")
                e = _unit(direction)
                along = float(u @ e)
                branch = m.branch or (1 if along > 0 else -1 if along < 0 else 0)
                if branch == 0:
                    raise InputError(f"{name}: {label}: the line from '{Q}' to '{P}' is square to the slide in the "
                                     "reference configuration (it locks there); give the module a branch")
                steps.append(dict(kind="rpr", label=label, block=block, guide=guide, P=P, Q=Q, u=u, e_ref=e,
                                  offset=float(_cross(u, e)), along_ref=along, reach=float(np.hypot(*u)),
                                  branch=branch))
                pose(block, label, slide=True)
                pose(guide, label)
            elif m.kind == "prp":
                C = m.joint
                lines = slide_lines(C)
                ready = [x for x in lines if x[1] is None or x[1] in posed]
                if len(ready) != 2:
                    waiting = [x for x in lines if x not in ready]
                    raise InputError(f"{name}: {label}: joint '{C}' needs two slides along the ground or placed guides, "
                                     f"it has {len(ready)} ({describe(ready)})"
                                     + (f"; the guide of {describe(waiting)} is not placed yet" if waiting else ""))
                if all(g is None for _, g, _ in ready):
                    raise InputError(f"{name}: {label}: both slides of joint '{C}' are on the ground: the joint cannot "
                                     "move (make it a pinned ground joint)")
                es = [_unit(d) for _, _, d in ready]
                if abs(float(_cross(es[0], es[1]))) <= LOCK_TOLERANCE:
                    raise InputError(f"{name}: {label}: the two slides of joint '{C}' ({describe(ready)}) are parallel "
                                     "in the reference configuration (it locks there)")
                for s, _, _ in ready:
                    if s is not None:
                        fresh(s, label)
                steps.append(dict(kind="prp", label=label, C=C,
                                  lines=tuple((s, g, e) for (s, g, _), e in zip(ready, es))))
                for s, _, _ in ready:
                    if s is not None:
                        pose(s, label, slide=True)
                known.add(C)
            else:                                   # rpp
                block, mid = m.links
                P = m.joint
                d1 = block_on(block, mid, label)
                if mid not in self.guided:
                    raise InputError(f"{name}: {label}: link '{mid}' does not slide: an rpp module moves a block along "
                                     "a link that slides along the ground or a placed guide (use rpr for a guide that "
                                     "turns about a pivot)")
                guide, d2 = self.guided[mid]
                if guide is not None and guide not in posed:
                    raise InputError(f"{name}: {label}: the guide '{guide}' of link '{mid}' is not placed yet")
                for b in (block, mid):
                    if b in posed:
                        raise InputError(f"{name}: {label}: link '{b}' is already placed by an earlier module")
                if known_joints(block) != [P]:
                    raise InputError(f"{name}: {label}: block '{block}' already has joints "
                                     f"{known_joints(block)} placed: it is over-constrained (its one known joint is "
                                     f"'{P}')")
                fresh(mid, label)
                e1, e2 = _unit(d1), _unit(d2)
                if abs(float(_cross(e1, e2))) <= LOCK_TOLERANCE:
                    raise InputError(f"{name}: {label}: the slide of block '{block}' along link '{mid}' is parallel to "
                                     f"the slide of '{mid}' along {guide_text(guide)}: the linkage locks at every "
                                     "position")
                steps.append(dict(kind="rpp", label=label, block=block, mid=mid, guide=guide, P=P,
                                  X=self.bodies[mid][0], e1_ref=e1, e2_ref=e2))
                pose(block, label, slide=True)
                pose(mid, label, slide=True)
        missing = [b for b in self.bodies if b not in posed]
        if missing:
            raise InputError(f"{name}: link(s) {', '.join(repr(b) for b in missing)} are placed by no module "
                             "(add the module that places them: every link is placed by exactly one module)")
        unplaced = [j for j in ref if j not in known]
        if unplaced:
            raise InputError(f"{name}: joint(s) {', '.join(repr(j) for j in unplaced)} are on no link and not on the "
                             "ground")
        return tuple(steps)

    @property
    def joint_names(self) -> tuple:
        return tuple(self._ref)

    def reference_position(self, joint: str) -> np.ndarray:
        return self._ref[joint]

    @property
    def reference_crank_angle(self) -> float:
        """The crank angle of the reference configuration [rad]."""
        return float(self._steps[0]["theta_ref"] - self.crank_zero)

    @property
    def sliding_blocks(self) -> dict:
        """``{ground slide joint: body}`` for the ground slides whose block carries welded links:
        the body translates along the slide without turning (a ``sliding_clamp`` support in the
        instantaneous structure)."""
        out = {}
        for b, (g, d) in self.guided.items():
            if g is None:
                for j in self.bodies[b]:
                    if j in self.ground_slides and abs(math.sin(self.ground_slides[j] - d)) < 1e-12:
                        out[j] = b
        return out

    def step(self, index: int) -> dict:
        """The planned data of module ``index`` (known joints, radii, branch, slide)."""
        return dict(self._steps[index])

    # -- solution ------------------------------------------------------------------------------
    def solve(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0,
              lock_tolerance: float = LOCK_TOLERANCE) -> LinkageState:
        """Positions, velocities and accelerations of every joint and body at the crank states
        (arrays broadcast together; crank angle [rad] from ``crank_zero``, CCW positive). A
        module that cannot assemble, or whose toggle angle (see :data:`LOCK_TOLERANCE`) has a
        sine within ``lock_tolerance``, raises :class:`AssemblyError`."""
        th = require_finite("crank_angle", crank_angle)
        w = require_finite("crank_speed", crank_speed)
        a = require_finite("crank_acceleration", crank_acceleration)
        th, w, a = (np.array(x, dtype=float) for x in np.broadcast_arrays(th, w, a))
        shape = th.shape
        ref = self._ref
        zero2 = np.zeros(shape + (2,))
        J = {j: (np.broadcast_to(ref[j], shape + (2,)).copy(), zero2, zero2) for j in self.ground}
        B, S, BS = {}, {}, {}

        def at(v):
            return np.broadcast_to(v, shape + (2,))

        def set_pose(body, anchor, rot, om, al):
            B[body] = BodyMotion(rot, om, al)
            p0, v0, a0 = J[anchor]
            for j in self.bodies[body]:
                if j == anchor or j in J:
                    continue
                r = _rot(at(ref[j] - ref[anchor]), rot)
                kr = _perp(r)
                J[j] = (p0 + r, v0 + om[..., None] * kr, a0 + al[..., None] * kr - (om**2)[..., None] * r)

        def pose_from(body, P, C):
            """Pose of a rigid body from two of its joints (|C - P| is constant)."""
            (pp, vp, ap), (pc, vc, ac) = J[P], J[C]
            r = pc - pp
            r2 = _dot(r, r)
            rot = _angle(r) - _angle(ref[C] - ref[P])
            set_pose(body, P, rot, _cross(r, vc - vp) / r2, _cross(r, ac - ap) / r2)

        def carried(guide, X):
            """The point of body ``guide`` (None: the ground) at joint X's reference position:
            position, velocity, acceleration, and the guide's rotation, speed, acceleration."""
            if guide is None:
                z = np.zeros(shape)
                return at(ref[X]).copy(), zero2, zero2, z, z, z
            g = B[guide]
            anchor = next(j for j in self.bodies[guide] if j in J)
            p0, v0, a0 = J[anchor]
            r = _rot(at(ref[X] - ref[anchor]), g.rotation)
            kr = _perp(r)
            return (p0 + r, v0 + g.omega[..., None] * kr,
                    a0 + g.alpha[..., None] * kr - (g.omega**2)[..., None] * r, g.rotation, g.omega, g.alpha)

        def fail(step, msg, bad):
            i = int(np.flatnonzero(np.ravel(np.broadcast_to(bad, shape)))[0])
            deg = math.degrees(float(np.ravel(th)[i]))
            raise AssemblyError(f"{self.name}: at crank angle {deg % 360.0:.6g} deg, {step['label']} {msg(i)}")

        def sc(x, v):
            return x[..., None] * v

        for st in self._steps:
            kind = st["kind"]
            if kind == "crank":
                rot = self.crank_zero + th - st["theta_ref"]
                set_pose(st["body"], self.pivot, rot, w, a)
            elif kind == "rrr":
                P, Q, C, r1, r2, br = st["P"], st["Q"], st["C"], st["r1"], st["r2"], st["branch"]
                (pp, vp, ap), (pq, vq, aq) = J[P], J[Q]
                d = pq - pp
                D = np.hypot(d[..., 0], d[..., 1])
                slack = 1e-12 * (r1 + r2)
                far, near = D > r1 + r2 + slack, D < abs(r1 - r2) - slack
                if np.any(far | near):
                    fail(st, lambda i: (f"cannot assemble: joints '{P}' and '{Q}' are {np.ravel(D)[i]:.6g} m apart, "
                                        f"{'more than' if np.ravel(far)[i] else 'less than'} the links reach "
                                        f"({r1:.6g} and {r2:.6g} m from joint '{C}'): the linkage locks before this "
                                        "position"), far | near)
                x = (D**2 + r1**2 - r2**2) / (2 * D)
                y = br * np.sqrt(np.maximum(r1**2 - x**2, 0.0))
                u = d / D[..., None]
                pc = pp + sc(x, u) + sc(y, _perp(u))
                cp, cq = pc - pp, pc - pq
                det = _cross(cp, cq)
                lock = np.abs(det) <= lock_tolerance * r1 * r2
                if np.any(lock):
                    fail(st, lambda i: (f"locks: links '{st['b1']}' and '{st['b2']}' are "
                                        f"{_asin_deg(np.ravel(det)[i] / (r1 * r2)):.3g} deg from collinear at joint "
                                        f"'{C}' (a toggle: their motion is undefined)"), lock)

                def solve2(f1, f2):
                    return np.stack([(f1 * cq[..., 1] - cp[..., 1] * f2) / det,
                                     (cp[..., 0] * f2 - cq[..., 0] * f1) / det], -1)
                vc = solve2(_dot(cp, vp), _dot(cq, vq))
                ac = solve2(_dot(cp, ap) - _dot(vc - vp, vc - vp), _dot(cq, aq) - _dot(vc - vq, vc - vq))
                J[C] = (pc, vc, ac)
                pose_from(st["b1"], P, C)
                pose_from(st["b2"], Q, C)
            elif kind == "rrp":
                # C = L0 + s e on the slide line, |C - P| = r1
                P, C, r1, br = st["P"], st["C"], st["r1"], st["branch"]
                pp, vp, ap = J[P]
                L0, vL, aL, rot_g, om, al = carried(st["guide"], C)
                e = _rot(at(st["e_ref"]), rot_g)
                ke = _perp(e)
                h = L0 - pp
                c = _cross(h, e)
                disc = r1**2 - c**2
                far = disc < -1e-12 * r1**2
                if np.any(far):
                    fail(st, lambda i: (f"cannot assemble: joint '{P}' is {abs(np.ravel(c)[i]):.6g} m from the slide "
                                        f"line of joint '{C}', farther than the link reaches ({r1:.6g} m): the linkage "
                                        "locks before this position"), far)
                s = -_dot(h, e) + br * np.sqrt(np.maximum(disc, 0.0))
                pc = L0 + sc(s, e)
                cp = pc - pp
                den = _dot(cp, e)
                lock = np.abs(den) <= lock_tolerance * r1
                if np.any(lock):
                    fail(st, lambda i: (f"locks: link '{st['b1']}' is "
                                        f"{_asin_deg(np.ravel(den)[i] / r1):.3g} deg from "
                                        f"perpendicular to the slide of joint '{C}' (its motion along the slide is "
                                        "undefined)"), lock)
                vg = vL + sc(om * s, ke)                 # guide point under C
                sd = -_dot(cp, vg - vp) / den
                vc = vg + sc(sd, e)
                ag = aL + sc(al * s, ke) - sc(om**2 * s, e)
                cor = sc(2.0 * sd * om, ke)
                sdd = -(_dot(cp, ag + cor - ap) + _dot(vc - vp, vc - vp)) / den
                J[C] = (pc, vc, ag + cor + sc(sdd, e))
                S[C] = (s, sd, sdd)
                pose_from(st["b1"], P, C)
                if st["block"] is not None:
                    set_pose(st["block"], C, rot_g, om, al)
                    BS[st["block"]] = S[C]
            elif kind == "rpr":
                # P - Q = R(phi) (u + s e0): the block (through P) and the guide (through Q) turn
                # together by phi; |u + s e0| = |P - Q| gives s, its direction phi.
                P, Q, br, off, reach = st["P"], st["Q"], st["branch"], st["offset"], st["reach"]
                (pp, vp, ap), (pq, vq, aq) = J[P], J[Q]
                d = pp - pq
                D = np.hypot(d[..., 0], d[..., 1])
                disc = D**2 - off**2
                far = disc < -1e-12 * reach**2
                if np.any(far):
                    fail(st, lambda i: (f"cannot assemble: joints '{P}' and '{Q}' are {np.ravel(D)[i]:.6g} m apart, "
                                        f"less than the offset ({abs(off):.6g} m) of the slide of block "
                                        f"'{st['block']}' from the pivot '{Q}' of its guide '{st['guide']}': the "
                                        "linkage locks before this position"), far)
                s = -st["along_ref"] + br * np.sqrt(np.maximum(disc, 0.0))
                rot = _angle(d) - _angle(at(st["u"]) + sc(s, at(st["e_ref"])))
                e = _rot(at(st["e_ref"]), rot)
                den = _dot(d, e)
                # Locked: P - Q square to the slide (the limit of an offset slide), or P on the pivot.
                through = D <= lock_tolerance * reach
                lock = (np.abs(den) <= lock_tolerance * D) | through
                if np.any(lock):
                    fail(st, lambda i: (f"locks: joint '{P}' is {np.ravel(D)[i]:.3g} m from the pivot '{Q}' of the "
                                        f"guide '{st['guide']}' (its turn is undefined)" if np.ravel(through)[i] else
                                        f"locks: the line from the pivot '{Q}' to joint '{P}' is "
                                        f"{_asin_deg(np.ravel(den)[i] / np.ravel(D)[i]):.3g} deg from square to the "
                                        f"slide of block '{st['block']}' along '{st['guide']}' (the guide's turn is "
                                        "undefined)"), lock)
                kd, ke = _perp(d), _perp(e)

                def solve_pe(b):               # b = x kd + y e  (det = cross(kd, e) = -den)
                    return -_cross(b, e) / den, -_cross(kd, b) / den
                om, sd = solve_pe(vp - vq)
                al, sdd = solve_pe(ap - aq + sc(om**2, d) - sc(2.0 * sd * om, ke))
                set_pose(st["guide"], Q, rot, om, al)
                set_pose(st["block"], P, rot, om, al)
                BS[st["block"]] = (s, sd, sdd)
            elif kind == "prp":
                # C = L1 + s1 e1 = L2 + s2 e2: two slide lines, each on the ground or a placed guide.
                C = st["C"]
                ln = []
                for blk, g, e_ref in st["lines"]:
                    L, vL, aL, rot, om, al = carried(g, C)
                    ln.append((blk, L, vL, aL, rot, om, al, _rot(at(e_ref), rot)))
                e1, e2 = ln[0][7], ln[1][7]
                cr = _cross(e1, e2)
                lock = np.abs(cr) <= lock_tolerance
                if np.any(lock):
                    fail(st, lambda i: (f"cannot assemble: its two slides ({', '.join(self._line_text(x) for x in st['lines'])}) "
                                        f"are {_asin_deg(np.ravel(cr)[i]):.3g} deg from parallel (joint '{C}' is "
                                        "undefined along them)"), lock)

                def solve_ll(b):               # b = s1 e1 - s2 e2
                    return _cross(b, e2) / cr, -_cross(e1, b) / cr
                s1, s2 = solve_ll(ln[1][1] - ln[0][1])
                ss = (s1, s2)
                vg = [x[2] + sc(x[5] * s_, _perp(x[7])) for x, s_ in zip(ln, ss)]
                sd = solve_ll(vg[1] - vg[0])
                ag = [x[3] + sc(x[6] * s_, _perp(x[7])) - sc(x[5]**2 * s_, x[7]) + sc(2.0 * x[5] * v_, _perp(x[7]))
                      for x, s_, v_ in zip(ln, ss, sd)]
                sdd = solve_ll(ag[1] - ag[0])
                J[C] = (ln[0][1] + sc(s1, e1), vg[0] + sc(sd[0], e1), ag[0] + sc(sdd[0], e1))
                for k, x in enumerate(ln):
                    slide = (ss[k], sd[k], sdd[k])
                    if x[0] is None or st["lines"][k][1] is None:
                        S[C] = slide
                    if x[0] is not None:
                        set_pose(x[0], C, x[4], x[5], x[6])
                        BS[x[0]] = slide
            else:                                                        # rpp
                # P = G(P_ref) + s2 e2 + s1 e1: the block slides along `mid`, `mid` along its guide G;
                # both keep the guide's rotation.
                P, X = st["P"], st["X"]
                pp, vp, ap = J[P]
                Lp, vLp, aLp, rot, om, al = carried(st["guide"], P)
                e1, e2 = _rot(at(st["e1_ref"]), rot), _rot(at(st["e2_ref"]), rot)
                cr = _cross(e2, e1)
                lock = np.abs(cr) <= lock_tolerance
                if np.any(lock):
                    fail(st, lambda i: (f"locks: the slide of block '{st['block']}' along '{st['mid']}' is "
                                        f"{_asin_deg(np.ravel(cr)[i]):.3g} deg from parallel to the slide of "
                                        f"'{st['mid']}' along "
                                        f"{'the ground' if st['guide'] is None else repr(st['guide'])}"), lock)

                def solve_pp(b):               # b = s2 e2 + s1 e1
                    return _cross(b, e1) / cr, _cross(e2, b) / cr
                b = pp - Lp
                s2, s1 = solve_pp(b)
                sd2, sd1 = solve_pp(vp - vLp - sc(om, _perp(b)))
                wv = sc(sd2, e2) + sc(sd1, e1)
                sdd2, sdd1 = solve_pp(ap - aLp - sc(al, _perp(b)) + sc(om**2, b) - sc(2.0 * om, _perp(wv)))
                LX, vLX, aLX, _, _, _ = carried(st["guide"], X)
                k2 = _perp(e2)
                J[X] = (LX + sc(s2, e2), vLX + sc(om * s2, k2) + sc(sd2, e2),
                        aLX + sc(al * s2, k2) - sc(om**2 * s2, e2) + sc(2.0 * om * sd2, k2) + sc(sdd2, e2))
                set_pose(st["mid"], X, rot, om, al)
                set_pose(st["block"], P, rot, om, al)
                BS[st["block"]], BS[st["mid"]] = (s1, sd1, sdd1), (s2, sd2, sdd2)
        return LinkageState(th, J, B, S, BS)

    @staticmethod
    def _line_text(line) -> str:
        s, g, _ = line
        return "the ground slide" if s is None else f"block '{s}' along {'the ground' if g is None else repr(g)}"


@dataclass(frozen=True)
class LinkageMotion:
    """Kinematics of a linkage mechanism at a set of crank positions (arrays over positions):
    ``state`` (every joint and body), and :meth:`link` for each mechanism link."""

    state: LinkageState
    frames: Mapping[str, tuple]          # link -> (body, start joint, end joint, reference angle)

    def link(self, name: str) -> LinkMotion:
        try:
            body, a, _, angle0 = self.frames[name]
        except KeyError:
            raise InputError(f"unknown link '{name}' (links: {', '.join(self.frames)})") from None
        bm = self.state.bodies[body]
        p, v, acc = self.state.joints[a]
        return LinkMotion(p, v, acc, angle0 + bm.rotation, bm.omega, bm.alpha)

    def position(self, joint: str) -> np.ndarray:
        return self.state.joints[joint][0]

    def joint(self, joint: str) -> tuple:
        """(position, velocity, acceleration) of a joint, each (..., 2)."""
        return self.state.joints[joint]


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
class LinkageMechanism(_LinkageMethods):
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
