"""The plan of a linkage's modules: the order checked once, and each module's fixed data.

:func:`plan_modules` checks that every body is posed by exactly one module and every joint is
placed, and precomputes what each step of :meth:`tmm_core.linkage_kinematics.LinkageKinematics.solve`
needs (reference vectors, slide directions, branches). Pure: reads the kinematics description only.

Owns: the module order check and each step's fixed data. Boundaries: no solving.
"""
from __future__ import annotations

import math

import numpy as np

from .errors import InputError
from .plane import angle as _angle, cross as _cross, unit as _unit

#: A module is reported locked where the sine of the angle of its toggle falls below this: between
#: a dyad's two links (rrr), between a link and its slide's normal (rrp), between the line from
#: the known joint to the pivot and the guide's normal (rpr), between two slides (prp, rpp); an rpr
#: also locks where its joint comes within this fraction of its reference distance of the pivot.
LOCK_TOLERANCE = 1e-9


def plan_modules(kin, ref_positions: dict) -> tuple:
    """Check the module order and precompute each step's fixed data; every body must be
    posed by exactly one module and every joint placed."""
    ref, name = ref_positions, kin.name
    for b, joints in kin.bodies.items():
        if len(joints) < 1:
            raise InputError(f"{name}: body '{b}' has no joints")
        for j in joints:
            if j not in ref:
                raise InputError(f"{name}: body '{b}' refers to joint '{j}', which has no position")
    for j in list(kin.ground) + list(kin.ground_slides):
        if j not in ref:
            raise InputError(f"{name}: ground joint '{j}' has no position")
    for s, (g, d) in kin.guided.items():
        if s not in kin.bodies or (g is not None and g not in kin.bodies):
            raise InputError(f"{name}: guided body '{s}' or its guide '{g}' is not a body")
        if g == s:
            raise InputError(f"{name}: body '{s}' cannot slide along itself")
        if g is None and not any(j in kin.ground_slides and abs(math.sin(kin.ground_slides[j] - d)) < 1e-12
                                 for j in kin.bodies[s]):
            raise InputError(f"{name}: body '{s}' slides along the ground but none of its joints is a ground "
                             "slide in that direction (its block)")
    if kin.crank not in kin.bodies:
        raise InputError(f"{name}: the crank '{kin.crank}' is not a link")
    known = set(kin.ground)
    posed = set()
    steps = []

    def known_joints(body, exclude=None):
        return [j for j in kin.bodies[body] if j in known and j != exclude]

    def known_joint(body, exclude, label):
        ks = known_joints(body, exclude)
        if not ks:
            raise InputError(f"{name}: {label}: link '{body}' has no joint placed yet (place one of "
                             f"{list(kin.bodies[body])} by an earlier module)")
        if len(ks) > 1:
            raise InputError(f"{name}: {label}: link '{body}' already has joints {ks} placed by other links: it is "
                             "over-constrained (a link placed by a module has exactly one joint known before it)")
        return ks[0]

    def guide_text(g):
        return "the ground" if g is None else f"link '{g}'"

    def pose(body, label, slide=False):
        if body in posed:
            raise InputError(f"{name}: {label}: link '{body}' is already placed by an earlier module")
        if body in kin.guided and not slide:
            raise InputError(f"{name}: {label}: link '{body}' slides along {guide_text(kin.guided[body][0])}: "
                             "place it by a module that keeps its slide (rrp, prp, rpr or rpp)")
        posed.add(body)
        known.update(kin.bodies[body])

    def slide_lines(C):
        """The slides of joint C not placed yet: (block body or None, guide body or None for
        the ground, direction). A ground slider's block carrying welded links is one slide."""
        out = [(s, g, d) for s, (g, d) in kin.guided.items() if C in kin.bodies[s] and s not in posed]
        if C in kin.ground_slides:
            d = kin.ground_slides[C]
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

    def unplaced_block(block, along, P, label):
        """An rpr's or rpp's block and the link it slides along are not placed yet, and the
        block's one known joint is P."""
        for b in (block, along):
            if b in posed:
                raise InputError(f"{name}: {label}: link '{b}' is already placed by an earlier module")
        if known_joints(block) != [P]:
            raise InputError(f"{name}: {label}: block '{block}' already has joints {known_joints(block)} placed: "
                             f"it is over-constrained (its one known joint is '{P}')")

    def block_on(block, guide, label):
        if block not in kin.guided or kin.guided[block][0] != guide:
            raise InputError(f"{name}: {label}: link '{block}' is not a block sliding along link '{guide}'")
        return kin.guided[block][1]

    for i, m in enumerate(kin.modules):
        label = m.label(i)
        for b in m.links:
            if b not in kin.bodies:
                raise InputError(f"{name}: {label}: unknown link '{b}' (links: {', '.join(kin.bodies)})")
        on = m.links[:1] if m.kind in ("rpr", "rpp") else m.links
        for b in on:
            if m.joint not in kin.bodies[b]:
                raise InputError(f"{name}: {label}: joint '{m.joint}' is not on link '{b}'")
        if m.kind in ("rpr", "rpp"):
            if m.joint not in known:
                raise InputError(f"{name}: {label}: joint '{m.joint}' is not placed yet (an {m.kind} module "
                                 "moves a block pinned at a joint placed by an earlier module)")
            if m.joint in kin.bodies[m.links[1]]:
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
            if body != kin.crank or m.joint != kin.tip:
                raise InputError(f"{name}: {label}: the crank module must place the tip '{kin.tip}' of the crank "
                                 f"'{kin.crank}'")
            if kin.pivot not in kin.ground or kin.pivot not in kin.bodies[body]:
                raise InputError(f"{name}: {label}: the crank pivot '{kin.pivot}' must be a ground joint of "
                                 "the crank")
            d = ref[kin.tip] - ref[kin.pivot]
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
            if guide in kin.guided:
                raise InputError(f"{name}: {label}: the guide '{guide}' slides along "
                                 f"{guide_text(kin.guided[guide][0])}: an rpr module turns its guide about a "
                                 "pivot (use rpp for a guide that slides)")
            unplaced_block(block, guide, P, label)
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
            if mid not in kin.guided:
                raise InputError(f"{name}: {label}: link '{mid}' does not slide: an rpp module moves a block along "
                                 "a link that slides along the ground or a placed guide (use rpr for a guide that "
                                 "turns about a pivot)")
            guide, d2 = kin.guided[mid]
            if guide is not None and guide not in posed:
                raise InputError(f"{name}: {label}: the guide '{guide}' of link '{mid}' is not placed yet")
            unplaced_block(block, mid, P, label)
            fresh(mid, label)
            e1, e2 = _unit(d1), _unit(d2)
            if abs(float(_cross(e1, e2))) <= LOCK_TOLERANCE:
                raise InputError(f"{name}: {label}: the slide of block '{block}' along link '{mid}' is parallel to "
                                 f"the slide of '{mid}' along {guide_text(guide)}: the linkage locks at every "
                                 "position")
            steps.append(dict(kind="rpp", label=label, block=block, mid=mid, guide=guide, P=P,
                              X=kin.bodies[mid][0], e1_ref=e1, e2_ref=e2))
            pose(block, label, slide=True)
            pose(mid, label, slide=True)
    missing = [b for b in kin.bodies if b not in posed]
    if missing:
        raise InputError(f"{name}: link(s) {', '.join(repr(b) for b in missing)} are placed by no module "
                         "(add the module that places them: every link is placed by exactly one module)")
    unplaced = [j for j in ref if j not in known]
    if unplaced:
        raise InputError(f"{name}: joint(s) {', '.join(repr(j) for j in unplaced)} are on no link and not on the "
                         "ground")
    return tuple(steps)
