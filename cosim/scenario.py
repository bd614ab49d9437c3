"""Scenario description: a TOML file mapped to frozen dataclasses in SI units.

One scenario feeds every engine: the loader builds a :class:`tmm_core.FourBarMechanism` (links,
sections, materials, point masses, end blocks, damping, viscoelastic law) that the transfer-matrix,
exudyn and MuJoCo engines all read, so geometry and material are written once.

Units are converted here, at the boundary, with pint. A physical value is a string with a unit
(``"7 in"``, ``"10.3e6 psi"``, ``"5.292 slug/ft^3"``, ``"373 rpm"``), or a table
``{value = "7 in", source = "..."}`` / ``{value = "2 %", assumption = "why this value"}``. Tables
such as ``damping`` or a point mass may carry ``assumption`` / ``source`` keys too. Every
assumption is collected in :attr:`Scenario.assumptions` with its rationale and written into the
run's resolved scenario. Errors name the file, the key and the value.

The file format (every table and key, with units and defaults) is documented in one place:
docs/scenario-format.md.

A file may start with ``extends = "base/<rig>"``: it is merged over that base file.

Time steps (``solver.*.step``, ``coupling.macro_step``) are written in seconds or as a crank
angle ("1 deg"), which is converted with the drive speed. The macro step must be a whole multiple
of every engine's step.
"""
from __future__ import annotations

import dataclasses
import logging
import math
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from tmm_core import FourBarMechanism, Gauge, SliderCrankMechanism, TMMError
from tmm_core.closed_forms import first_bending_frequency_Hz

from . import scenario_reader as rd
from .linkage_scenario import build_mechanism
from .motor_design import motor as read_motor
from .overrides import OverrideError, apply_overrides, set_key
# SCENARIO_DIR and scenario_names stay importable from here (scripts and tests use them).
from .scenario_files import SCENARIO_DIR, ScenarioFileError, read_with_bases, scenario_names
from .scenario_reader import G0, Reader
# The data types live in scenario_types; they stay importable from here, with the unit registry.
from .scenario_types import (Assumption, CouplingSettings, DriveSpec, ExudynSettings, MujocoSettings,  # noqa: F401
                             OutputSettings, Scenario, ScenarioError, TMMSettings, Variants)
from .structure_scenario import StaticScenario, build as build_structure
from .unknowns_table import declared, variant
from .units import UREG

log = logging.getLogger(__name__)


#: Mechanism types: four-bar or slider-crank main loops (motion), a general linkage in motion
#: (closed-form modules, sub-loops, plates, sliders: :mod:`cosim.linkage_scenario`), or a general
#: structure held at one position (static analysis).
LINKAGE_TYPES = ("four-bar", "slider-crank", "linkage", "structure")


#: The tables of a run folder's ``scenario.resolved.toml`` (:func:`resolved`), by which
#: :func:`load` knows one: a scenario file has none of ``resolved`` and ``input``.
AS_RUN_TABLES = frozenset({"scenario", "resolved", "input"})


def load(path_or_name) -> Scenario | StaticScenario:
    """Load a scenario from a path or from the name of a file in ``scenarios/``; a loaded
    scenario of any kind (a variant made with ``with_overrides``) is returned as it is. A run
    folder's ``scenario.resolved.toml`` loads as the scenario that run ran (its ``[input]``)."""
    if isinstance(path_or_name, Variants):
        return path_or_name
    path = Path(path_or_name)
    if not path.suffix:
        path = SCENARIO_DIR / f"{path_or_name}.toml"
    if not path.exists():
        available = ", ".join(scenario_names())
        raise ScenarioError(f"scenario '{path_or_name}' not found (file {path}); available: {available}")
    if path.is_dir():
        raise ScenarioError(f"scenario '{path_or_name}': is a folder, not a scenario file")
    try:
        data = read_with_bases(path)
    except ScenarioFileError as exc:
        raise ScenarioError(str(exc)) from None
    if AS_RUN_TABLES <= data.keys():
        # A run folder's scenario.resolved.toml (:func:`resolved`): the scenario it ran, overrides
        # included, is its [input]; the rest is the record of what that made.
        return from_dict(data["input"], str(path), default_name=data["scenario"].get("name") or path.stem)
    return from_dict(data, str(path), default_name=path.stem)


def from_dict(data: dict, path: str = "<dict>", default_name: str = "scenario") -> Scenario | StaticScenario:
    """Build a scenario from parsed TOML data (``path`` is only used in messages): a
    :class:`Scenario` for a mechanism in motion (``kind`` 'four-bar', 'slider-crank' or 'linkage',
    its ``mechanism`` of the matching type), a :class:`cosim.structure_scenario.StaticScenario`
    for a ``type = "structure"`` held at one position."""
    r = Reader(path)
    top = r.table(data, "", {"scenario", "linkage", "materials", "sections", "links", "drive", "gravity", "gauges",
                             "solver", "output", "motor", "coupling", "joints", "plates", "springs", "sliders",
                             "loads", "uncertainty", "modules"}, {"linkage", "links"})
    meta = r.table(top.get("scenario", {}), "scenario", {"name", "description", "sources", "rig"})
    sc_name, description, sources, rig = _meta(r, meta, default_name)
    solver = r.table(top.get("solver", {}), "solver", {"tmm", "exudyn", "mujoco"})
    tmm = rd.tmm_settings(r, solver.get("tmm", {}))

    mats_raw = r.names(top.get("materials", {}), "materials")
    materials = {k: rd.material(r, k, v) for k, v in mats_raw.items()}
    viscos = {}
    for k, v in mats_raw.items():
        sls = rd.viscoelastic(r, k, v)
        if sls is not None:
            if not np.isclose(sls.instantaneous_modulus_Pa, materials[k].E_Pa, rtol=1e-9):
                raise r.fail(f"materials.{k}.E", "must equal viscoelastic.instantaneous_modulus for a viscoelastic "
                                                 "material", v["E"])
            viscos[k] = sls
    secs_raw = r.names(top.get("sections", {}), "sections")
    sections = {k: rd.section(r, k, v) for k, v in secs_raw.items()}

    if not isinstance(top["linkage"], dict):
        raise r.fail("linkage", "must be a table (type = \"four-bar\", ...)", top["linkage"])
    if "type" not in top["linkage"]:
        raise r.fail("linkage.type", f"is required (one of {', '.join(LINKAGE_TYPES)})")
    kind = r.number(top["linkage"]["type"], "linkage.type", choices=LINKAGE_TYPES)
    if kind == "structure":
        return dataclasses.replace(build_structure(r, top, path, default_name, materials, sections, meta),
                                   loader=from_dict)
    if "modules" in top and kind != "linkage":
        raise r.fail("modules", f"only a 'linkage' has [[modules]] (this one is a {kind})")
    if kind == "linkage":
        mech, gauge_link = build_mechanism(r, top, materials, sections, viscos, tmm.segments)
    else:
        mech, gauge_link = _main_loop(r, top, kind, materials, sections, viscos, tmm.segments)

    drive = rd.drive(r, top.get("drive", {}))
    if not drive.speed_rad_s:
        raise r.fail("drive.speed", "is required and must be positive: a linkage in motion needs a crank speed "
                                    "(a structure held at one position is linkage.type = \"structure\")",
                     rd.peek(top.get("drive", {}).get("speed")) if isinstance(top.get("drive"), dict) else None)
    r.speed = drive.speed_rad_s
    if "step" in solver.get("tmm", {}) and tmm.step_rad is not None and not drive.speed_rad_s:
        raise r.fail("solver.tmm.step", "a crank-angle step needs a non-zero drive.speed", solver["tmm"]["step"])
    try:
        mech.motion(np.linspace(0, 2 * np.pi, 73) + drive.start_angle_rad)
    except TMMError as exc:
        raise r.fail("linkage", f"the crank cannot turn a full revolution: {exc}") from None

    gauges = _gauges(r, top, gauge_link)
    gravity = _gravity(r, top)
    exudyn, mujoco = _exudyn_settings(r, solver), _mujoco_settings(r, solver)
    output = _output_settings(r, top)
    motor = read_motor(r, top["motor"], drive, mech) if "motor" in top else None
    if drive.mode == "motor" and motor is None and drive.type != "fmu":
        raise r.fail("drive.mode", "needs a [motor] table", "motor")
    coupling = rd.coupling(r, top.get("coupling", {}))
    _check_steps(r, drive, tmm, exudyn, mujoco, coupling)
    _check_stiffness(r, top, mech, drive)
    if "uncertainty" in top:
        _check_uncertainty(r, top["uncertainty"], path, top, gauges)
    return Scenario(sc_name, description, Path(path) if path != "<dict>" else None, sources, mech, drive,
                    gauges, gravity, tmm, exudyn, mujoco, output, tuple(r.assumptions), data, motor, coupling,
                    rig, loader=from_dict)


def _gauges(r: Reader, top: dict, gauge_link) -> tuple:
    """The ``[gauges.*]``: each on its link (``gauge_link`` checks and places it), face top or bottom."""
    gauges = []
    for name, g in r.names(top.get("gauges", {}), "gauges").items():
        gk = f"gauges.{name}"
        gd = r.table(g, gk, {"link", "position", "face"}, {"link", "position"})
        link, pos = gauge_link(gk, gd)
        gauges.append(Gauge(name, link, pos, r.number(gd.get("face", "top"), f"{gk}.face", choices=("top", "bottom"))))
    return tuple(gauges)


def _gravity(r: Reader, top: dict) -> tuple | None:
    """``[gravity] vector`` [m/s^2], or None without the table."""
    if "gravity" not in top:
        return None
    gv = r.table(top["gravity"], "gravity", {"vector"}, {"vector"})["vector"]
    if not isinstance(gv, list) or len(gv) != 2:
        raise r.fail("gravity.vector", "must be a list of two accelerations", gv)
    return tuple(r.quantity(x, f"gravity.vector[{i}]", "m/s**2") for i, x in enumerate(gv))


def _exudyn_settings(r: Reader, solver: dict) -> ExudynSettings:
    """``[solver.exudyn]``."""
    ex = r.table(solver.get("exudyn", {}), "solver.exudyn", {"elements", "step", "spectral_radius", "newton_tolerance"})
    exudyn = ExudynSettings(
        _at_most(r, r.number(ex.get("elements", 8), "solver.exudyn.elements", int, positive=True),
                 "solver.exudyn.elements", rd.MAX_SEGMENTS),
        rd.step(r, ex.get("step", "1e-4 s"), "solver.exudyn.step"),
        r.number(ex.get("spectral_radius", 0.9), "solver.exudyn.spectral_radius"),
        r.number(ex.get("newton_tolerance", 1e-6), "solver.exudyn.newton_tolerance", positive=True))
    if not 0 <= exudyn.spectral_radius <= 1:
        raise r.fail("solver.exudyn.spectral_radius", "must lie in [0, 1]", exudyn.spectral_radius)
    return exudyn


def _mujoco_settings(r: Reader, solver: dict) -> MujocoSettings:
    """``[solver.mujoco]``."""
    mj = r.table(solver.get("mujoco", {}), "solver.mujoco", {"step", "servo_frequency", "solref_factor", "solimp"})
    if "solimp" in mj and not 0 < r.number(mj["solimp"], "solver.mujoco.solimp") < 1:
        raise r.fail("solver.mujoco.solimp", "must lie between 0 and 1 (MuJoCo's constraint impedance)", mj["solimp"])
    mujoco = MujocoSettings(
        rd.step(r, mj.get("step", "1e-4 s"), "solver.mujoco.step"),
        r.quantity(mj["servo_frequency"], "solver.mujoco.servo_frequency", "Hz", positive=True)
        if "servo_frequency" in mj else None,
        r.number(mj.get("solref_factor", 2.0), "solver.mujoco.solref_factor", positive=True),
        r.number(mj.get("solimp", 0.9999), "solver.mujoco.solimp"))
    return mujoco


def _output_settings(r: Reader, top: dict) -> OutputSettings:
    """``[output]``: run length, default engines and the steady-state test."""
    out = r.table(top.get("output", {}), "output", {"revolutions", "engines", "max_revolutions", "steady_tolerance"})
    engines = r.unwrap(out.get("engines", ["tmm", "exudyn", "mujoco"]), "output.engines")
    if not isinstance(engines, list) or not engines or any(e not in ("tmm", "exudyn", "mujoco") for e in engines):
        raise r.fail("output.engines", "must be a non-empty list of 'tmm', 'exudyn', 'mujoco'", engines)
    if len(set(engines)) != len(engines):
        raise r.fail("output.engines", "names an engine twice", engines)
    output = OutputSettings(r.number(out["revolutions"], "output.revolutions", positive=True)
                            if "revolutions" in out else None, tuple(engines),
                            r.number(out.get("max_revolutions", 30.0), "output.max_revolutions", positive=True),
                            r.quantity(out.get("steady_tolerance", "0.5 %"), "output.steady_tolerance", "",
                                       positive=True))
    if not output.steady_tolerance < 1:
        raise r.fail("output.steady_tolerance", "must be below 100 % (revolutions that differ by more are not "
                                                "steady)", out["steady_tolerance"])
    return output


def _check_steps(r: Reader, drive, tmm, exudyn, mujoco, coupling) -> None:
    """Refuse a time step (an engine's or the macro step) longer than one crank revolution: no
    revolution would be resolved (a step written in seconds where degrees were meant)."""
    period = drive.period_s
    steps = {"solver.tmm.step": tmm.step_s_at(drive.speed_rad_s),
             "solver.exudyn.step": exudyn.step_s, "solver.mujoco.step": mujoco.step_s,
             "coupling.macro_step": coupling.macro_step_s}
    for key, value in steps.items():
        if value is not None and value > period * (1 + 1e-9):
            raise r.fail(key, f"is {value:.4g} s, longer than one crank revolution ({period:.4g} s at the drive "
                              "speed): write it in seconds or as a crank angle below 360 deg")


def _at_most(r: Reader, value, key: str, limit):
    if value > limit:
        raise r.fail(key, f"must be at most {limit}", value)
    return value


#: A scenario's name names its run folders: a plain identifier, never a path.
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,99}$")


def _meta(r: Reader, meta: dict, default_name: str):
    """``(name, description, sources, rig)`` of the ``[scenario]`` table, each checked: the name
    is a plain identifier (it names the run folder: no path, no ``..``)."""
    if "name" in meta:
        name = r.text(meta["name"], "scenario.name")
    else:                       # the file's name, made plain ("my rig.toml" -> "my_rig")
        name = re.sub(r"[^A-Za-z0-9_.-]", "_", str(default_name)).strip("._-")[:100] or "scenario"
    if not NAME_PATTERN.match(name) or ".." in name:
        raise r.fail("scenario.name",
                     "must be a plain name of letters, digits, '_', '-' and '.' (it names the run folder; no path)",
                     name)
    description = r.text(meta.get("description", ""), "scenario.description")
    sources = r.unwrap(meta.get("sources", []), "scenario.sources")
    if isinstance(sources, str):
        sources = [sources]
    if not isinstance(sources, list) or not all(isinstance(x, str) for x in sources):
        raise r.fail("scenario.sources", "must be a string or a list of strings", sources)
    rig = r.text(meta["rig"], "scenario.rig") if "rig" in meta else None
    return name, description, tuple(sources), rig


#: The values a structural link's material and section take (outside them a number was written in
#: the wrong unit): a modulus of 0.1-1000 GPa [Pa], a density at most 30 000 kg/m^3 (osmium is
#: 22 600) and a slenderness (length over the section's radius of gyration) at most 3000 (a strip
#: 1 m long and 1 mm deep). Only the ends that lower the bending frequency are checked.
STRUCTURAL_E_PA = (1e8, 1e12)
STRUCTURAL_MAX_DENSITY = 3e4
STRUCTURAL_MAX_SLENDERNESS = 3000.0


def _soft_link_key(top: dict, link) -> tuple[str, object, str]:
    """``(key, written value, what to check)`` of the value that puts ``link``'s first bending
    frequency below the crank's: its material's modulus or density, or its section's depth
    (inertia when written as area and inertia), whichever lies outside a structural link's
    range; else ``drive.speed`` (a speed no linkage turns at)."""
    mat, E = link.material.name, link.material.E_Pa
    written = top.get("materials", {}).get(mat, {})
    if not STRUCTURAL_E_PA[0] <= E <= STRUCTURAL_E_PA[1]:
        return f"materials.{mat}.E", rd.peek(written.get("E", E)), "the modulus and its unit"
    if link.material.density_kg_m3 > STRUCTURAL_MAX_DENSITY:
        return (f"materials.{mat}.density", rd.peek(written.get("density", link.material.density_kg_m3)),
                "the density and its unit")
    slenderness = link.length_m / math.sqrt(link.section.inertia_m4 / link.section.area_m2)
    sec = rd.peek(top.get("links", {}).get(link.name, {}).get("section"))
    sec_table = top.get("sections", {}).get(sec, {}) if isinstance(sec, str) else {}
    if slenderness > STRUCTURAL_MAX_SLENDERNESS and isinstance(sec_table, dict) and sec_table:
        part = "depth" if "width" in sec_table else "inertia"      # a rectangle bends in plane over its depth
        return (f"sections.{sec}.{part}", rd.peek(sec_table.get(part)),
                f"the section's {part} and its unit: the {link.length_m:.3g} m {link.name} is {slenderness:.3g} "
                "radii of gyration long, a link typically a few hundred")
    return "drive.speed", rd.peek(top.get("drive", {}).get("speed")), "the number and its unit"


def _check_stiffness(r: Reader, top: dict, mech, drive) -> None:
    """Refuse a link far too soft for any linkage (a modulus, density or section written in the
    wrong unit): its first bending frequency (pinned-pinned span) below the crank's turning
    frequency, where the transfer matrices of the turning link overflow. Names the key whose value
    is outside a structural link's range (:func:`_soft_link_key`), the speed if none is."""
    speed = abs(drive.speed_rad_s)
    links = getattr(mech, "links", None)
    if not speed or links is None:
        return
    for link in links():
        if link.rigid:
            continue
        m = link.section.area_m2 * link.material.density_kg_m3
        EI = link.material.E_Pa * link.section.inertia_m4
        if not m > 0:
            continue
        omega1 = 2 * math.pi * first_bending_frequency_Hz(EI, m, link.length_m)      # [rad/s]
        if omega1 < speed:
            key, value, what = _soft_link_key(top, link)
            if key == "drive.speed":
                raise r.fail(key, f"turns the crank at {speed / (2 * math.pi):.3g} Hz, above the {link.name}'s "
                                  f"first bending frequency {omega1 / (2 * math.pi):.3g} Hz: no linkage runs "
                                  f"there (check {what})", value)
            raise r.fail(key, f"the {link.name} is far too soft for a linkage: its first bending frequency "
                              f"{omega1 / (2 * math.pi):.3g} Hz lies below the crank's {speed / (2 * math.pi):.3g} Hz "
                              f"(check {what})", value)
        # Rayleigh coefficients: the modal ratio they give at the link's first mode, below critical
        # like a written ratio (a coefficient in the wrong unit damps every mode away).
        d = link.damping
        zeta = d.mass_per_s / (2 * omega1) + d.stiffness_s * omega1 / 2
        if zeta >= rd.MAX_DAMPING_RATIO:
            part = "stiffness" if d.stiffness_s * omega1 / 2 >= d.mass_per_s / (2 * omega1) else "mass"
            raise r.fail(f"links.{link.name}.damping.{part}",
                         f"gives a damping ratio of {100 * zeta:.3g} % at the {link.name}'s first bending mode "
                         f"({omega1 / (2 * math.pi):.3g} Hz): must be below 100 % (check the coefficient and its unit)")


_UNCERTAINTY_KEYS = {"samples", "seed", "parameters", "identify", "morris_trajectories"}
_UNKNOWN_KEYS = {"keys", "distribution", "unit", "low", "high", "mean", "std", "values", "rationale", "assumption",
                 "source"}


def _check_uncertainty(r: Reader, data, path: str, top: dict, gauges: tuple = ()) -> None:
    """The ``[uncertainty]`` table's keys at load (every command, ``run`` too); its values are
    read by :func:`cosim.unknowns.declared`, which names the key."""
    u = r.table(data, "uncertainty", _UNCERTAINTY_KEYS)
    for k in ("samples", "seed", "morris_trajectories"):
        if k in u and (isinstance(u[k], bool) or not isinstance(u[k], int) or (k != "seed" and u[k] <= 0)):
            raise r.fail(f"uncertainty.{k}", "must be a plain " + ("integer" if k == "seed" else "positive integer"),
                         u[k])
        if k in u and k != "seed" and u[k] > (10_000 if k == "samples" else 1_000):      # each one is a model run
            raise r.fail(f"uncertainty.{k}", f"must be at most {10_000 if k == 'samples' else 1_000}", u[k])
    if "identify" in u and not (isinstance(u["identify"], list) and all(isinstance(x, str) for x in u["identify"])):
        raise r.fail("uncertainty.identify", "must be a list of the names of declared unknowns", u["identify"])
    params = r.names(u.get("parameters", {}), "uncertainty.parameters")
    unknown = [x for x in u.get("identify", []) if x not in params]
    if unknown:
        raise r.fail("uncertainty.identify", f"names no declared unknown (declared: {', '.join(sorted(params)) or 'none'})",
                     unknown[0])
    if "parameters" not in u:
        return
    for name, d in params.items():
        r.table(d, f"uncertainty.parameters.{name}", _UNKNOWN_KEYS, {"keys", "distribution"})
        for k in d["keys"] if isinstance(d["keys"], list) else []:
            if not isinstance(k, str) or k.startswith(("model.", "measurement.")):
                continue
            try:               # a scenario key must lead somewhere in the file (a typo would vary nothing)
                set_key(top, k, 0, write=False)
            except OverrideError as exc:
                raise r.fail(f"uncertainty.parameters.{name}.keys", str(exc), k) from None
    if params:
        declared({"uncertainty": u}, path)          # every value's kind and unit, named by its key


def check_unknowns(sc: Scenario) -> None:
    """Where the ``[uncertainty]`` table is read (``cosim uncertainty``, ``cosim identify``), before
    any sample runs: every unknown at the edges of its range makes a scenario the loader accepts
    (a wrong unit, value or gauge name is refused under its own key, not found by every sample
    failing). Not at load: a variant that drops what an unknown varies (the gauges of a quick
    engine test) is a scenario of its own, and the check loads the scenario a few times more."""
    raw = sc.raw
    if not isinstance(raw.get("uncertainty"), dict) or not raw["uncertainty"].get("parameters"):
        return
    path = str(sc.path or sc.name)
    _check_unknowns(Reader(path), raw, declared(raw, path)[2], tuple(sc.gauges))


def _bound_samples(spec) -> dict:
    """The values an unknown takes at the edges of its range, by the key that declares them."""
    if spec.discrete:
        return {"values": list(spec.values)}
    if spec.distribution == "normal":
        return {"mean": [spec.mean - 2 * spec.std, spec.mean + 2 * spec.std]}
    return {"low": [spec.low], "high": [spec.high]}


def _check_unknowns(r: Reader, top: dict, unknowns: dict, gauges: tuple) -> None:
    """Every unknown at the edges of its range is a scenario the loader accepts: a wrong unit,
    value or key in ``[uncertainty]`` is refused at load under its own key (it passed ``cosim
    run``, which ignores the table, and then failed every sample of ``cosim uncertainty``)."""
    scenario = SimpleNamespace(gauges=gauges, name=r.path, path=r.path)      # what variant() reads of one
    base = {k: v for k, v in top.items() if k != "uncertainty"}
    # (unknown, key, value, side): the low edges are side 0, the high ones side 1, a choice's k-th value side k
    edges = [(name, which, x, k if which == "values" else (which == "high") + k)
             for name, spec in unknowns.items() for which, values in _bound_samples(spec).items()
             for k, x in enumerate(values)]
    sides = {}                                      # one load a side, every unknown at that edge together
    for name, which, x, side in edges:
        try:
            sides.setdefault(side, {}).update(variant(scenario, unknowns, {name: x}).overrides)
        except ScenarioError as exc:
            raise r.fail(f"uncertainty.parameters.{name}.{which}", _short(str(exc)), x) from None
    try:
        for overrides in sides.values():
            if overrides:
                from_dict(apply_overrides(base, overrides), r.path)
    except ScenarioError:                           # one at a time, to name the unknown
        for name, which, x, _ in edges:
            try:
                from_dict(apply_overrides(base, variant(scenario, unknowns, {name: x}).overrides), r.path)
            except ScenarioError as exc:
                raise r.fail(f"uncertainty.parameters.{name}.{which}", f"at {x!r} {unknowns[name].unit} it makes a "
                             f"scenario the loader refuses: {_short(str(exc))}", x) from None


def _short(text: str, limit: int = 300) -> str:
    """``text`` cut to ``limit`` characters (a message quoted inside another)."""
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _main_loop(r: Reader, top: dict, kind: str, materials: dict, sections: dict, viscos: dict, segments: int):
    """The four-bar or slider-crank of a scenario; returns the mechanism and ``gauge_link(key,
    table) -> (link, position_m)`` (a gauge's link and position, checked)."""
    for key in ("joints", "plates", "springs", "sliders", "loads"):
        if key in top:
            raise r.fail(key, f"only a 'structure' or 'linkage' has [{key}] (this one is a {kind})")
    if kind == "slider-crank":
        lk = r.table(top["linkage"], "linkage", {"type", "pivot", "slide_angle", "offset", "branch", "slider_mass",
                                                 "slider_weight"}, {"type"})
    else:
        lk = r.table(top["linkage"], "linkage", {"type", "ground", "pivot", "ground_angle", "branch"}, {"type", "ground"})
    pivot = lk.get("pivot", ["0 m", "0 m"])
    if not isinstance(pivot, list) or len(pivot) != 2:
        raise r.fail("linkage.pivot", "must be a list of two coordinates", pivot)
    pivot = tuple(r.quantity(p, f"linkage.pivot[{i}]", "m") for i, p in enumerate(pivot))
    branch = {"open": 1, "crossed": -1}[r.number(lk.get("branch", "open"), "linkage.branch", choices=("open", "crossed"))]
    names = ("crank", "coupler") if kind == "slider-crank" else ("crank", "coupler", "rocker")
    links_raw = r.table(top["links"], "links", set(names), set(names))
    links = {k: rd.link(r, k, v, sections, materials, viscos, segments) for k, v in links_raw.items()}
    if kind == "slider-crank":
        if "slider_mass" in lk and "slider_weight" in lk:
            raise r.fail("linkage.slider_mass", "give either slider_mass or slider_weight")
        mass = (r.quantity(lk["slider_weight"], "linkage.slider_weight", "N", nonnegative=True) / G0
                if "slider_weight" in lk else
                r.quantity(lk.get("slider_mass", "0 kg"), "linkage.slider_mass", "kg", nonnegative=True))
        mech = SliderCrankMechanism(links["crank"], links["coupler"],
                                    r.quantity(lk.get("offset", "0 m"), "linkage.offset", "m"), pivot,
                                    r.quantity(lk.get("slide_angle", "0 deg"), "linkage.slide_angle", "rad"), branch,
                                    mass)
    else:
        ground = r.quantity(lk["ground"], "linkage.ground", "m", positive=True)
        ground_angle = r.quantity(lk.get("ground_angle", "0 deg"), "linkage.ground_angle", "rad")
        _check_change_point(r, {"links.crank.length": links["crank"].length_m,
                                "links.coupler.length": links["coupler"].length_m,
                                "links.rocker.length": links["rocker"].length_m, "linkage.ground": ground})
        mech = FourBarMechanism(links["crank"], links["coupler"], links["rocker"], ground, pivot, ground_angle, branch)

    def gauge_link(gk, gd):
        link = r.number(gd["link"], f"{gk}.link", choices=names)
        if links[link].rigid:
            raise r.fail(f"{gk}.link", f"the {link} is rigid (links.{link}.rigid = true): a rigid link has no strain",
                         link)
        pos = r.quantity(gd["position"], f"{gk}.position", "m", nonnegative=True)
        if pos > links[link].length_m:
            raise r.fail(f"{gk}.position", f"lies beyond the end of the {link} ({links[link].length_m:.6g} m)",
                         gd["position"])
        return link, pos
    return mech, gauge_link


#: A four-bar whose Grashof sum s + l - (p + q) lies within this fraction of its longest link of
#: zero is a change-point linkage (refused); within NEAR_CHANGE_POINT of it, a warning at load.
CHANGE_POINT, NEAR_CHANGE_POINT = 1e-9, 0.02


def _check_change_point(r: Reader, lengths: dict) -> None:
    """Refuse a change-point four-bar (s + l = p + q: once a revolution all four pivots line up
    and the linkage may fold either way, where its kinematics and the transfer-matrix solve are
    singular) and warn when the sum lies within :data:`NEAR_CHANGE_POINT` of the longest link
    (a near-toggle: large joint forces and strains at that crank angle). Lengths in m."""
    ordered = sorted(lengths.values())
    margin = (ordered[0] + ordered[3]) - (ordered[1] + ordered[2])
    what = ", ".join(f"{k} = {v:.6g} m" for k, v in lengths.items())
    if abs(margin) <= CHANGE_POINT * ordered[3]:
        raise r.fail("linkage", f"is a change-point linkage ({what}: shortest + longest = the other two, s + l = p + "
                                "q): once a revolution all four pivots line up and the linkage may fold either way, "
                                "which no engine can follow; change one of these lengths")
    if abs(margin) <= NEAR_CHANGE_POINT * ordered[3]:
        log.warning("scenario '%s': linkage near a change point (%s: s + l - (p + q) = %.3g m, %.2g %% of the "
                    "longest link): the pivots nearly line up once a revolution, a toggle with large joint forces and "
                    "strains there", r.path, what, margin, 100 * abs(margin) / ordered[3])


def resolved(scenario: Scenario) -> dict:
    """Everything the run used, TOML-ready: ``[resolved]`` holds every value in SI after units,
    defaults and derivations (field names carry the units), ``assumptions`` every declared
    assumption with its rationale, ``[input]`` the file as written (bases merged)."""

    def clean(x):
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return clean({f.name: getattr(x, f.name) for f in dataclasses.fields(x)})
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items() if v is not None}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x if v is not None]
        if isinstance(x, Path):
            return str(x)
        if isinstance(x, UREG.Quantity):           # a typed override, written as the file would write it
            return f"{x.magnitude!r} {x.units:~}"
        if hasattr(x, "item") and getattr(x, "ndim", 1) == 0:
            x = x.item()
        if isinstance(x, np.ndarray):
            return clean(x.tolist())
        if isinstance(x, float) and not math.isfinite(x):
            return str(x)
        return x

    mech = scenario.mechanism
    return {
        "scenario": {"name": scenario.name, "description": scenario.description, "rig": scenario.rig or "",
                     "file": str(scenario.path) if scenario.path else "", "sources": list(scenario.sources)},
        "resolved": clean({
            "linkage": {k: v for k, v in (("type", type(mech).__name__), ("ground_m", getattr(mech, "ground_m", None)),
                                          ("offset_m", getattr(mech, "offset_m", None)),
                                          ("slider_mass_kg", getattr(mech, "slider_mass_kg", None)),
                                          ("pivot_m", list(mech.pivot)), ("ground_angle_rad", mech.ground_angle),
                                          ("branch", None if not hasattr(mech, "branch")
                                           else "open" if mech.branch == 1 else "crossed")) if v is not None},
            "links": {link.name: link for link in mech.links()},
            "drive": {**dataclasses.asdict(scenario.drive), "speed_rpm": scenario.drive.speed_rpm}, "gauges": {g.name: g for g in scenario.gauges},
            "gravity_m_s2": list(scenario.gravity) if scenario.gravity else None,
            "solver": {"tmm": scenario.tmm, "exudyn": scenario.exudyn, "mujoco": scenario.mujoco},
            "motor": scenario.motor, "coupling": scenario.coupling, "output": scenario.output}),
        "assumptions": [{"key": a.key, "value": a.value, "rationale": a.rationale} for a in scenario.assumptions],
        "input": clean(scenario.raw),
    }
