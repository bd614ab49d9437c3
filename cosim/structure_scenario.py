"""General planar structures held at one configuration: a scenario format and its static run.

A scenario with ``[linkage] type = "structure"`` describes any planar mechanism frozen at one
position (Shin's multiloop examples): joints with positions and supports, links running through a
path of joints, rigid plates, springs, slider joints and loads. The format has one home:
docs/scenario-format.md, "Structures held at one position". Topology errors name the item.

Owns: the ``type = "structure"`` format and its static run. Boundaries: no time-domain runs.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tmm_core import Joint, LoadCase, Member, Structure, TMMError, external_resultant, solve_static, surface_stresses
from tmm_core.structure import RigidBody, SliderJoint

from .files import write_atomic
from .joint_tables import joint_checker, joint_position, read_loads, read_springs
from .runlog import run_folder, write_csv, write_json
from .scenario_reader import MAX_SEGMENTS
from .scenario_types import Variants

ANALYSES = ("linear", "beam_column", "large_deflection")


@dataclass(frozen=True)
class StaticScenario(Variants):
    """A resolved structure scenario (SI)."""

    name: str
    description: str
    path: Path | None
    sources: tuple
    structure: Structure
    case: LoadCase
    analysis: str
    parts: dict               # {link: [member names in path order]}
    key_nodes: dict           # {joint: [(member, node index)]}
    assumptions: tuple
    raw: dict = field(repr=False, default_factory=dict)
    rig: str | None = None
    kind: str = "structure"
    #: The loader that built it, which builds its variants (:class:`cosim.scenario_types.Variants`).
    loader: object = field(default=None, repr=False, compare=False)


def _joints(r, top: dict) -> tuple:
    """``(positions {joint: (x, y) [m]}, [Joint])`` of the ``[joints.*]`` tables: position,
    support and the support's direction [rad]."""
    joints_raw = r.names(top.get("joints", {}), "joints")
    if not joints_raw:
        raise r.fail("joints", "a structure needs [joints.<name>] tables")
    positions, joints = {}, []
    for name, d in joints_raw.items():
        key = f"joints.{name}"
        d = r.table(d, key, {"position", "support", "direction"}, {"position"})
        positions[name] = joint_position(r, d, key)
        support = r.number(d.get("support", "free"), f"{key}.support",
                           choices=("free", "pinned", "clamped", "slider", "sliding_clamp"))
        joints.append(Joint(name, support, r.quantity(d.get("direction", "0 deg"), f"{key}.direction", "rad")))
    return positions, joints


@dataclass(frozen=True)
class _Frame:
    """What a link of the format is built on: the joints' positions [m], the check of a joint's
    name, the clamped joints, and the sections and materials by name."""

    positions: dict
    joint_ref: Callable
    clamped: frozenset
    sections: dict
    materials: dict


def _named(r, table: dict, key: str, kind: str, defined: dict):
    """The section or material a link names, refused naming the ones defined."""
    found = defined.get(r.text(table[kind], f"{key}.{kind}"))
    if found is None:
        raise r.fail(f"{key}.{kind}", f"unknown {kind} (defined: {', '.join(sorted(defined)) or 'none'})",
                     table[kind])
    return found


def _link_members(r, name: str, d: dict, frame: _Frame) -> list:
    """The members of link ``name``: one per pair of consecutive joints of its path, pinned at
    its two ends unless welded there or clamped, rigidly joined along the path."""
    key = f"links.{name}"
    d = r.table(d, key, {"path", "section", "material", "segments", "welded_at"}, {"path", "section", "material"})
    route = r.unwrap(d["path"], f"{key}.path")
    if not isinstance(route, list) or len(route) < 2:
        raise r.fail(f"{key}.path", "must list at least two joints", route)
    route = [frame.joint_ref(j, f"{key}.path") for j in route]
    sec = _named(r, d, key, "section", frame.sections)
    mat = _named(r, d, key, "material", frame.materials)
    n = r.number(d.get("segments", 4), f"{key}.segments", int, positive=True)
    if n > MAX_SEGMENTS:
        raise r.fail(f"{key}.segments", f"must be at most {MAX_SEGMENTS}", n)
    welds = r.unwrap(d.get("welded_at", []), f"{key}.welded_at")
    if not isinstance(welds, list):
        raise r.fail(f"{key}.welded_at", "must be a list of joints", welds)
    welded = {frame.joint_ref(j, f"{key}.welded_at") for j in welds}
    members = []
    for i, (a, b) in enumerate(zip(route[:-1], route[1:])):
        L = float(np.linalg.norm(frame.positions[b] - frame.positions[a]))
        if L <= 0:
            raise r.fail(f"{key}.path", f"joints '{a}' and '{b}' coincide", route)
        start = "rigid" if (i > 0 or a in welded or a in frame.clamped) else "pin"
        end = "rigid" if (i < len(route) - 2 or b in welded or b in frame.clamped) else "pin"
        mname = name if len(route) == 2 else f"{name}[{a}-{b}]"
        members.append(Member.uniform(mname, a, b, L, n, sec, mat, start_connection=start, end_connection=end))
    return members


def _plates(r, top: dict, joint_ref) -> list:
    """The rigid plates of ``[plates.*]``: a centroid joint and vertex joints (a joint is the
    vertex of one plate at most)."""
    plates, seen = [], {}
    for name, d in r.names(top.get("plates", {}), "plates").items():
        key = f"plates.{name}"
        d = r.table(d, key, {"centroid", "vertices"}, {"centroid", "vertices"})
        verts = r.unwrap(d["vertices"], f"{key}.vertices")
        if not isinstance(verts, list) or not verts:
            raise r.fail(f"{key}.vertices", "must list the plate's vertex joints", verts)
        for v in verts:
            joint_ref(v, f"{key}.vertices")
            if v in seen:
                raise r.fail(f"{key}.vertices", f"joint '{v}' is already a vertex of plate '{seen[v]}'", v)
            seen[v] = name
        plates.append(RigidBody(name, joint_ref(d["centroid"], f"{key}.centroid"), tuple(verts)))
    return plates


def _sliders(r, top: dict, joint_ref, members: list, parts: dict) -> list:
    """The slider joints of ``[sliders.*]``: a block joint sliding along a link at its guide joint."""
    sliders = []
    for name, d in r.names(top.get("sliders", {}), "sliders").items():
        key = f"sliders.{name}"
        d = r.table(d, key, {"block", "guide", "along"}, {"block", "guide", "along"})
        link = r.text(d["along"], f"{key}.along")
        if link not in parts:
            raise r.fail(f"{key}.along", f"unknown link (links: {', '.join(sorted(parts))})", link)
        guide = joint_ref(d["guide"], f"{key}.guide")
        member = next((m for m in members if m.name in parts[link] and guide in (m.start, m.end)), None)
        if member is None:
            raise r.fail(f"{key}.guide", f"joint '{guide}' is not on link '{link}'", guide)
        sliders.append(SliderJoint(name, joint_ref(d["block"], f"{key}.block"), guide, member.name))
    return sliders


def _key_nodes(members: list) -> dict:
    """``{joint: [(member, node index)]}``: the member ends at each joint."""
    key_nodes = {}
    for m in members:
        key_nodes.setdefault(m.start, []).append((m.name, 0))
        key_nodes.setdefault(m.end, []).append((m.name, m.n_segments))
    return key_nodes


def build(r, top: dict, path: str, default_name: str, materials: dict, sections: dict, meta: dict):
    """Build a :class:`StaticScenario` from the TOML tree (``r`` is the scenario reader)."""
    lk = r.table(top["linkage"], "linkage", {"type", "analysis"}, {"type"})
    for unused in ("drive", "gauges", "gravity", "solver", "output", "motor", "coupling", "uncertainty", "modules"):
        if unused in top:      # a structure at one position has no motion: the table would be ignored
            raise r.fail(unused, "a structure held at one position (linkage.type = \"structure\") has no "
                                 f"[{unused}]: remove it")
    analysis = r.number(lk.get("analysis", "beam_column"), "linkage.analysis", choices=ANALYSES)
    positions, joints = _joints(r, top)
    joint_ref = joint_checker(r, positions)
    clamped = frozenset(j.name for j in joints if j.support in ("clamped", "sliding_clamp"))
    frame = _Frame(positions, joint_ref, clamped, sections, materials)
    members, parts = [], {}
    for name, d in r.names(top.get("links", {}), "links").items():
        own = _link_members(r, name, d, frame)
        members += own
        parts[name] = [m.name for m in own]
    plates = _plates(r, top, joint_ref)
    springs = read_springs(r, top, joint_ref)
    sliders = _sliders(r, top, joint_ref, members, parts)
    loads = {}
    for key, d, vec in read_loads(r, top, {"joint", "link", "position", "force", "moment"}):
        member, node = _load_node(r, key, d, members, parts, positions)
        loads.setdefault(member.name, np.zeros((member.n_segments + 1, 3)))[node] += vec
    try:
        structure = Structure(tuple(joints), tuple(members), tuple(springs), tuple(plates), tuple(sliders))
    except TMMError as exc:
        raise r.fail("linkage", str(exc)) from None
    _check_dangling(r, structure)
    return StaticScenario(str(meta.get("name", default_name)), str(meta.get("description", "")),
                          Path(path) if path != "<dict>" else None, tuple(meta.get("sources", [])), structure,
                          LoadCase(positions, loads), analysis, parts, _key_nodes(members), tuple(r.assumptions),
                          top, str(meta["rig"]) if "rig" in meta else None)


def _load_node(r, key, d, members, parts, positions):
    if "joint" in d:
        j = d["joint"]
        for m in members:
            if m.start == j:
                return m, 0
            if m.end == j:
                return m, m.n_segments
        raise r.fail(f"{key}.joint", "no link ends at this joint (load a link node instead)", j)
    if "link" not in d or "position" not in d:
        raise r.fail(key, "give joint, or link and position")
    link = d["link"]
    if link not in parts:
        raise r.fail(f"{key}.link", f"unknown link (links: {', '.join(sorted(parts))})", link)
    x = r.quantity(d["position"], f"{key}.position", "m", nonnegative=True)
    for mname in parts[link]:
        m = next(mm for mm in members if mm.name == mname)
        st = m.stations
        if x <= st[-1] + 1e-9:
            j = int(np.argmin(np.abs(st - x)))
            if abs(st[j] - x) > 1e-6 * max(st[-1], 1.0):
                raise r.fail(f"{key}.position", f"not at a node of link '{link}' (nodes every {st[1]:.6g} m)",
                             d["position"])
            return m, j
        x -= st[-1]
    raise r.fail(f"{key}.position", f"beyond the end of link '{link}'", d["position"])


def _check_dangling(r, structure: Structure):
    """A link end at a revolute that nothing else holds turns freely: a mechanism, not a structure."""
    holds = {}
    for m in structure.members:
        for j, conn in ((m.start, m.start_connection), (m.end, m.end_connection)):
            holds.setdefault(j, []).append((m.name, conn))
    other = {sp.a for sp in structure.springs} | {sp.b for sp in structure.springs}
    for b in structure.rigid_bodies:
        other |= {b.master, *b.slaves}
    for s in structure.sliders:
        other |= {s.block, s.guide}
    for j in structure.joints:
        ends = holds.get(j.name, [])
        if j.support == "free" and j.name not in other and len(ends) == 1 and ends[0][1] == "pin":
            raise r.fail(f"links.{ends[0][0].split('[')[0]}", f"dangles at joint '{j.name}': nothing else is attached "
                                                              "there and the end is a revolute (add a support, another "
                                                              "link, or weld it)")


def solve(sc: StaticScenario):
    return solve_static(sc.structure, sc.case, beam_column=sc.analysis != "linear",
                        large_deflection=sc.analysis == "large_deflection", tol=1e-8)


def results(sc: StaticScenario, sol) -> tuple:
    """(rows per node, summary dict) in SI."""
    lin = sol.linear if hasattr(sol, "linear") else sol
    rows = []
    for name, r in lin.members.items():
        top, bottom = surface_stresses(r)
        Sy = [m.yield_strength_Pa for m in r.member.materials]
        if all(v is not None for v in Sy):
            # Per node and side (the two sides of a node can carry different axial forces).
            ys = np.array(Sy)[np.clip(np.arange(r.member.n_segments + 1)[:, None] - (np.arange(2) == 0), 0,
                                      r.member.n_segments - 1)]
            peak = np.maximum(np.abs(top), np.abs(bottom))
            with np.errstate(divide="ignore"):
                sf = np.where(peak > 0, ys / np.where(peak > 0, peak, 1.0), np.inf)
        else:
            sf = np.full(top.shape, np.nan)
        pos, disp = r.node_positions, r.displacement
        for j in range(r.member.n_segments + 1):
            for side, label in ((0, "left"), (1, "right")):
                if (j == 0 and side == 0) or (j == r.member.n_segments and side == 1):
                    continue              # no segment on that side of an end node
                rows.append({"member": name, "node": j, "side": label, "X_m": pos[j, 0], "Y_m": pos[j, 1],
                             "dX_m": disp[j, 0], "dY_m": disp[j, 1],
                             "distortion_m": float(np.hypot(*disp[j])), "M_Nm": r.M[j, side], "V_N": r.V[j, side],
                             "N_N": r.N[j, side], "sigma_top_Pa": top[j, side], "sigma_bottom_Pa": bottom[j, side],
                             "safety_factor": sf[j, side]})
    worst = min(rows, key=lambda x: x["safety_factor"] if x["safety_factor"] == x["safety_factor"] else np.inf)
    biggest = max(rows, key=lambda x: x["distortion_m"])
    # Beam-column and large-deflection equilibrium holds about the deformed positions.
    resultant = external_resultant(sol, deformed=sc.analysis != "linear")
    summary = {
        "scenario": sc.name, "kind": "structure", "status": "completed", "analysis": sc.analysis,
        "iterations": int(getattr(sol, "iterations", 1)),
        "joints": {j: {"dX_m": float(v[0]), "dY_m": float(v[1])} for j, v in lin.joint_displacement.items()},
        "reactions": {j: {"Fx_N": float(v[0]), "Fy_N": float(v[1]), "M_Nm": float(v[2])}
                      for j, v in lin.reactions.items()},
        "spring_forces_N": {k: float(v) for k, v in lin.spring_forces.items()},
        "max_distortion": {"member": biggest["member"], "node": biggest["node"], "value_m": biggest["distortion_m"]},
        "min_safety_factor": {"member": worst["member"], "node": worst["node"], "side": worst["side"],
                              "value": worst["safety_factor"]},
        "equilibrium_residual": {"Fx_N": float(resultant[0]), "Fy_N": float(resultant[1]),
                                 "M_Nm": float(resultant[2])},
    }
    return rows, summary


def run_static(sc: StaticScenario, out=None) -> tuple:
    """Solve and write ``nodes.csv``, ``summary.json`` and ``scenario.resolved.toml`` to the run folder."""
    import tomli_w

    folder = run_folder(sc.name, out)
    write_atomic(folder / "scenario.resolved.toml", tomli_w.dumps(
        {"scenario": {"name": sc.name, "description": sc.description, "analysis": sc.analysis},
         "assumptions": [{"key": a.key, "value": a.value, "rationale": a.rationale} for a in sc.assumptions],
         "input": sc.raw}))
    write_json(folder / "summary.json", {"scenario": sc.name, "kind": "structure", "status": "incomplete"})
    sol = solve(sc)
    rows, summary = results(sc, sol)
    write_csv(folder / "nodes.csv", rows)
    write_json(folder / "summary.json", summary)
    return folder, summary


def summary_table(summary: dict) -> str:
    lines = [f"scenario {summary['scenario']}  static {summary['analysis']} analysis ({summary['iterations']} "
             f"iterations)", "", "joint displacements [mm]"]
    for j, d in summary["joints"].items():
        lines.append(f"  {j:>6}  dX {1e3 * d['dX_m']:+10.4f}  dY {1e3 * d['dY_m']:+10.4f}")
    lines += ["", "reactions [N, N m]"]
    for j, v in summary["reactions"].items():
        lines.append(f"  {j:>6}  Fx {v['Fx_N']:+10.3f}  Fy {v['Fy_N']:+10.3f}  M {v['M_Nm']:+10.4f}")
    if summary["spring_forces_N"]:
        lines += ["", "spring forces (tension +) [N]"] + [f"  {k}: {v:+.3f}" for k, v in summary["spring_forces_N"].items()]
    md, sf = summary["max_distortion"], summary["min_safety_factor"]
    lines += ["", f"max distortion {1e3 * md['value_m']:.4f} mm at {md['member']} node {md['node']}",
              f"min safety factor {sf['value']:.4g} at {sf['member']} node {sf['node']} ({sf['side']} side)",
              f"equilibrium residual {summary['equilibrium_residual']}"]
    return "\n".join(lines)
