"""General planar linkages: closed-form kinematics by modules (Shin's component-module approach).

Kinematics (Shin 1986, Ch. 2 and App. A, the component-module approach). A
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

Owns: the closed-form module kinematics of any planar linkage. Boundaries: no structure or
dynamics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .errors import AssemblyError, InputError, require_finite
from .kinematics import LinkMotion
from .linkage_plan import LOCK_TOLERANCE, plan_modules
from .plane import angle as _angle, asin_deg as _asin_deg, cross as _cross, dot as _dot, perp as _perp, rot as _rot

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
        object.__setattr__(self, "_steps", plan_modules(self, ref))

    # -- planning ------------------------------------------------------------------------------

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
