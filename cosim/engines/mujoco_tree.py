"""The MuJoCo body tree of a linkage: bodies with their frames at the reference configuration
and exact mass properties, their parents and joints from the closed-form modules, and the loop
closures (``connect`` constraints). Pure data built from :func:`tmm_core.linkage.as_linkage`;
the engine (:mod:`cosim.engines.mujoco`) writes it as MJCF.

Owns: the MuJoCo body tree of a linkage (frames, masses, parents, closures). Boundaries: no MJCF
text and no simulation.
"""
from __future__ import annotations

import math

import numpy as np

from tmm_core import InputError

from .base import EngineError

SLIDER_BODY_KG = 1e-6     # a ground slide's block body; the block's mass sits on the link's end


def link_inertia(link):
    """Exact rigid-body (mass, centre of mass x, z inertia about it) of a link (see
    :meth:`tmm_core.Link.rigid_body`)."""
    try:
        return link.rigid_body()
    except InputError as exc:
        raise EngineError(f"mujoco: {exc}; a rigid body needs a positive mass") from None


def rot2(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


class BodyTree:
    """The MuJoCo body tree of a linkage: bodies (frames at the reference configuration, mass
    properties, parent, joint), the loop closures and the node sites, from its modules."""

    def __init__(self, lk):
        kin = self.kin = lk.kinematics
        self.lk = lk
        for i in range(len(kin.modules)):
            kind = kin.step(i)["kind"]
            if kind not in ("crank", "rrr", "rrp"):
                # rpr, prp and rpp need a slide between two moving bodies or two slides at one
                # joint; this tree builder does not have them yet (docs/scenario-format.md, "Linkages in motion").
                raise InputError(f"the MuJoCo engine builds linkages from crank, rrr and rrp modules only; "
                                 f"module {i + 1} is {kind!r}: run this linkage with --engines tmm,exudyn")
        ref = kin.reference_position
        members = {}
        for link, a, b, _, _ in lk.members:
            members.setdefault(lk.frames[link.name], []).append((link, a, b))
        plates = {p.name: p for p in lk.plates}
        # Body frames: origin at the first link's start, x along it (a plate's first link is its
        # carrier, from the centre of mass to its first vertex).
        self.frame = {}
        for body in kin.bodies:
            link, a, b = members[body][0]
            d = ref(b) - ref(a)
            self.frame[body] = (ref(a), math.atan2(d[1], d[0]))
        # Mass properties in the body frame.
        self.mass = {}
        for body, links in members.items():
            O, phi = self.frame[body]
            R = rot2(-phi)
            items = []
            for link, a, b in links:
                if body in plates and link.name == plates[body].carrier:
                    p = plates[body]
                    items.append((p.mass_kg, R @ (ref(p.master) - O), p.inertia_kg_m2))
                    continue
                m, xc, Jc = link_inertia(link)
                d = ref(b) - ref(a)
                items.append((m, R @ (ref(a) + xc * d / np.hypot(*d) - O), Jc))
            m = sum(x[0] for x in items)
            c = sum(x[0] * x[1] for x in items) / m
            J = sum(x[2] + x[0] * float((x[1] - c) @ (x[1] - c)) for x in items)
            self.mass[body] = (m, c, J)
        # The tree: parent, joint type and anchor, from the modules. A ground slide's block is a
        # light body on a slide joint from the world, and its link hangs from it (the loop closes
        # at the link's other joint, between massive bodies: a soft connect to a nearly massless
        # block would yield under the loads it carries).
        self.parent, self.joint, self.order, self.closures, self.slider_blocks = {}, {}, [], [], {}

        def carrier_of(j):
            if j in kin.ground:
                return None
            return next(b for b in self.order if j in kin.bodies.get(b, ()))

        def hang(body, anchor, parent="auto"):
            self.parent[body] = carrier_of(anchor) if parent == "auto" else parent
            self.joint[body] = ("hinge", anchor)
            self.order.append(body)
        for i in range(len(kin.modules)):
            st = kin.step(i)
            if st["kind"] == "crank":
                hang(st["body"], kin.pivot, None)
            elif st["kind"] == "rrr":
                hang(st["b1"], st["P"])
                hang(st["b2"], st["Q"])
                self.closures.append((st["b1"], st["b2"], st["C"]))
            elif st["block"] is None:
                name = f"slider_{st['C']}"
                gam = math.atan2(st["e_ref"][1], st["e_ref"][0])
                self.slider_blocks[name] = st["C"]
                self.frame[name] = (ref(st["C"]), gam)
                self.mass[name] = (SLIDER_BODY_KG, np.zeros(2), 1e-9)
                self.parent[name], self.joint[name] = None, ("slide", st["C"], st["e_ref"])
                self.order.append(name)
                other = carrier_of(st["P"])
                hang(st["b1"], st["C"], name)
                self.closures.append((st["b1"], other, st["P"]))
            else:
                hang(st["b1"], st["P"])
                self.parent[st["block"]] = st["guide"]
                self.joint[st["block"]] = ("slide", st["C"], st["e_ref"])
                self.order.append(st["block"])
                self.closures.append((st["b1"], st["block"], st["C"]))

    def local(self, body, point) -> np.ndarray:
        """A reference-configuration point in a body's frame (the world's for None)."""
        if body is None:
            return np.asarray(point, float)
        O, phi = self.frame[body]
        return rot2(-phi) @ (np.asarray(point, float) - O)
