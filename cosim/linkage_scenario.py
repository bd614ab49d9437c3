"""The ``type = "linkage"`` scenario format: any planar linkage in motion, no code per mechanism.

A linkage is drawn once, assembled, at a reference position (joint coordinates); its motion comes
from an ordered list of closed-form modules (Shin's component-module approach,
:mod:`tmm_core.linkage`), each placing joints from joints already placed. The format (joints,
links, plates, sliders, springs, loads, modules and their branches, Shin's component types, the
load-time assembly and toggle check) has one home: docs/scenario-format.md, "Linkages in motion"
and "Every table of a linkage in motion".

Owns: the ``type = "linkage"`` format and its load-time assembly check. Boundaries: no run logic;
shared springs and loads are cosim.joint_tables.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tmm_core import Damping, Link, PointMass, TMMError
from tmm_core.linkage import (MODULE_KINDS, GuidedSlider, LinkageKinematics, LinkageMechanism, Module, Plate,
                              carrier_link, polygon_properties)

from .joint_tables import joint_checker, joint_position, read_loads, read_springs
from .scenario_reader import G0, MAX_SEGMENTS, damping as damping_reader

SUPPORTS = ("free", "pinned", "slider")
REVOLUTION_CHECK = 1440
#: A module whose links come this close to a toggle [deg] somewhere in a revolution locks there
#: (its joint forces grow without bound): the loader refuses it.
LOCK_ANGLE_DEG = 0.5


def build_mechanism(r, top: dict, materials: dict, sections: dict, viscos: dict, segments: int):
    """Build the :class:`LinkageMechanism` of a ``type = "linkage"`` scenario. Returns the
    mechanism and ``gauge_link(key, table) -> (member, position_m)``, which places a gauge given
    along a link's path on the part that holds it.

    In order: the joints, the links' paths, the slider blocks on moving guides, the kinematic
    bodies (links welded together move as one), the plates, the slides, the modules and the
    kinematics (checked over a revolution), the members (link parts), springs and loads."""
    lk = r.table(top["linkage"], "linkage", {"type", "crank", "crank_zero"}, {"type", "crank"})
    crank_name = r.text(lk["crank"], "linkage.crank")
    crank_zero = r.quantity(lk.get("crank_zero", "0 deg"), "linkage.crank_zero", "rad")
    jt = _joints(r, top)
    paths, welded, link_data = _paths(r, top, crank_name, jt)
    guided_specs = _guided_specs(r, top, paths, jt)
    body_name, bodies, weld_at = _bodies(paths, welded, guided_specs)
    plate_specs = _plates(r, top, materials, jt, paths, bodies)
    guided = _slides(r, guided_specs, paths, jt, body_name, weld_at)
    modules = _modules(r, top, crank_name, paths[crank_name], jt, body_name, bodies, plate_specs, guided)
    kin = _kinematics(r, jt, bodies, body_name, crank_name, paths[crank_name], modules, crank_zero, guided)
    members, frames, part_of = _members(r, paths, link_data, materials, sections, viscos, segments, crank_name,
                                        jt, welded, guided_specs, body_name)
    plates, sliders = _carried(jt, members, frames, part_of, paths, plate_specs, guided_specs)
    mech = _mechanism(r, top, jt, kin, members, frames, plates, sliders)
    return mech, _gauge_placer(r, members, part_of)


@dataclass(frozen=True)
class _JointTable:
    """The ``[joints]`` of a linkage: drawn positions [m] (a plate's centre of mass is added as a
    joint of its own), supports, slide directions [rad], block masses [kg] (taken by the first
    link end at the block), ``ref(name, key)`` (a joint's name, checked) and the ground joints."""

    positions: dict
    support: dict
    slide_dir: dict
    block_mass: dict
    ref: object
    ground: frozenset


def _mass(r, d: dict, key: str) -> float:
    """A ``mass`` or ``weight`` (exactly one) [kg]."""
    if ("mass" in d) == ("weight" in d):
        raise r.fail(key, "give exactly one of mass and weight")
    return (r.quantity(d["mass"], f"{key}.mass", "kg", nonnegative=True) if "mass" in d
            else r.quantity(d["weight"], f"{key}.weight", "N", nonnegative=True) / G0)


def _joints(r, top: dict) -> _JointTable:
    """The ``[joints.*]`` tables."""
    joints_raw = r.names(top.get("joints", {}), "joints")
    if not joints_raw:
        raise r.fail("joints", "a linkage needs [joints.<name>] tables (positions in the drawn configuration)")
    positions, support, slide_dir, block_mass = {}, {}, {}, {}
    for name, d in joints_raw.items():
        key = f"joints.{name}"
        d = r.table(d, key, {"position", "support", "direction", "mass", "weight"}, {"position"})
        positions[name] = joint_position(r, d, key)
        support[name] = r.number(d.get("support", "free"), f"{key}.support", choices=SUPPORTS)
        if support[name] == "slider":
            slide_dir[name] = r.quantity(d.get("direction", "0 deg"), f"{key}.direction", "rad")
        elif "direction" in d:
            raise r.fail(f"{key}.direction", "only a joint with support = 'slider' has a slide direction")
        if "mass" in d or "weight" in d:
            if support[name] != "slider":
                raise r.fail(f"{key}.mass", "only a slider joint carries a block mass (put other masses on links)")
            block_mass[name] = _mass(r, d, key)
    ground = frozenset(j for j, s in support.items() if s == "pinned")
    return _JointTable(positions, support, slide_dir, block_mass, joint_checker(r, positions), ground)


def _paths(r, top: dict, crank_name: str, jt: _JointTable) -> tuple:
    """``(paths, welded, tables)`` of the ``[links.*]``: each link's joints in order, the joints
    it is welded at, its table."""
    joint_ref, ground, support = jt.ref, jt.ground, jt.support
    links_raw = r.names(top["links"], "links")
    if crank_name not in links_raw:
        raise r.fail("linkage.crank", f"unknown link (links: {', '.join(sorted(links_raw))})", crank_name)
    paths, welded, link_data = {}, {}, {}
    for name, d in links_raw.items():
        key = f"links.{name}"
        d = r.table(d, key, {"path", "section", "material", "segments", "welded_at", "rigid", "damping",
                             "point_masses"}, {"path", "section", "material"})
        route = r.unwrap(d["path"], f"{key}.path")
        if not isinstance(route, list) or len(route) < 2:
            raise r.fail(f"{key}.path", "must list at least two joints", route)
        route = [joint_ref(j, f"{key}.path") for j in route]
        if len(set(route)) != len(route):
            raise r.fail(f"{key}.path", "lists a joint twice", route)
        paths[name] = route
        welds = r.unwrap(d.get("welded_at", []), f"{key}.welded_at")
        if not isinstance(welds, list):
            raise r.fail(f"{key}.welded_at", "must be a list of joints", welds)
        welded[name] = {joint_ref(j, f"{key}.welded_at") for j in welds}
        for j in welded[name]:
            if j not in (route[0], route[-1]):
                raise r.fail(f"{key}.welded_at", f"joint '{j}' is not an end of the link (interior joints of a path "
                                                 "are continuous already)", j)
            if j in ground:
                raise r.fail(f"{key}.welded_at", f"joint '{j}' is a ground joint: a link welded to the ground does not "
                                                 "move", j)
        link_data[name] = d
    crank_path = paths[crank_name]
    if support[crank_path[0]] != "pinned":
        raise r.fail(f"links.{crank_name}.path", "the crank's path must start at its ground pivot (a joint with "
                                                 f"support 'pinned'); '{crank_path[0]}' is {support[crank_path[0]]}",
                     crank_path)
    return paths, welded, link_data


def _guided_specs(r, top: dict, paths: dict, jt: _JointTable) -> list:
    """The ``[sliders.*]``: (name, block joint, guide joint, guide link, block mass [kg])."""
    joint_ref, support, positions = jt.ref, jt.support, jt.positions
    sliders_raw = r.names(top.get("sliders", {}), "sliders")
    guided_specs = []
    for name, d in sliders_raw.items():
        key = f"sliders.{name}"
        d = r.table(d, key, {"block", "guide", "along", "mass", "weight"}, {"block", "guide", "along"})
        along = r.text(d["along"], f"{key}.along")
        if along not in paths:
            raise r.fail(f"{key}.along", f"unknown link (links: {', '.join(sorted(paths))})", along)
        guide = joint_ref(d["guide"], f"{key}.guide")
        if guide not in paths[along]:
            raise r.fail(f"{key}.guide", f"joint '{guide}' is not on link '{along}'", guide)
        block = joint_ref(d["block"], f"{key}.block")
        if block in paths[along] or support[block] != "free":
            raise r.fail(f"{key}.block", "the block must be a free joint of its own (not on the guide link)", block)
        if np.hypot(*(positions[block] - positions[guide])) > 1e-9 * max(1.0, float(np.hypot(*positions[guide]))):
            raise r.fail(f"{key}.block", f"the block must be drawn at its guide joint '{guide}'", block)
        mass = _mass(r, d, key) if ("mass" in d or "weight" in d) else 0.0
        guided_specs.append((name, block, guide, along, mass))
    return guided_specs


def _bodies(paths: dict, welded: dict, guided_specs: list) -> tuple:
    """Kinematic bodies: links welded together (or to a block) move as one. Returns ``(body of
    each link and block, joints of each body, links welded at each joint)``."""
    blocks = {b: name for name, b, *_ in guided_specs}
    parent = {n: n for n in list(paths) + [f"slider:{s[0]}" for s in guided_specs]}

    def find(x):
        while parent[x] != x:
            x = parent[x]
        return x

    weld_at = {}
    for name, js in welded.items():
        for j in js:
            weld_at.setdefault(j, []).append(name)
    for j, names in weld_at.items():
        group = names + ([f"slider:{blocks[j]}"] if j in blocks else [])
        for other in group[1:]:
            ra, rb = find(group[0]), find(other)
            if ra != rb:
                parent[rb] = ra
    groups = {}
    for n in parent:
        groups.setdefault(find(n), []).append(n)
    body_name, bodies = {}, {}
    for members in groups.values():
        block = next((m for m in members if m.startswith("slider:")), None)
        bname = block.split(":", 1)[1] if block else members[0]
        js = []
        for m in members:
            for j in (paths[m] if m in paths else [next(s[1] for s in guided_specs if f"slider:{s[0]}" == m)]):
                if j not in js:
                    js.append(j)
            body_name[m] = bname
        bodies[bname] = tuple(js)
    return body_name, bodies, weld_at


def _plates(r, top: dict, materials: dict, jt: _JointTable, paths: dict, bodies: dict) -> list:
    """The ``[plates.*]``: (name, vertices, centre-of-mass joint, mass [kg], inertia [kg m^2],
    material). Each plate becomes a body; a centre of mass not drawn as a joint is added as one."""
    joint_ref, positions = jt.ref, jt.positions
    plates_raw = r.names(top.get("plates", {}), "plates")
    plate_specs = []
    for name, d in plates_raw.items():
        key = f"plates.{name}"
        if name in bodies or name in paths:
            raise r.fail(key, "a plate needs a name of its own (a link has it)")
        d = r.table(d, key, {"vertices", "thickness", "material", "centroid"}, {"vertices", "thickness", "material"})
        verts = r.unwrap(d["vertices"], f"{key}.vertices")
        if not isinstance(verts, list) or len(verts) < 3:
            raise r.fail(f"{key}.vertices", "must list at least three vertex joints, in order around the plate", verts)
        verts = [joint_ref(v, f"{key}.vertices") for v in verts]
        mat = materials.get(r.text(d["material"], f"{key}.material"))
        if mat is None:
            raise r.fail(f"{key}.material", f"unknown material (defined: {', '.join(sorted(materials)) or 'none'})",
                         d["material"])
        thick = r.quantity(d["thickness"], f"{key}.thickness", "m", positive=True)
        try:
            mass, centre, inertia = polygon_properties([positions[v] for v in verts], thick, mat.density_kg_m3)
        except TMMError as exc:
            raise r.fail(f"{key}.vertices", str(exc), verts) from None
        if not mass > 0:
            raise r.fail(f"{key}.material", "the plate has no mass (a material with density is needed)", d["material"])
        if "centroid" in d:
            master = joint_ref(d["centroid"], f"{key}.centroid")
            off = float(np.hypot(*(positions[master] - centre)))
            if off > 1e-3 * max(float(np.hypot(*(positions[v] - centre))) for v in verts):
                raise r.fail(f"{key}.centroid", f"joint '{master}' is {off:.4g} m from the plate's centre of mass "
                                                f"({centre[0]:.6g}, {centre[1]:.6g}) m", master)
            centre = positions[master]
        else:
            master = f"{name}_cm"
            if master in positions:
                raise r.fail(key, f"joint name '{master}' is taken; give the plate a centroid joint")
            positions[master] = centre
        plate_specs.append((name, verts, master, mass, inertia, mat))
        bodies[name] = tuple(verts) + (master,)
    return plate_specs


def _slides(r, guided_specs: list, paths: dict, jt: _JointTable, body_name: dict, weld_at: dict) -> dict:
    """Blocks along moving guides, and ground slider blocks carrying welded links: ``{body:
    (guide body or None for the ground, slide angle [rad])}``."""
    positions, support, slide_dir = jt.positions, jt.support, jt.slide_dir
    guided = {}
    for name, block, guide, along, mass in guided_specs:
        a, b = _part_ends(paths[along], guide)
        d = positions[b] - positions[a]
        guided[body_name[f"slider:{name}"]] = (body_name[along], math.atan2(d[1], d[0]))
    for j, names in weld_at.items():
        if support[j] != "slider":
            continue
        # Links welded at a ground slider joint are welded to its block: they slide without turning.
        b = body_name[names[0]]
        if b in guided:
            other = ("the ground slider joint '" + next(k for k, ns in weld_at.items() if k != j and support[k] ==
                                                        "slider" and body_name[ns[0]] == b) + "'"
                     if guided[b][0] is None else f"a block along link '{guided[b][0]}'")
            raise r.fail(f"links.{names[0]}.welded_at", f"the links welded at the slider joint '{j}' are welded to "
                                                       f"{other} too: a body slides along one guide", j)
        guided[b] = (None, slide_dir[j])
    return guided


def _modules(r, top: dict, crank_name: str, crank_path: list, jt: _JointTable, body_name: dict, bodies: dict,
             plate_specs: list, guided: dict) -> list:
    """The ``[[modules]]``: the ordered closed-form steps that place the joints."""
    joint_ref = jt.ref
    mods_raw = r.unwrap(top.get("modules", []), "modules")
    if not isinstance(mods_raw, list) or not mods_raw:
        raise r.fail("modules", "a linkage needs [[modules]]: the ordered closed-form steps that place its joints")
    link_body = dict(body_name)
    link_body.update({p[0]: p[0] for p in plate_specs})
    modules = []
    for i, m in enumerate(mods_raw):
        key = f"modules[{i}]"
        m = r.table(m, key, {"type", "joint", "link", "links", "branch"}, {"type"})
        kind = r.number(m["type"], f"{key}.type", choices=MODULE_KINDS)
        names = [r.text(m["link"], f"{key}.link")] if "link" in m else r.unwrap(m.get("links", []), f"{key}.links")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise r.fail(f"{key}.links", "must be a list of link names", names)
        want = {"rrr": 2, "prp": 0}.get(kind, 1)
        if len(names) != want:
            raise r.fail(f"{key}.{'links' if kind == 'rrr' else 'link'}",
                         f"a '{kind}' module names {want} link{'s' if want != 1 else ''}"
                         + (" (its slides are its joint's: a slider support, [sliders] blocks at the joint)"
                            if kind == "prp" else ""), names)
        for n in names:
            if n not in link_body:
                raise r.fail(f"{key}.{'link' if 'link' in m else 'links'}",
                             f"unknown link '{n}' (links and plates: {', '.join(sorted(link_body))})", n)
        bnames = tuple(link_body[n] for n in names)
        if kind == "crank":
            if names[0] != crank_name:
                raise r.fail(f"{key}.link", f"the crank module drives linkage.crank ('{crank_name}')", names[0])
            joint = crank_path[1]
        else:
            if "joint" not in m:
                raise r.fail(f"{key}.joint", "is required (the joint the module places)" if kind not in ("rpr", "rpp")
                             else "is required (the joint placed before at which the block is pinned, or where a "
                                  "link welded to the block ends)")
            joint = joint_ref(m["joint"], f"{key}.joint")
        if kind in ("rpr", "rpp"):
            # The block: the body sliding along the named link that holds the joint.
            held = [b for b, (g, _) in guided.items() if g == bnames[0] and joint in bodies[b]]
            if len(held) != 1:
                raise r.fail(f"{key}.joint", f"{'no' if not held else 'more than one'} [sliders] block along link "
                                             f"'{names[0]}' holds joint '{joint}' (pin the block at '{joint}', or "
                                             f"weld to the block a link that ends there)", joint)
            bnames = (held[0], bnames[0])
        branch = r.number(m.get("branch", 0), f"{key}.branch", int)
        if branch not in (-1, 0, 1):
            raise r.fail(f"{key}.branch", "must be 1 or -1 (or left out: the drawn configuration's)", branch)
        try:
            modules.append(Module(kind, joint, bnames, branch))
        except TMMError as exc:
            raise r.fail(key, str(exc)) from None
    if modules[0].kind != "crank":
        raise r.fail("modules[0].type", "the first module is the crank", mods_raw[0].get("type"))
    return modules


def _kinematics(r, jt: _JointTable, bodies: dict, body_name: dict, crank_name: str, crank_path: list,
                modules: list, crank_zero: float, guided: dict) -> LinkageKinematics:
    """The linkage's kinematics, refused unless the crank turns a full revolution."""
    try:
        kin = LinkageKinematics({k: tuple(v) for k, v in jt.positions.items()}, bodies, tuple(sorted(jt.ground)),
                                body_name[crank_name], crank_path[0], crank_path[1], tuple(modules), crank_zero,
                                jt.slide_dir, guided, name=f"linkage '{r.path}'")
    except TMMError as exc:
        raise r.fail("modules", str(exc)) from None
    try:
        # Turned CCW from the drawn position: the first position that fails is where it locks.
        kin.solve(kin.reference_crank_angle + np.linspace(0.0, 2 * math.pi, REVOLUTION_CHECK, endpoint=False),
                  lock_tolerance=math.sin(math.radians(LOCK_ANGLE_DEG)))
    except TMMError as exc:
        raise r.fail("modules", f"the crank cannot turn a full revolution: {exc}") from None
    return kin


def _members(r, paths: dict, link_data: dict, materials: dict, sections: dict, viscos: dict, segments: int,
             crank_name: str, jt: _JointTable, welded: dict, guided_specs: list, body_name: dict) -> tuple:
    """The members (link parts between the joints of a path): ``(members, frame body of each
    member, {link: (member names, start of each part along the link [m])})``."""
    positions, block_mass = jt.positions, jt.block_mass
    members, frames, part_of = [], {}, {}
    for name, route in paths.items():
        d, key = link_data[name], f"links.{name}"
        sec = sections.get(r.text(d["section"], f"{key}.section"))
        if sec is None:
            raise r.fail(f"{key}.section", f"unknown section (defined: {', '.join(sorted(sections)) or 'none'})",
                         d["section"])
        mat_name = r.text(d["material"], f"{key}.material")
        mat = materials.get(mat_name)
        if mat is None:
            raise r.fail(f"{key}.material", f"unknown material (defined: {', '.join(sorted(materials)) or 'none'})",
                         mat_name)
        n = r.number(d.get("segments", segments), f"{key}.segments", int, positive=True)
        if n > MAX_SEGMENTS:
            raise r.fail(f"{key}.segments", f"must be at most {MAX_SEGMENTS}", n)
        rigid = r.number(d.get("rigid", False), f"{key}.rigid", bool)
        if rigid and (name != crank_name or len(route) != 2):
            raise r.fail(f"{key}.rigid", "only a binary crank can be rigid (the transfer-matrix model welds it to its "
                                         "clamped pivot, so its far joint becomes a fixed pin)", True)
        if rigid and "damping" in d:
            raise r.fail(f"{key}.damping", "a rigid link has no elastic motion to damp; remove it", d["damping"])
        damping = damping_reader(r, d["damping"], f"{key}.damping") if "damping" in d else Damping()
        lengths = [float(np.hypot(*(positions[b] - positions[a]))) for a, b in zip(route[:-1], route[1:])]
        for (a, b), L in zip(zip(route[:-1], route[1:]), lengths):
            if L <= 0:
                raise r.fail(f"{key}.path", f"joints '{a}' and '{b}' coincide", route)
        starts = np.concatenate([[0.0], np.cumsum(lengths)])
        pms = r.unwrap(d.get("point_masses", []), f"{key}.point_masses")
        if not isinstance(pms, list):
            raise r.fail(f"{key}.point_masses", "must be a list of tables", pms)
        masses = [[] for _ in lengths]
        for i, pm in enumerate(pms):
            pk = f"{key}.point_masses[{i}]"
            p = r.table(pm, pk, {"position", "mass", "weight", "label"}, {"position"})
            x = r.quantity(p["position"], f"{pk}.position", "m", nonnegative=True)
            k = _part_index(starts, x)
            if k is None:
                raise r.fail(f"{pk}.position", f"lies beyond the end of link '{name}' ({starts[-1]:.6g} m)",
                             p["position"])
            masses[k].append(PointMass(float(np.clip(x - starts[k], 0.0, lengths[k])), _mass(r, p, pk), 0.0,
                                       str(p.get("label", f"{name} mass {i}"))))
        names = []
        for k, (a, b) in enumerate(zip(route[:-1], route[1:])):
            mname = name if len(route) == 2 else f"{name}[{a}-{b}]"
            extra = []
            for j in (a, b):          # a slider block's mass sits on the first link end at the block
                if j in block_mass and not any(j in (mm[1], mm[2]) for mm in members):
                    extra.append(PointMass(0.0 if j == a else lengths[k], block_mass.pop(j), 0.0, f"slider block {j}"))
                for sname, blk, _, _, smass in guided_specs:
                    if blk == j and smass > 0 and not any(j in (mm[1], mm[2]) for mm in members):
                        extra.append(PointMass(0.0 if j == a else lengths[k], smass, 0.0, f"slider block {sname}"))
            try:
                link = Link(mname, lengths[k], sec, mat, n, tuple(masses[k]) + tuple(extra), damping,
                            None if rigid else viscos.get(mat_name), rigid=rigid)
            except TMMError as exc:
                raise r.fail(key, str(exc)) from None
            ca = "rigid" if (k > 0 or a in welded[name] or (name == crank_name and k == 0)) else "pin"
            cb = "rigid" if (k < len(route) - 2 or b in welded[name]) else "pin"
            members.append((link, a, b, ca, cb))
            frames[mname] = body_name[name]
            names.append(mname)
        part_of[name] = (names, starts)
    for j in block_mass:
        raise r.fail(f"joints.{j}.mass", "no link ends at this slider joint")
    return members, frames, part_of


def _carried(jt: _JointTable, members: list, frames: dict, part_of: dict, paths: dict, plate_specs: list,
             guided_specs: list) -> tuple:
    """The plates (each carried by a stiff link from its centre of mass to its first vertex,
    added to ``members``) and the guided sliders (on the part of the guide link at the guide)."""
    positions = jt.positions
    stiffest = max((m[0] for m in members), key=lambda l: l.material.E_Pa * l.section.inertia_m4)
    plates = []
    for name, verts, master, mass, inertia, mat in plate_specs:
        L = float(np.hypot(*(positions[verts[0]] - positions[master])))
        members.append((carrier_link(name, L, stiffest.section, mass, inertia, mat.E_Pa), master, verts[0], "rigid",
                        "pin"))
        frames[name] = name
        plates.append(Plate(name, tuple(verts), master, mass, inertia, name))
    sliders = []
    for name, block, guide, along, _ in guided_specs:
        names, _ = part_of[along]
        a, b = _part_ends(paths[along], guide)
        part = names[0] if len(names) == 1 else f"{along}[{a}-{b}]"
        sliders.append(GuidedSlider(name, block, guide, part))
    return plates, sliders


def _mechanism(r, top: dict, jt: _JointTable, kin, members: list, frames: dict, plates: list,
               sliders: list) -> LinkageMechanism:
    """The mechanism with its springs and loads, checked to make a structure."""
    joint_ref, support = jt.ref, jt.support
    springs = read_springs(r, top, joint_ref)
    loads, plate_names = {}, {p.name for p in plates}
    for key, d, vec in read_loads(r, top, {"joint", "force", "moment"}, {"joint"}):
        j = joint_ref(d["joint"], f"{key}.joint")
        target = next(((m[0], 0 if m[1] == j else m[0].total_segments) for m in members
                       if j in (m[1], m[2]) and not m[0].rigid and m[0].name not in plate_names), None)
        if target is None:
            raise r.fail(f"{key}.joint", "no flexible link ends at this joint", j)
        link, node = target
        loads.setdefault(link.name, np.zeros((link.n_nodes, 3)))[node] += vec

    try:
        mech = LinkageMechanism(kin, tuple(members), frames,
                                {j: s for j, s in support.items() if s != "free"}, tuple(plates), tuple(sliders),
                                tuple(springs), loads, name=f"linkage '{r.path}'")
        mech.structure()
    except TMMError as exc:
        raise r.fail("linkage", str(exc)) from None
    return mech


def _gauge_placer(r, members: list, part_of: dict):
    """``gauge_link(key, table) -> (member, position_m)``: a gauge given along a link's path, on
    the part that holds it."""
    def gauge_link(key, gd):
        link = r.text(gd["link"], f"{key}.link")
        if link not in part_of:
            raise r.fail(f"{key}.link", f"unknown link (links: {', '.join(sorted(part_of))})", link)
        if any(m[0].rigid for m in members if m[0].name in part_of[link][0]):
            raise r.fail(f"{key}.link", f"the {link} is rigid (links.{link}.rigid = true): a rigid link has no strain",
                         link)
        x = r.quantity(gd["position"], f"{key}.position", "m", nonnegative=True)
        names, starts = part_of[link]
        k = _part_index(starts, x)
        if k is None:
            raise r.fail(f"{key}.position", f"lies beyond the end of the {link} ({starts[-1]:.6g} m)", gd["position"])
        return names[k], float(np.clip(x - starts[k], 0.0, starts[k + 1] - starts[k]))
    return gauge_link


def _part_index(starts, x):
    """Index of the part of a path (part k from starts[k] to starts[k+1]) that holds ``x``; a
    joint between two parts belongs to the part that ends there."""
    tol = 1e-6 * float(starts[-1])          # joint coordinates are written to a few significant digits
    if x > starts[-1] + tol:
        return None
    return int(min(len(starts) - 2, max(0, np.searchsorted(starts, x - tol, side="left") - 1)))


def _part_ends(route, guide):
    """The part of a path that a slider runs along at joint ``guide``: the first part with an end
    there (as in :mod:`cosim.structure_scenario`)."""
    i = route.index(guide)
    return (route[i - 1], route[i]) if i > 0 else (route[0], route[1])
