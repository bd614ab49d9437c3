"""General planar linkages: closed-form kinematics by modules, and the mechanism behind every engine.

Kinematics (Shin 1986, Ch. 2, the component-module approach; notes seed000 §4). A linkage is a
set of rigid *bodies* (each a list of joints that keep their relative positions: a straight link
through its path of joints, a plate through its vertices, a slider block with the links welded to
it), joined at joints, and described at one assembled *reference* configuration (joint
coordinates). Its motion is solved, for any crank angle, by an ordered list of closed-form
modules; each places one new joint from joints already known and fixes the bodies that meet
there:

=========  =========================================================================================
``crank``  Shin type 1, the input link: the driven body turns about its ground pivot by the crank
           angle (measured from the global direction ``crank_zero``).
``rrr``    Shin type 2, the dyad: joint C shared by two bodies, each with one known joint (P, Q):
           the intersection of two circles; branch = the side of P->Q on which C lies.
``rrp``    Shin types 3, 5, 6: joint C of a body with one known joint P, sliding on a line, either
           fixed to the ground (a joint with a ``slider`` support) or carried by a guide body (C
           belongs to a block body that slides along the guide and turns with it); branch = the
           sign of (C - P) along the slide.
=========  =========================================================================================

Shin's type 4 (a further point of a body whose pose is known: "solid link") is applied
automatically: a module fixes whole bodies, and every joint of a body follows from its pose.
Branches default to the reference configuration's, so a linkage drawn assembled moves on the
branch it is drawn in. Velocities and accelerations come from the differentiated closure
relations of each module (linear 2x2 systems), exactly; the tests check them against finite
differences. A module that cannot assemble (a dyad beyond its stretched or folded limit, a link
too short to reach its slide line) or that locks (the two links of a dyad collinear, a link
perpendicular to its slide) raises :class:`tmm_core.errors.AssemblyError` naming the module and
the crank angle.

Mechanism (:class:`LinkageMechanism`): the flexible links (members, each a straight part of a
link between two joints), rigid plates, slider blocks, springs and constant loads, with the
protocol the transfer-matrix time domain uses (``links``, ``elastic_links``, ``structure``,
``motion``, ``joint_positions``, ``drive_torque_terms``, ``external_loads``, ``crank_inertia``).
Its instantaneous structure is Shin's: the crank clamped at its ground pivot (a rigid crank is
welded there, so its far joint is a fixed pin), revolutes elsewhere unless a link is welded, ground
pivots pinned, ground slides as ``slider`` supports, plates as :class:`RigidBody`, blocks on a
moving guide as :class:`SliderJoint`. A plate's mass and rotary inertia sit on a strain-free
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

MODULE_KINDS = ("crank", "rrr", "rrp")
#: A dyad is reported locked where |sin| of the angle between its two links (rrr) or between the
#: link and its slide's normal (rrp) falls below this.
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
    return math.degrees(math.asin(min(1.0, abs(float(x)))))


@dataclass(frozen=True)
class Module:
    """One closed-form step: ``kind`` ('crank', 'rrr', 'rrp'), the ``joint`` it places (the
    crank's tip for 'crank'), the bodies it poses (``links``: the crank; the dyad's two bodies;
    the rrp's link with its known joint), and the assembly ``branch`` (+1/-1; 0 = the
    reference configuration's)."""

    kind: str
    joint: str
    links: tuple
    branch: int = 0

    def __post_init__(self):
        if self.kind not in MODULE_KINDS:
            raise InputError(f"module kind must be one of {MODULE_KINDS}, got {self.kind!r}")
        n = {"crank": 1, "rrr": 2, "rrp": 1}[self.kind]
        if len(self.links) != n:
            raise InputError(f"module '{self.kind}' at joint '{self.joint}' needs {n} link(s), got {list(self.links)}")
        if self.branch not in (-1, 0, 1):
            raise InputError(f"module '{self.kind}' at joint '{self.joint}': branch must be +1, -1 or 0, got "
                             f"{self.branch!r}")

    def label(self, index: int) -> str:
        return f"module {index + 1} ({self.kind} at joint '{self.joint}', link{'s' if len(self.links) > 1 else ''} " \
               f"{', '.join(repr(b) for b in self.links)})"


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
    an rrp module's joint along its line from the reference position [m, m/s, m/s^2]."""

    crank_angle: np.ndarray
    joints: Mapping[str, tuple]
    bodies: Mapping[str, BodyMotion]
    slides: Mapping[str, tuple]


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
        with the guide.
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
        for s, (g, _) in self.guided.items():
            if s not in self.bodies or (g not in self.bodies):
                raise InputError(f"{name}: guided body '{s}' or its guide '{g}' is not a body")
        if self.crank not in self.bodies:
            raise InputError(f"{name}: the crank '{self.crank}' is not a link")
        known = set(self.ground)
        posed = set()
        steps = []

        def members_of(j):
            return [b for b, js in self.bodies.items() if j in js]

        def known_joint(body, exclude, label):
            ks = [j for j in self.bodies[body] if j in known and j != exclude]
            if not ks:
                raise InputError(f"{name}: {label}: link '{body}' has no joint placed yet (place one of "
                                 f"{list(self.bodies[body])} by an earlier module)")
            if len(ks) > 1:
                raise InputError(f"{name}: {label}: link '{body}' already has joints {ks} placed by other links: it is "
                                 "over-constrained (a link placed by a module has exactly one joint known before it)")
            return ks[0]

        def pose(body, label):
            if body in posed:
                raise InputError(f"{name}: {label}: link '{body}' is already placed by an earlier module")
            posed.add(body)
            known.update(self.bodies[body])

        for i, m in enumerate(self.modules):
            label = m.label(i)
            for b in m.links:
                if b not in self.bodies:
                    raise InputError(f"{name}: {label}: unknown link '{b}' (links: {', '.join(self.bodies)})")
                if m.joint not in self.bodies[b]:
                    raise InputError(f"{name}: {label}: joint '{m.joint}' is not on link '{b}'")
            if m.joint in known:
                raise InputError(f"{name}: {label}: joint '{m.joint}' is already placed by an earlier module")
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
            else:                                   # rrp
                b1 = m.links[0]
                C = m.joint
                P = known_joint(b1, C, label)
                block = next((s for s in self.guided if C in self.bodies[s]), None)
                if C in self.ground_slides and block is not None:
                    raise InputError(f"{name}: {label}: joint '{C}' slides on the ground and on block '{block}'")
                if C in self.ground_slides:
                    guide, direction = None, self.ground_slides[C]
                elif block is not None:
                    guide, direction = self.guided[block]
                    if guide not in posed:
                        raise InputError(f"{name}: {label}: the guide '{guide}' of block '{block}' is not placed yet")
                    if block == b1:
                        raise InputError(f"{name}: {label}: the link '{b1}' cannot be its own sliding block")
                else:
                    raise InputError(f"{name}: {label}: joint '{C}' has no slide (give it a slider support, or put it "
                                     "on a block that slides along a guide)")
                e = np.array([math.cos(direction), math.sin(direction)])
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
                    pose(block, label)
            # A body none of whose joints a module places, but two of whose joints are known, is
            # over-constrained (it could not keep its length).
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

    def step(self, index: int) -> dict:
        """The planned data of module ``index`` (known joints, radii, branch, slide)."""
        return dict(self._steps[index])

    # -- solution ------------------------------------------------------------------------------
    def solve(self, crank_angle, crank_speed=0.0, crank_acceleration=0.0,
              lock_tolerance: float = LOCK_TOLERANCE) -> LinkageState:
        """Positions, velocities and accelerations of every joint and body at the crank states
        (arrays broadcast together; crank angle [rad] from ``crank_zero``, CCW positive). A
        module whose links come within ``lock_tolerance`` (the sine of the angle) of a toggle
        raises :class:`AssemblyError`."""
        th = require_finite("crank_angle", crank_angle)
        w = require_finite("crank_speed", crank_speed)
        a = require_finite("crank_acceleration", crank_acceleration)
        th, w, a = (np.array(x, dtype=float) for x in np.broadcast_arrays(th, w, a))
        shape = th.shape
        ref = self._ref
        zero2 = np.zeros(shape + (2,))
        J = {j: (np.broadcast_to(ref[j], shape + (2,)).copy(), zero2, zero2) for j in self.ground}
        B, S = {}, {}

        def set_pose(body, anchor, rot, om, al):
            B[body] = BodyMotion(rot, om, al)
            p0, v0, a0 = J[anchor]
            for j in self.bodies[body]:
                if j == anchor or j in J:
                    continue
                r = _rot(np.broadcast_to(ref[j] - ref[anchor], shape + (2,)), rot)
                kr = _perp(r)
                J[j] = (p0 + r, v0 + om[..., None] * kr, a0 + al[..., None] * kr - (om**2)[..., None] * r)

        def pose_from(body, P, C):
            """Pose of a rigid body from two of its joints (|C - P| is constant)."""
            (pp, vp, ap), (pc, vc, ac) = J[P], J[C]
            r = pc - pp
            r2 = _dot(r, r)
            rot = _angle(r) - _angle(ref[C] - ref[P])
            set_pose(body, P, rot, _cross(r, vc - vp) / r2, _cross(r, ac - ap) / r2)

        def fail(step, msg, bad):
            i = int(np.flatnonzero(np.ravel(bad))[0])
            deg = math.degrees(float(np.ravel(th)[i]))
            raise AssemblyError(f"{self.name}: at crank angle {deg % 360.0:.6g} deg, {step['label']} {msg(i)}")

        for st in self._steps:
            if st["kind"] == "crank":
                rot = self.crank_zero + th - st["theta_ref"]
                set_pose(st["body"], self.pivot, rot, w, a)
                continue
            if st["kind"] == "rrr":
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
                pc = pp + x[..., None] * u + y[..., None] * _perp(u)
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
                continue
            # rrp: C = L0 + s e on the slide line, |C - P| = r1
            P, C, r1, br, e_ref = st["P"], st["C"], st["r1"], st["branch"], st["e_ref"]
            pp, vp, ap = J[P]
            if st["guide"] is None:
                L0, vL, aL = np.broadcast_to(ref[C], shape + (2,)), zero2, zero2
                rot_g, om, al = np.zeros(shape), np.zeros(shape), np.zeros(shape)
            else:
                g = B[st["guide"]]
                anchor = next(j for j in self.bodies[st["guide"]] if j in J)
                p0, v0, a0 = J[anchor]
                rg = _rot(np.broadcast_to(ref[C] - ref[anchor], shape + (2,)), g.rotation)
                krg = _perp(rg)
                om, al, rot_g = g.omega, g.alpha, g.rotation
                L0 = p0 + rg
                vL = v0 + om[..., None] * krg
                aL = a0 + al[..., None] * krg - (om**2)[..., None] * rg
            e = _rot(np.broadcast_to(e_ref, shape + (2,)), rot_g)
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
            pc = L0 + s[..., None] * e
            cp = pc - pp
            den = _dot(cp, e)
            lock = np.abs(den) <= lock_tolerance * r1
            if np.any(lock):
                fail(st, lambda i: (f"locks: link '{st['b1']}' is "
                                    f"{_asin_deg(np.ravel(den)[i] / r1):.3g} deg from "
                                    f"perpendicular to the slide of joint '{C}' (its motion along the slide is "
                                    "undefined)"), lock)
            vg = vL + (om * s)[..., None] * ke                 # guide point under C
            sd = -_dot(cp, vg - vp) / den
            vc = vg + sd[..., None] * e
            ag = aL + (al * s)[..., None] * ke - (om**2 * s)[..., None] * e
            cor = (2.0 * sd * om)[..., None] * ke
            sdd = -(_dot(cp, ag + cor - ap) + _dot(vc - vp, vc - vp)) / den
            J[C] = (pc, vc, ag + cor + sdd[..., None] * e)
            S[C] = (s, sd, sdd)
            pose_from(st["b1"], P, C)
            if st["block"] is not None:
                set_pose(st["block"], C, rot_g, om, al)
        return LinkageState(th, J, B, S)


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
        ``kinematics.ground_slides``); the crank pivot is clamped in the instantaneous structure.
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
        for j in kin.joint_names:
            if j not in used:
                continue
            if j == kin.pivot and not crank.rigid:
                joints.append(Joint(j, "clamped"))
            elif j in pins:
                joints.append(Joint(j, "pinned"))
            elif self.supports.get(j) == "slider":
                joints.append(Joint(j, "slider", kin.ground_slides[j]))
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
