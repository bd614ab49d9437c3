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

File layout (all tables except ``[scenario]``, ``[linkage]``, ``[links.*]`` are optional)::

    [scenario]      name, description, sources, rig (records of that rig are compared)
    [linkage]       type = "four-bar", ground, pivot, ground_angle, branch = "open" | "crossed"
                    type = "slider-crank", pivot, slide_angle, offset, slider_mass | slider_weight, branch
                    type = "linkage" (any planar linkage in motion, with [joints.*], [plates.*],
                    [sliders.*], [springs.*], [loads.*] and [[modules]]): see :mod:`cosim.linkage_scenario`
                    type = "structure": see :mod:`cosim.structure_scenario`
    [materials.X]   E, density, yield_strength, endurance_limit, poisson,
                    viscoelastic = {instantaneous_modulus, relaxed_modulus, relaxation_time}
    [sections.X]    width, depth  (or area, inertia, depth)
    [links.crank|coupler|rocker]
                    length, section, material, segments, point_masses = [{position, mass | weight,
                    inertia, label}], damping = {ratio, frequency} | {stiffness, mass},
                    start_block / end_block = {length, section, material},
                    rigid = true | false (only the crank; its section and material give its mass)
    [drive]         mode = "prescribed" | "motor", speed, rotation = "ccw" | "cw", start_angle
    [gravity]       vector = [gx, gy]
    [gauges.X]      link, position, face = "top" | "bottom"
    [solver.tmm]    segments, integrator, step, beam_column, start,
                    coupling = {coriolis, centrifugal, angular_acceleration} (all true by default),
                    axial_force = "dynamic" (default) | "quasi_static" | "none"
    [solver.exudyn] elements, step, spectral_radius, newton_tolerance
    [solver.mujoco] step, servo_frequency, solref_factor, solimp
    [motor]         rated_power, rated_speed, rated_voltage (derive the constants below that are not
                    given: :func:`cosim.motor.derive_pm_dc_motor`, its knobs efficiency,
                    copper_loss_share, coulomb_share, electrical_time_constant, rotor_inertia_per_power),
                    resistance, inductance, torque_constant, back_emf, rotor_inertia, viscous_friction,
                    coulomb_friction, supply_voltage, gear_ratio, flywheel_inertia | flywheels =
                    [{diameter, thickness, density, count}], shaft_stiffness, shaft_damping,
                    controller = {bandwidth, current_bandwidth, current_limit} | {kp, ki}, setpoint = {profile, start, t0, duration},
                    reversible
    [coupling]      macro_step, scheme = "jacobi" | "gauss_seidel" | "iterated", extrapolation =
                    "constant" | "linear", interface_jacobian, tolerance, max_iterations,
                    start = "steady" | "rest"
    [output]        revolutions (a fixed run length; default: until steady), max_revolutions (30),
                    steady_tolerance ("0.5 %"), engines (the default engines of `cosim run`)
    [uncertainty]   samples, seed, parameters.<name> = {keys, distribution, ...}: see cosim.uncertainty

A file may start with ``extends = "base/<rig>"``: it is merged over that base file.

Time steps (``solver.*.step``, ``coupling.macro_step``) are written in seconds or as a crank
angle ("1 deg"), which is converted with the drive speed. The macro step must be a whole multiple
of every engine's step.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pint

from tmm_core import (Coupling, Damping, FourBarMechanism, Gauge, InputError, Link, Material, PointMass, Section,
                      SliderCrankMechanism, StandardLinearSolid, TMMError)
from tmm_core.mechanism import EndBlock

from .units import UREG, has_number, quantity as _parse_quantity  # noqa: E402  the one unit system
G0 = 9.80665
SCENARIO_DIR = Path(__file__).resolve().parent.parent / "scenarios"


#: Mechanism types: four-bar or slider-crank main loops (motion), a general linkage in motion
#: (closed-form modules, sub-loops, plates, sliders: :mod:`cosim.linkage_scenario`), or a general
#: structure held at one position (static analysis).
LINKAGE_TYPES = ("four-bar", "slider-crank", "linkage", "structure")


class ScenarioError(InputError):
    """A scenario file is malformed; the message names the file, the key and the value."""


@dataclass(frozen=True)
class Assumption:
    """A value the sources do not give, with the reason it was chosen."""

    key: str
    value: str
    rationale: str


@dataclass(frozen=True)
class DriveSpec:
    """Crank drive. ``speed_rad_s`` is signed (CCW positive); ``mode`` 'prescribed' or 'motor'."""

    mode: str = "prescribed"
    speed_rad_s: float = 0.0
    start_angle_rad: float = 0.0


@dataclass(frozen=True)
class TMMSettings:
    segments: int = 8
    integrator: str = "generalized_alpha"
    step_s: float | None = None
    step_rad: float | None = math.radians(1.0)
    beam_column: bool = True
    start: str = "quasi_static"
    coupling: Coupling = Coupling.all()
    axial_force: str = "dynamic"


@dataclass(frozen=True)
class ExudynSettings:
    elements: int = 8
    step_s: float = 1e-4
    spectral_radius: float = 0.9
    newton_tolerance: float = 1e-6


@dataclass(frozen=True)
class MujocoSettings:
    step_s: float = 1e-4
    servo_frequency_Hz: float | None = None
    solref_factor: float = 2.0
    solimp: float = 0.9999


@dataclass(frozen=True)
class CouplingSettings:
    """Co-simulation coupling (see :mod:`cosim.master`). ``macro_step_s`` None: the largest engine
    step, if the others divide it."""

    macro_step_s: float | None = None
    scheme: str = "gauss_seidel"
    extrapolation: str = "linear"
    interface_jacobian: bool = True
    tolerance: float = 1e-6
    max_iterations: int = 20
    start: str = "steady"


@dataclass(frozen=True)
class OutputSettings:
    """``revolutions``: a fixed run length; None (default) runs until every engine is steady
    (its last two revolutions agree to ``steady_tolerance``, :mod:`cosim.metrics`) or until
    ``max_revolutions``."""

    revolutions: float | None = None
    engines: tuple = ("tmm", "exudyn", "mujoco")     # the engines `cosim run` uses by default
    max_revolutions: float = 30.0
    steady_tolerance: float = 0.005


@dataclass(frozen=True)
class Scenario:
    """A resolved scenario, SI throughout."""

    name: str
    description: str
    path: Path | None
    sources: tuple
    mechanism: FourBarMechanism
    drive: DriveSpec
    gauges: tuple
    gravity: tuple | None
    tmm: TMMSettings
    exudyn: ExudynSettings
    mujoco: MujocoSettings
    output: OutputSettings
    assumptions: tuple
    raw: dict = field(repr=False, default_factory=dict)
    motor: object = None                  # cosim.motor.MotorParameters, or None without a [motor] table
    coupling: CouplingSettings = CouplingSettings()
    rig: str | None = None                # the physical rig (records of it are matched by this name)

    def engine_step_s(self, engine: str) -> float:
        """Internal step of an engine [s]."""
        if engine == "tmm":
            if self.tmm.step_s is not None:
                return self.tmm.step_s
            if not self.drive.speed_rad_s:
                raise ScenarioError(f"scenario '{self.path}': key 'solver.tmm.step': a crank-angle step needs a "
                                    "non-zero drive.speed")
            return self.tmm.step_rad / abs(self.drive.speed_rad_s)
        return {"exudyn": self.exudyn.step_s, "mujoco": self.mujoco.step_s}[engine]

    @property
    def crank_speed_rad_s(self) -> float:
        return self.drive.speed_rad_s

    def with_overrides(self, overrides: dict) -> "Scenario":
        """A variant of this scenario with key paths of its file set to new values, e.g.
        ``{"drive.speed": "300 rpm", "links.coupler.damping.ratio": "3 %"}``, validated by the
        loader (its errors name the key). See :mod:`cosim.overrides`."""
        from .overrides import OverrideError, apply_overrides
        label = f"{self.path or self.name} (with {', '.join(f'{k} = {v!r}' for k, v in overrides.items())})"
        try:
            data = apply_overrides(self.raw, overrides)
        except OverrideError as exc:
            raise ScenarioError(f"scenario '{self.path or self.name}': {exc}") from None
        return from_dict(data, label, default_name=self.name)

    @property
    def revolution_period_s(self) -> float:
        return 2 * math.pi / abs(self.drive.speed_rad_s)


# --------------------------------------------------------------------------------------------
class _Reader:
    """Walks the TOML tree, converts values and records assumptions and unknown keys."""

    def __init__(self, path: str):
        self.path = path
        self.speed = 0.0          # drive speed [rad/s], for steps written as crank angles
        self.assumptions: list[Assumption] = []

    def fail(self, key: str, msg: str, value=None) -> ScenarioError:
        shown = "" if value is None else f" = {value!r}"
        return ScenarioError(f"scenario '{self.path}': key '{key}'{shown}: {msg}")

    def table(self, data, key: str, allowed: set[str], required: set[str] = frozenset()) -> dict:
        if not isinstance(data, dict):
            raise self.fail(key, "must be a table", data)
        unknown = set(data) - allowed - {"assumption", "source"}
        if unknown:
            bad = sorted(unknown)[0]
            raise self.fail(f"{key}.{bad}" if key else bad, f"unknown key (allowed: {', '.join(sorted(allowed))})",
                            data[bad])
        missing = required - set(data)
        if missing:
            raise self.fail(f"{key}.{sorted(missing)[0]}" if key else sorted(missing)[0], "is required")
        if "assumption" in data:
            self.assumptions.append(Assumption(key, _short({k: v for k, v in data.items() if k != "assumption"}),
                                               str(data["assumption"])))
        return data

    def _unwrap(self, value, key):
        if isinstance(value, dict) and "value" in value:
            extra = set(value) - {"value", "assumption", "source"}
            if extra:
                raise self.fail(f"{key}.{sorted(extra)[0]}", "unknown key (allowed: value, assumption, source)")
            if "assumption" in value:
                self.assumptions.append(Assumption(key, str(value["value"]), str(value["assumption"])))
            return value["value"]
        return value

    def quantity(self, value, key: str, unit: str, positive: bool = False, nonnegative: bool = False) -> float:
        """A physical value converted to ``unit`` (an SI unit); plain numbers are refused unless
        the unit is dimensionless."""
        raw = self._unwrap(value, key)
        if isinstance(raw, bool):
            raise self.fail(key, f"must be a quantity in {unit}", raw)
        if isinstance(raw, (int, float)):
            if UREG.Quantity(1, unit).dimensionless:
                q = float(raw)
            else:
                raise self.fail(key, f"has no unit; write it with one, e.g. '{raw} {_example_unit(unit)}'", raw)
        elif isinstance(raw, str):
            if not has_number(raw):
                # pint reads a bare unit ("rpm", "psi") as one of it: a number is required.
                raise self.fail(key, f"has no number; write a number and a unit, e.g. '1 {_example_unit(unit)}'", raw)
            try:
                parsed = _parse_quantity(raw)
            except ValueError:
                raise self.fail(key, "is not a quantity with a unit", raw) from None
            target = UREG.Quantity(1, unit)
            if parsed.dimensionless and not target.dimensionless:
                raise self.fail(key, f"has no unit; write it with one, e.g. '{raw} {_example_unit(unit)}'", raw)
            try:
                q = float(parsed.to(unit).magnitude)
            except pint.DimensionalityError:
                raise self.fail(key, f"has the wrong dimension: expected {target.dimensionality}, got "
                                     f"{parsed.dimensionality}", raw) from None
        else:
            raise self.fail(key, f"must be a quantity in {unit}", raw)
        if not math.isfinite(q):
            raise self.fail(key, "must be finite", raw)
        if positive and q <= 0:
            raise self.fail(key, "must be positive", raw)
        if nonnegative and q < 0:
            raise self.fail(key, "must not be negative", raw)
        return q

    def number(self, value, key, kind=float, positive=False, choices=None):
        raw = self._unwrap(value, key)
        if choices is not None:
            if raw not in choices:
                raise self.fail(key, f"must be one of {list(choices)}", raw)
            return raw
        if kind is int:
            if isinstance(raw, bool) or not isinstance(raw, int):
                raise self.fail(key, "must be an integer", raw)
        elif kind is bool:
            if not isinstance(raw, bool):
                raise self.fail(key, "must be true or false", raw)
            return raw
        elif isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise self.fail(key, "must be a number", raw)
        if positive and raw <= 0:
            raise self.fail(key, "must be positive", raw)
        return kind(raw)

    def text(self, value, key):
        raw = self._unwrap(value, key)
        if not isinstance(raw, str):
            raise self.fail(key, "must be a string", raw)
        return raw


def _peek(value):
    """The value of a ``{value = ..., assumption = ...}`` table (or the plain value), unrecorded."""
    return value["value"] if isinstance(value, dict) and "value" in value else value


def _short(d) -> str:
    return ", ".join(f"{k} = {v}" for k, v in d.items())


def _example_unit(unit: str) -> str:
    return {"m": "in", "Pa": "psi", "kg/m**3": "slug/ft^3", "kg": "lb", "s": "s", "rad/s": "rpm",
            "rad": "deg", "Hz": "Hz", "N": "lbf"}.get(unit, unit)


# --------------------------------------------------------------------------------------------
def _material(r: _Reader, name, data) -> Material:
    key = f"materials.{name}"
    d = r.table(data, key, {"E", "density", "yield_strength", "endurance_limit", "poisson", "viscoelastic"},
                {"E", "density"})
    opt = {}
    if "yield_strength" in d:
        opt["yield_strength_Pa"] = r.quantity(d["yield_strength"], f"{key}.yield_strength", "Pa", positive=True)
    if "endurance_limit" in d:
        opt["endurance_limit_Pa"] = r.quantity(d["endurance_limit"], f"{key}.endurance_limit", "Pa", positive=True)
    if "poisson" in d:
        opt["poisson"] = r.number(d["poisson"], f"{key}.poisson")
    return Material(name, r.quantity(d["E"], f"{key}.E", "Pa", positive=True),
                    r.quantity(d["density"], f"{key}.density", "kg/m**3", nonnegative=True), **opt)


def _viscoelastic(r: _Reader, name, data):
    if "viscoelastic" not in data:
        return None
    key = f"materials.{name}.viscoelastic"
    d = r.table(data["viscoelastic"], key, {"instantaneous_modulus", "relaxed_modulus", "relaxation_time"},
                {"instantaneous_modulus", "relaxed_modulus", "relaxation_time"})
    return StandardLinearSolid(r.quantity(d["instantaneous_modulus"], f"{key}.instantaneous_modulus", "Pa", True),
                               r.quantity(d["relaxed_modulus"], f"{key}.relaxed_modulus", "Pa", True),
                               r.quantity(d["relaxation_time"], f"{key}.relaxation_time", "s", True))


def _section(r: _Reader, name, data) -> Section:
    key = f"sections.{name}"
    d = r.table(data, key, {"width", "depth", "area", "inertia"}, {"depth"})
    depth = r.quantity(d["depth"], f"{key}.depth", "m", positive=True)
    if "width" in d:
        if "area" in d or "inertia" in d:
            raise r.fail(key, "give either width or area and inertia, not both")
        return Section.rectangle(r.quantity(d["width"], f"{key}.width", "m", positive=True), depth)
    if "area" not in d or "inertia" not in d:
        raise r.fail(f"{key}.width", "is required (or give both area and inertia)")
    return Section(r.quantity(d["area"], f"{key}.area", "m**2", positive=True),
                   r.quantity(d["inertia"], f"{key}.inertia", "m**4", positive=True), depth)


def _lookup(r, table, name, key, what):
    if name not in table:
        raise r.fail(key, f"unknown {what} (defined: {', '.join(sorted(table)) or 'none'})", name)
    return table[name]


def _damping(r: _Reader, data, key) -> Damping:
    d = r.table(data, key, {"ratio", "frequency", "stiffness", "mass"})
    if "ratio" in d:
        if "stiffness" in d or "mass" in d:
            raise r.fail(key, "give either ratio and frequency or Rayleigh stiffness/mass coefficients")
        if "frequency" not in d:
            raise r.fail(f"{key}.frequency", "is required with a damping ratio (the frequency it holds at)")
        ratio = r.quantity(d["ratio"], f"{key}.ratio", "", nonnegative=True)
        return Damping.modal(ratio, r.quantity(d["frequency"], f"{key}.frequency", "Hz", positive=True))
    return Damping(r.quantity(d.get("stiffness", "0 s"), f"{key}.stiffness", "s", nonnegative=True),
                   r.quantity(d.get("mass", "0 1/s"), f"{key}.mass", "1/s", nonnegative=True))


def _link(r: _Reader, name, data, sections, materials, viscos, segments) -> Link:
    key = f"links.{name}"
    d = r.table(data, key, {"length", "section", "material", "segments", "point_masses", "damping", "start_block",
                            "end_block", "rigid"}, {"length", "section", "material"})
    rigid = r.number(d.get("rigid", False), f"{key}.rigid", bool)
    if rigid and name != "crank":
        raise r.fail(f"{key}.rigid", "only the crank can be rigid (the transfer-matrix model welds it to its clamped "
                                     "pivot, so its far joint becomes a fixed pin)", True)
    if rigid and "damping" in d:
        raise r.fail(f"{key}.damping", "a rigid link has no elastic motion to damp; remove it", d["damping"])
    length = r.quantity(d["length"], f"{key}.length", "m", positive=True)
    sec = _lookup(r, sections, r.text(d["section"], f"{key}.section"), f"{key}.section", "section")
    mat_name = r.text(d["material"], f"{key}.material")
    mat = _lookup(r, materials, mat_name, f"{key}.material", "material")
    n = r.number(d.get("segments", segments), f"{key}.segments", int, positive=True)
    masses = []
    pms = d.get("point_masses", [])
    if not isinstance(pms, list):
        raise r.fail(f"{key}.point_masses", "must be a list of tables", pms)
    for i, pm in enumerate(pms):
        pk = f"{key}.point_masses[{i}]"
        p = r.table(pm, pk, {"position", "mass", "weight", "inertia", "label"}, {"position"})
        if ("mass" in p) == ("weight" in p):
            raise r.fail(pk, "give exactly one of mass and weight")
        mass = (r.quantity(p["mass"], f"{pk}.mass", "kg", nonnegative=True) if "mass" in p
                else r.quantity(p["weight"], f"{pk}.weight", "N", nonnegative=True) / G0)
        masses.append(PointMass(r.quantity(p["position"], f"{pk}.position", "m"), mass,
                                r.quantity(p.get("inertia", "0 kg*m^2"), f"{pk}.inertia", "kg*m**2", nonnegative=True),
                                str(p.get("label", f"{name} mass {i}"))))
    blocks = {}
    for end in ("start_block", "end_block"):
        if end in d:
            bk = f"{key}.{end}"
            b = r.table(d[end], bk, {"length", "section", "material"}, {"length", "section", "material"})
            blocks[end] = EndBlock(r.quantity(b["length"], f"{bk}.length", "m", positive=True),
                                   _lookup(r, sections, r.text(b["section"], f"{bk}.section"), f"{bk}.section", "section"),
                                   _lookup(r, materials, r.text(b["material"], f"{bk}.material"), f"{bk}.material",
                                           "material"))
    damping = _damping(r, d["damping"], f"{key}.damping") if "damping" in d else Damping()
    try:
        return Link(name, length, sec, mat, n, tuple(masses), damping, None if rigid else viscos.get(mat_name), **blocks,
                    rigid=rigid)
    except TMMError as exc:
        raise r.fail(key, str(exc)) from None


def load(path_or_name) -> Scenario:
    """Load a scenario from a path or from the name of a file in ``scenarios/``."""
    path = Path(path_or_name)
    if not path.suffix:
        path = SCENARIO_DIR / f"{path_or_name}.toml"
    if not path.exists():
        available = ", ".join(scenario_names())
        raise ScenarioError(f"scenario '{path_or_name}' not found (file {path}); available: {available}")
    data = _read_with_bases(path, [])
    return from_dict(data, str(path), default_name=path.stem)


def _read_with_bases(path: Path, chain: list) -> dict:
    """Parse a scenario file; ``extends = "base/name"`` (relative to the file, ``.toml`` optional)
    merges the file over its base (tables merge key by key, other values replace), so a rig is
    written once and each test speed only states what differs."""
    if path.resolve() in chain:
        raise ScenarioError(f"scenario '{path}': 'extends' loops back ({' -> '.join(str(p) for p in chain)})")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"scenario '{path}': not valid TOML: {exc}") from None
    except OSError as exc:
        raise ScenarioError(f"scenario '{path}': cannot be read ({exc.strerror})") from None
    base = data.pop("extends", None)
    if base is None:
        return data
    if not isinstance(base, str):
        raise ScenarioError(f"scenario '{path}': key 'extends' = {base!r}: must be the name of a base file")
    base_path = path.parent / base
    if not base_path.suffix:
        base_path = base_path.with_suffix(".toml")
    if not base_path.exists():
        raise ScenarioError(f"scenario '{path}': key 'extends' = {base!r}: no file {base_path}")
    return _merge(_read_with_bases(base_path, chain + [path.resolve()]), data)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def scenario_names() -> list:
    """Names of the runnable scenario files in ``scenarios/`` (bases under ``scenarios/base`` excluded)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def from_dict(data: dict, path: str = "<dict>", default_name: str = "scenario") -> Scenario:
    """Build a :class:`Scenario` from parsed TOML data (``path`` is only used in messages)."""
    r = _Reader(path)
    top = r.table(data, "", {"scenario", "linkage", "materials", "sections", "links", "drive", "gravity", "gauges",
                             "solver", "output", "motor", "coupling", "joints", "plates", "springs", "sliders",
                             "loads", "uncertainty", "modules"}, {"linkage", "links"})
    meta = r.table(top.get("scenario", {}), "scenario", {"name", "description", "sources", "rig"})
    solver = r.table(top.get("solver", {}), "solver", {"tmm", "exudyn", "mujoco"})
    tmm = _tmm_settings(r, solver.get("tmm", {}))

    mats_raw = r.table(top.get("materials", {}), "materials", set(top.get("materials", {})))
    materials = {k: _material(r, k, v) for k, v in mats_raw.items()}
    viscos = {}
    for k, v in mats_raw.items():
        sls = _viscoelastic(r, k, v)
        if sls is not None:
            if not np.isclose(sls.instantaneous_modulus_Pa, materials[k].E_Pa, rtol=1e-9):
                raise r.fail(f"materials.{k}.E", "must equal viscoelastic.instantaneous_modulus for a viscoelastic "
                                                 "material", v["E"])
            viscos[k] = sls
    secs_raw = r.table(top.get("sections", {}), "sections", set(top.get("sections", {})))
    sections = {k: _section(r, k, v) for k, v in secs_raw.items()}

    kind = r.number(r.table(top["linkage"], "linkage", set(top["linkage"]))["type"] if isinstance(top["linkage"], dict)
                    and "type" in top["linkage"] else None, "linkage.type", choices=LINKAGE_TYPES)
    if kind == "structure":
        from .structure_scenario import build
        return build(r, top, path, default_name, materials, sections, meta)
    if "modules" in top and kind != "linkage":
        raise r.fail("modules", f"only a 'linkage' has [[modules]] (this one is a {kind})")
    if kind == "linkage":
        from .linkage_scenario import build_mechanism
        mech, gauge_link = build_mechanism(r, top, materials, sections, viscos, tmm.segments)
    else:
        mech, gauge_link = _main_loop(r, top, kind, materials, sections, viscos, tmm.segments)

    drive = _drive(r, top.get("drive", {}))
    r.speed = drive.speed_rad_s
    if "step" in solver.get("tmm", {}) and tmm.step_rad is not None and not drive.speed_rad_s:
        raise r.fail("solver.tmm.step", "a crank-angle step needs a non-zero drive.speed", solver["tmm"]["step"])
    try:
        mech.motion(np.linspace(0, 2 * np.pi, 73) + drive.start_angle_rad)
    except TMMError as exc:
        raise r.fail("linkage", f"the crank cannot turn a full revolution: {exc}") from None

    gauges = []
    for name, g in r.table(top.get("gauges", {}), "gauges", set(top.get("gauges", {}))).items():
        gk = f"gauges.{name}"
        gd = r.table(g, gk, {"link", "position", "face"}, {"link", "position"})
        link, pos = gauge_link(gk, gd)
        gauges.append(Gauge(name, link, pos, r.number(gd.get("face", "top"), f"{gk}.face", choices=("top", "bottom"))))

    gravity = None
    if "gravity" in top:
        gv = r.table(top["gravity"], "gravity", {"vector"}, {"vector"})["vector"]
        if not isinstance(gv, list) or len(gv) != 2:
            raise r.fail("gravity.vector", "must be a list of two accelerations", gv)
        gravity = tuple(r.quantity(x, f"gravity.vector[{i}]", "m/s**2") for i, x in enumerate(gv))

    ex = r.table(solver.get("exudyn", {}), "solver.exudyn", {"elements", "step", "spectral_radius", "newton_tolerance"})
    exudyn = ExudynSettings(
        r.number(ex.get("elements", 8), "solver.exudyn.elements", int, positive=True),
        _step(r, ex.get("step", "1e-4 s"), "solver.exudyn.step"),
        r.number(ex.get("spectral_radius", 0.9), "solver.exudyn.spectral_radius"),
        r.number(ex.get("newton_tolerance", 1e-6), "solver.exudyn.newton_tolerance", positive=True))
    if not 0 <= exudyn.spectral_radius <= 1:
        raise r.fail("solver.exudyn.spectral_radius", "must lie in [0, 1]", exudyn.spectral_radius)
    mj = r.table(solver.get("mujoco", {}), "solver.mujoco", {"step", "servo_frequency", "solref_factor", "solimp"})
    mujoco = MujocoSettings(
        _step(r, mj.get("step", "1e-4 s"), "solver.mujoco.step"),
        r.quantity(mj["servo_frequency"], "solver.mujoco.servo_frequency", "Hz", positive=True)
        if "servo_frequency" in mj else None,
        r.number(mj.get("solref_factor", 2.0), "solver.mujoco.solref_factor", positive=True),
        r.number(mj.get("solimp", 0.9999), "solver.mujoco.solimp"))
    out = r.table(top.get("output", {}), "output", {"revolutions", "engines", "max_revolutions", "steady_tolerance"})
    engines = r._unwrap(out.get("engines", ["tmm", "exudyn", "mujoco"]), "output.engines")
    if not isinstance(engines, list) or not engines or any(e not in ("tmm", "exudyn", "mujoco") for e in engines):
        raise r.fail("output.engines", "must be a non-empty list of 'tmm', 'exudyn', 'mujoco'", engines)
    output = OutputSettings(r.number(out["revolutions"], "output.revolutions", positive=True)
                            if "revolutions" in out else None, tuple(engines),
                            r.number(out.get("max_revolutions", 30.0), "output.max_revolutions", positive=True),
                            r.quantity(out.get("steady_tolerance", "0.5 %"), "output.steady_tolerance", "",
                                       positive=True))
    motor = _motor(r, top["motor"], drive, mech) if "motor" in top else None
    if drive.mode == "motor" and motor is None:
        raise r.fail("drive.mode", "needs a [motor] table", "motor")
    coupling = _coupling(r, top.get("coupling", {}))
    sources = meta.get("sources", [])
    if isinstance(sources, str):
        sources = [sources]
    return Scenario(str(meta.get("name", default_name)), str(meta.get("description", "")),
                    Path(path) if path != "<dict>" else None, tuple(sources), mech, drive, tuple(gauges), gravity,
                    tmm, exudyn, mujoco, output, tuple(r.assumptions), data, motor, coupling,
                    str(meta["rig"]) if "rig" in meta else None)


def _main_loop(r: _Reader, top: dict, kind: str, materials: dict, sections: dict, viscos: dict, segments: int):
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
    links = {k: _link(r, k, v, sections, materials, viscos, segments) for k, v in links_raw.items()}
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


def _step(r: _Reader, value, key: str) -> float:
    """A time step in seconds, or a crank angle converted with the drive speed."""
    raw = r._unwrap(value, key)
    try:
        q = _parse_quantity(raw) if isinstance(raw, str) else None
    except Exception:
        q = None
    if isinstance(q, pint.Quantity) and q.dimensionality == UREG.Quantity(1, "rad").dimensionality and \
            str(q.units) != "dimensionless":
        if not r.speed:
            raise r.fail(key, "a crank-angle step needs a non-zero drive.speed", raw)
        return r.quantity(raw, key, "rad", positive=True) / abs(r.speed)
    return r.quantity(raw, key, "s", positive=True)


def _coupling(r: _Reader, data) -> CouplingSettings:
    d = r.table(data, "coupling", {"macro_step", "scheme", "extrapolation", "interface_jacobian", "tolerance",
                                   "max_iterations", "start"})
    c = CouplingSettings(
        _step(r, d["macro_step"], "coupling.macro_step") if "macro_step" in d else None,
        r.number(d.get("scheme", "gauss_seidel"), "coupling.scheme", choices=("jacobi", "gauss_seidel", "iterated")),
        r.number(d.get("extrapolation", "linear"), "coupling.extrapolation", choices=("constant", "linear")),
        r.number(d.get("interface_jacobian", True), "coupling.interface_jacobian", bool),
        r.number(d.get("tolerance", 1e-6), "coupling.tolerance", positive=True),
        r.number(d.get("max_iterations", 20), "coupling.max_iterations", int, positive=True),
        r.number(d.get("start", "steady"), "coupling.start", choices=("steady", "rest")))
    return c


MOTOR_CONSTANTS = {"resistance": ("resistance_ohm", "ohm"), "inductance": ("inductance_H", "H"),
                   "torque_constant": ("torque_constant_Nm_A", "N*m/A"),
                   "back_emf": ("back_emf_V_s_rad", "V*s/rad"), "rotor_inertia": ("rotor_inertia_kg_m2", "kg*m**2"),
                   "viscous_friction": ("viscous_friction_Nm_s_rad", "N*m*s/rad"),
                   "coulomb_friction": ("coulomb_friction_Nm", "N*m")}


def _motor(r: _Reader, data, drive: DriveSpec, mech):
    from .motor import MotorParameters, SetPoint, derive_pm_dc_motor

    knobs = {"efficiency": ("efficiency", ""), "copper_loss_share": ("copper_loss_share", ""),
             "coulomb_share": ("coulomb_share", ""), "electrical_time_constant": ("electrical_time_constant_s", "s"),
             "rotor_inertia_per_power": ("rotor_inertia_per_W", "kg*m**2/W")}
    d = r.table(data, "motor", set(MOTOR_CONSTANTS) | set(knobs) | {
        "rated_power", "rated_speed", "rated_voltage", "supply_voltage", "gear_ratio", "flywheel_inertia", "flywheels",
        "shaft_stiffness", "shaft_damping", "controller", "setpoint", "reversible"})
    values = {}
    for key, (name, unit) in MOTOR_CONSTANTS.items():
        if key in d:
            strict = key in ("resistance", "inductance", "torque_constant", "back_emf")
            values[name] = r.quantity(d[key], f"motor.{key}", unit, positive=strict, nonnegative=not strict)
    rating = [k for k in ("rated_power", "rated_speed", "rated_voltage") if k in d]
    missing = [k for k in MOTOR_CONSTANTS if MOTOR_CONSTANTS[k][0] not in values]
    if missing:
        if len(rating) < 3:
            need = sorted({"rated_power", "rated_speed", "rated_voltage"} - set(rating))
            raise r.fail(f"motor.{need[0]}", f"is required to derive the motor constants not given "
                                             f"({', '.join(missing)})")
        P = r.quantity(d["rated_power"], "motor.rated_power", "W", positive=True)
        w = r.quantity(d["rated_speed"], "motor.rated_speed", "rad/s", positive=True)
        V = r.quantity(d["rated_voltage"], "motor.rated_voltage", "V", positive=True)
        kw = {name: r.quantity(d[k], f"motor.{k}", unit, positive=True) for k, (name, unit) in knobs.items() if k in d}
        try:
            derived, why = derive_pm_dc_motor(P, w, V, **kw)
        except InputError as exc:
            raise r.fail("motor.rated_power", str(exc)) from None
        for key in missing:
            name, unit = MOTOR_CONSTANTS[key]
            values[name] = derived[name]
            r.assumptions.append(Assumption(f"motor.{key}", f"{derived[name]:.6g} {unit.replace('**', '^')}", why))
    if "supply_voltage" in d:
        values["supply_voltage_V"] = r.quantity(d["supply_voltage"], "motor.supply_voltage", "V", positive=True)
    elif "rated_voltage" in d:
        values["supply_voltage_V"] = r.quantity(d["rated_voltage"], "motor.rated_voltage", "V", positive=True)
    else:
        raise r.fail("motor.supply_voltage", "is required (or give rated_voltage)")
    values["gear_ratio"] = r.number(d.get("gear_ratio", 1.0), "motor.gear_ratio", positive=True)
    if "flywheel_inertia" in d and "flywheels" in d:
        raise r.fail("motor.flywheels", "give either flywheel_inertia or flywheels, not both")
    J_fw = r.quantity(d.get("flywheel_inertia", "0 kg*m^2"), "motor.flywheel_inertia", "kg*m**2", nonnegative=True)
    fws = d.get("flywheels", [])
    if not isinstance(fws, list):
        raise r.fail("motor.flywheels", "must be a list of tables", fws)
    for i, fw in enumerate(fws):
        fk = f"motor.flywheels[{i}]"
        f = r.table(fw, fk, {"diameter", "thickness", "density", "count"}, {"diameter", "thickness", "density"})
        radius = 0.5 * r.quantity(f["diameter"], f"{fk}.diameter", "m", positive=True)
        mass = (r.quantity(f["density"], f"{fk}.density", "kg/m**3", positive=True) * math.pi * radius**2 *
                r.quantity(f["thickness"], f"{fk}.thickness", "m", positive=True))
        J_fw += r.number(f.get("count", 1), f"{fk}.count", int, positive=True) * 0.5 * mass * radius**2   # solid disk
    values["flywheel_inertia_kg_m2"] = J_fw
    if "shaft_stiffness" in d:
        values["shaft_stiffness_Nm_rad"] = r.quantity(d["shaft_stiffness"], "motor.shaft_stiffness", "N*m/rad",
                                                      positive=True)
    values["shaft_damping_Nm_s_rad"] = r.quantity(d.get("shaft_damping", "0 N*m*s/rad"), "motor.shaft_damping",
                                                  "N*m*s/rad", nonnegative=True)
    values["reversible"] = r.number(d.get("reversible", False), "motor.reversible", bool)

    sp = r.table(d.get("setpoint", {}), "motor.setpoint", {"profile", "start", "t0", "duration"})
    speed = drive.speed_rad_s
    sign = -1.0 if speed < 0 else 1.0
    setpoint = SetPoint(r.number(sp.get("profile", "constant"), "motor.setpoint.profile",
                                 choices=("constant", "ramp", "step")), speed,
                        sign * r.quantity(sp.get("start", "0 rpm"), "motor.setpoint.start", "rad/s", nonnegative=True),
                        r.quantity(sp.get("t0", "0 s"), "motor.setpoint.t0", "s", nonnegative=True),
                        r.quantity(sp.get("duration", "0 s"), "motor.setpoint.duration", "s", nonnegative=True))
    values["setpoint"] = setpoint
    ctrl = r.table(d.get("controller", {}), "motor.controller", {"bandwidth", "kp", "ki", "current_bandwidth",
                                                                 "current_limit"})
    if "current_limit" in ctrl:
        values["current_limit_A"] = r.quantity(ctrl["current_limit"], "motor.controller.current_limit", "A",
                                               positive=True)
    if "bandwidth" in ctrl and ("kp" in ctrl or "ki" in ctrl):
        raise r.fail("motor.controller", "give either bandwidth or kp and ki")
    if "kp" in ctrl or "ki" in ctrl:
        values["kp_V_s_rad"] = r.quantity(ctrl.get("kp", "0 V*s/rad"), "motor.controller.kp", "V*s/rad",
                                          nonnegative=True)
        values["ki_V_rad"] = r.quantity(ctrl.get("ki", "0 V/rad"), "motor.controller.ki", "V/rad", nonnegative=True)
    try:
        params = MotorParameters(**values)
        if "kp" not in ctrl and "ki" not in ctrl:
            bw = r.quantity(ctrl.get("bandwidth", "2 Hz"), "motor.controller.bandwidth", "Hz", positive=True)
            bwi = (r.quantity(ctrl["current_bandwidth"], "motor.controller.current_bandwidth", "Hz", positive=True)
                   if "current_bandwidth" in ctrl else None)
            params = params.with_gains_for(bw, float(np.mean(mech.crank_inertia(np.linspace(0, 2 * math.pi, 72,
                                                                                            endpoint=False))[0])), bwi)
        elif "current_bandwidth" in ctrl:
            raise r.fail("motor.controller.current_bandwidth", "needs bandwidth (the gains are designed from both)")
    except InputError as exc:
        raise r.fail("motor", str(exc)) from None
    return params


def _drive(r: _Reader, data) -> DriveSpec:
    d = r.table(data, "drive", {"mode", "speed", "rotation", "start_angle"})
    mode = r.number(d.get("mode", "prescribed"), "drive.mode", choices=("prescribed", "motor"))
    speed = r.quantity(d.get("speed", "0 rpm"), "drive.speed", "rad/s", nonnegative=True)
    rotation = r.number(d.get("rotation", "ccw"), "drive.rotation", choices=("ccw", "cw"))
    return DriveSpec(mode, speed if rotation == "ccw" else -speed,
                     r.quantity(d.get("start_angle", "0 deg"), "drive.start_angle", "rad"))


def _tmm_settings(r: _Reader, data) -> TMMSettings:
    d = r.table(data, "solver.tmm", {"segments", "integrator", "step", "beam_column", "start", "coupling",
                                     "axial_force"})
    step_s = step_rad = None
    if "step" in d:
        raw = r._unwrap(d["step"], "solver.tmm.step")
        try:
            q = _parse_quantity(raw) if isinstance(raw, str) else None
        except Exception:
            q = None              # r.quantity below names the key and the value
        if q is not None and isinstance(q, pint.Quantity) and q.dimensionality == UREG.Quantity(1, "s").dimensionality:
            step_s = r.quantity(raw, "solver.tmm.step", "s", positive=True)
        else:
            step_rad = r.quantity(raw, "solver.tmm.step", "rad", positive=True)
    else:
        step_rad = math.radians(1.0)
    cp = r.table(d.get("coupling", {}), "solver.tmm.coupling", {"coriolis", "centrifugal", "angular_acceleration"})
    # The rotating-frame terms are on by default: at 373 rpm on the FE rig they move the peaks by
    # 2-4 % and the geometrically exact exudyn model has them (README, "engines agree").
    coupling = Coupling(*(r.number(cp.get(k, True), f"solver.tmm.coupling.{k}", bool)
                          for k in ("coriolis", "centrifugal", "angular_acceleration")))
    if _peek(d.get("beam_column", True)) is False and _peek(d.get("axial_force", "none")) != "none":
        raise r.fail("solver.tmm.axial_force", "has no effect with beam_column = false (linear theory, no axial "
                                               "force in the bending equations); remove one of them", d["axial_force"])
    if _peek(d.get("axial_force")) == "iterated":
        raise r.fail("solver.tmm.axial_force", "'iterated' was replaced by 'dynamic' (the step's own axial force "
                                               "together with the axial shortening from bending)", "iterated")
    return TMMSettings(
        r.number(d.get("segments", 8), "solver.tmm.segments", int, positive=True),
        r.number(d.get("integrator", "generalized_alpha"), "solver.tmm.integrator",
                 choices=("generalized_alpha", "newmark", "houbolt")),
        step_s, step_rad,
        r.number(d.get("beam_column", True), "solver.tmm.beam_column", bool),
        r.number(d.get("start", "quasi_static"), "solver.tmm.start", choices=("quasi_static", "rest")),
        coupling,
        r.number(d.get("axial_force", "dynamic"), "solver.tmm.axial_force",
                 choices=("dynamic", "quasi_static", "none")))


def resolved(scenario: Scenario) -> dict:
    """Everything the run used, TOML-ready: ``[resolved]`` holds every value in SI after units,
    defaults and derivations (field names carry the units), ``assumptions`` every declared
    assumption with its rationale, ``[input]`` the file as written (bases merged)."""
    import dataclasses

    def clean(x):
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return clean({f.name: getattr(x, f.name) for f in dataclasses.fields(x)})
        if isinstance(x, dict):
            return {str(k): clean(v) for k, v in x.items() if v is not None}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x if v is not None]
        if isinstance(x, Path):
            return str(x)
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
            "drive": scenario.drive, "gauges": {g.name: g for g in scenario.gauges},
            "gravity_m_s2": list(scenario.gravity) if scenario.gravity else None,
            "solver": {"tmm": scenario.tmm, "exudyn": scenario.exudyn, "mujoco": scenario.mujoco},
            "motor": scenario.motor, "coupling": scenario.coupling, "output": scenario.output}),
        "assumptions": [{"key": a.key, "value": a.value, "rationale": a.rationale} for a in scenario.assumptions],
        "input": clean(scenario.raw),
    }
