"""Reading a scenario's TOML tree: values with units, tables, and the per-table builders.

Owns: :class:`Reader` (walks the tree, converts every value to SI through :mod:`cosim.units`,
records assumptions, and words every error with the file, the key and the value) and the
builders of materials, sections, damping, links, steps, the drive, the coupling and the
transfer-matrix settings. The loader (:mod:`cosim.scenario`) orchestrates them; the structure,
linkage and motor-design readers use the same Reader.
"""
from __future__ import annotations

import functools
import math

import pint

from tmm_core import (Coupling, Damping, Link, Material, PointMass, Section, StandardLinearSolid, TMMError)
from tmm_core.mechanism import EndBlock

from .scenario_types import (Assumption, CouplingSettings, DriveSpec, ScenarioError, TMMSettings)
from .units import UREG, AngleUnitError, has_number, magnitude_in, quantity as parse_quantity

G0 = 9.80665           # standard gravity [m/s^2], for weights written in force units
#: Magnitudes a value may have in SI units: beyond them no rig is meant and the arithmetic of
#: masses, inertias and stiffnesses (d**4, E*I, ...) overflows or underflows.
MAX_MAGNITUDE, MIN_MAGNITUDE = 1e20, 1e-30
#: A mesh finer than this is refused at load (its arrays alone would not fit; the run's cost is
#: estimated and refused separately, cosim.runs.estimate_cost).
MAX_SEGMENTS = 10_000
#: An angle beyond this many radians (~1600 turns) is refused: no key of a scenario needs more
#: than a few turns, and a double that large keeps fewer digits for the fraction of a turn (at
#: "1e19 deg", 1.7e17 rad, neighbouring doubles are 32 rad apart: the angle means nothing).
MAX_ANGLE_RAD = 1e4
#: A modal damping ratio at or above critical (100 %) is refused.
MAX_DAMPING_RATIO = 1.0


@functools.lru_cache(maxsize=256)
def _needs_unit(unit: str) -> bool:
    """Whether a value in ``unit`` must be written with a unit. An angle is dimensionless to pint,
    but a bare number is no angle: "90" is refused, not 90 rad."""
    return unit == "rad" or not UREG.Quantity(1, unit).dimensionless


@functools.lru_cache(maxsize=4096)
def _converted(raw: str, unit: str) -> tuple:
    """``("ok", value in unit)`` or ``(reason, detail)`` for a value written as text. Kept per
    (text, unit): every variant of a sweep or a sampling study reads the same few hundred texts,
    and pint's parsing and conversion were most of a scenario's load time."""
    try:
        parsed = parse_quantity(raw)
    except ValueError as exc:
        return "not_quantity", str(exc)
    return _convert(parsed, unit)


def _convert(parsed, unit: str) -> tuple:
    """``("ok", value in unit)`` or ``(reason, detail)`` for a pint quantity: one parsed from
    text, or a typed override (a number with its unit, :mod:`cosim.overrides`)."""
    target = UREG.Quantity(1, unit)
    if (parsed.dimensionless and not target.dimensionless) or (_needs_unit(unit) and parsed.unitless):
        return "no_unit", None
    try:
        return "ok", magnitude_in(parsed, unit)
    except pint.DimensionalityError:
        return "wrong_dimension", (str(target.dimensionality), str(parsed.dimensionality))
    except AngleUnitError as exc:
        return "angle", str(exc)
    except (OverflowError, ZeroDivisionError, TypeError, ValueError):
        return "not_convertible", None


class Reader:
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
            # The key is named, its value never shown: a file that is not a scenario (a wrong
            # 'extends') must not have its content echoed.
            raise self.fail(f"{key}.{bad}" if key else bad, f"unknown key (allowed: {', '.join(sorted(allowed))})")
        missing = required - set(data)
        if missing:
            raise self.fail(f"{key}.{sorted(missing)[0]}" if key else sorted(missing)[0], "is required")
        if "assumption" in data:
            self.assumptions.append(Assumption(key, short({k: v for k, v in data.items() if k != "assumption"}),
                                               str(data["assumption"])))
        return data

    def names(self, data, key: str) -> dict:
        """A table of named entries (``[materials.*]``, ``[gauges.*]``): a table, or a message
        naming the key (a scalar written in its place)."""
        return self.table(data, key, set(data) if isinstance(data, dict) else set())

    def unwrap(self, value, key):
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
        raw = self.unwrap(value, key)
        if isinstance(raw, bool):
            raise self.fail(key, f"must be a quantity in {unit}", raw)
        needs_unit = _needs_unit(unit)
        if isinstance(raw, (int, float)):
            if not needs_unit:
                q = float(raw)
            else:
                raise self.fail(key, f"has no unit; write it with one, e.g. '{raw} {example_unit(unit)}'", raw)
        elif isinstance(raw, str) or isinstance(raw, UREG.Quantity):
            if isinstance(raw, str):
                if "," in raw:
                    # "3,73 rpm" is read as 373 rpm by pint: a decimal comma is refused, not guessed.
                    raise self.fail(key, "has a comma: write decimals with '.' and no thousands separators", raw)
                if not has_number(raw):
                    # pint reads a bare unit ("rpm", "psi") as one of it: a number is required.
                    raise self.fail(key, f"has no number; write a number and a unit, e.g. '1 {example_unit(unit)}'",
                                    raw)
                code, q = _converted(raw, unit)
            else:                 # a typed override (a number with its unit): nothing to parse
                code, q = _convert(raw, unit)
            if code == "not_quantity":
                raise self.fail(key, f"is not a quantity with a unit ({q})", raw)
            if code == "no_unit":
                raise self.fail(key, f"has no unit; write it with one, e.g. '{raw} {example_unit(unit)}'", raw)
            if code == "wrong_dimension":
                raise self.fail(key, f"has the wrong dimension: expected {q[0]}, got {q[1]}", raw)
            if code == "angle":
                raise self.fail(key, q, raw)
            if code == "not_convertible":
                raise self.fail(key, "is not a number with a unit that can be converted (too large, or not a "
                                     "number)", raw)
        else:
            raise self.fail(key, f"must be a quantity in {unit}", raw)
        if not math.isfinite(q):
            raise self.fail(key, "must be finite", raw)
        if abs(q) > MAX_MAGNITUDE or 0 < abs(q) < MIN_MAGNITUDE:
            raise self.fail(key, f"is {q:.3g} {unit or '(dimensionless)'} in SI units, outside "
                                 f"{MIN_MAGNITUDE:g}..{MAX_MAGNITUDE:g}: no rig is that size (check the number and "
                                 "its unit)", raw)
        if unit == "rad" and abs(q) > MAX_ANGLE_RAD:
            raise self.fail(key, f"is {q:.3g} rad ({q / (2 * math.pi):.3g} turns), beyond {MAX_ANGLE_RAD:g} rad: an "
                                 "angle this large loses its fraction of a turn in floating point; write it within "
                                 "a turn (e.g. '30 deg')", raw)
        if positive and q <= 0:
            raise self.fail(key, "must be positive", raw)
        if nonnegative and q < 0:
            raise self.fail(key, "must not be negative", raw)
        return q

    def number(self, value, key, kind=float, positive=False, choices=None):
        raw = self.unwrap(value, key)
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
        if isinstance(raw, float) and not math.isfinite(raw):
            raise self.fail(key, "must be finite", raw)
        if abs(raw) > MAX_MAGNITUDE:
            raise self.fail(key, f"must be at most {MAX_MAGNITUDE:g} in magnitude", raw)
        if 0 < abs(raw) < MIN_MAGNITUDE:
            # As for quantities: such a number underflows in the products made of it (a gear ratio
            # of 1e-300 squared divided by zero in the motor's controller design).
            raise self.fail(key, f"must be 0 or at least {MIN_MAGNITUDE:g} in magnitude", raw)
        if positive and raw <= 0:
            raise self.fail(key, "must be positive", raw)
        return kind(raw)

    def text(self, value, key):
        raw = self.unwrap(value, key)
        if not isinstance(raw, str):
            raise self.fail(key, "must be a string", raw)
        return raw


def peek(value):
    """The value of a ``{value = ..., assumption = ...}`` table (or the plain value), unrecorded."""
    return value["value"] if isinstance(value, dict) and "value" in value else value


def short(d) -> str:
    return ", ".join(f"{k} = {v}" for k, v in d.items())


def example_unit(unit: str) -> str:
    return {"m": "in", "Pa": "psi", "kg/m**3": "slug/ft^3", "kg": "lb", "s": "s", "rad/s": "rpm",
            "rad": "deg", "Hz": "Hz", "N": "lbf"}.get(unit, unit)


# --------------------------------------------------------------------------------------------
def material(r: Reader, name, data) -> Material:
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
        if not -1 < opt["poisson"] < 0.5:
            raise r.fail(f"{key}.poisson", "must lie in (-1, 0.5)", d["poisson"])
    E = r.quantity(d["E"], f"{key}.E", "Pa", positive=True)
    density = r.quantity(d["density"], f"{key}.density", "kg/m**3", positive=True)
    try:
        return Material(name, E, density, **opt)
    except TMMError as exc:
        raise r.fail(key, str(exc)) from None


def viscoelastic(r: Reader, name, data):
    if "viscoelastic" not in data:
        return None
    key = f"materials.{name}.viscoelastic"
    d = r.table(data["viscoelastic"], key, {"instantaneous_modulus", "relaxed_modulus", "relaxation_time"},
                {"instantaneous_modulus", "relaxed_modulus", "relaxation_time"})
    values = (r.quantity(d["instantaneous_modulus"], f"{key}.instantaneous_modulus", "Pa", True),
              r.quantity(d["relaxed_modulus"], f"{key}.relaxed_modulus", "Pa", True),
              r.quantity(d["relaxation_time"], f"{key}.relaxation_time", "s", True))
    try:
        return StandardLinearSolid(*values)
    except TMMError as exc:
        raise r.fail(key, str(exc)) from None


def section(r: Reader, name, data) -> Section:
    key = f"sections.{name}"
    d = r.table(data, key, {"width", "depth", "area", "inertia"}, {"depth"})
    depth = r.quantity(d["depth"], f"{key}.depth", "m", positive=True)
    if "width" in d:
        if "area" in d or "inertia" in d:
            raise r.fail(key, "give either width or area and inertia, not both")
        width = r.quantity(d["width"], f"{key}.width", "m", positive=True)
        try:
            return Section.rectangle(width, depth)
        except TMMError as exc:
            raise r.fail(key, str(exc)) from None
    if "area" not in d or "inertia" not in d:
        raise r.fail(f"{key}.width", "is required (or give both area and inertia)")
    area = r.quantity(d["area"], f"{key}.area", "m**2", positive=True)
    inertia = r.quantity(d["inertia"], f"{key}.inertia", "m**4", positive=True)
    try:
        return Section(area, inertia, depth)
    except TMMError as exc:
        raise r.fail(key, str(exc)) from None


def lookup(r, table, name, key, what):
    if name not in table:
        raise r.fail(key, f"unknown {what} (defined: {', '.join(sorted(table)) or 'none'})", name)
    return table[name]


def damping(r: Reader, data, key) -> Damping:
    d = r.table(data, key, {"ratio", "frequency", "stiffness", "mass"})
    if "ratio" in d:
        if "stiffness" in d or "mass" in d:
            raise r.fail(key, "give either ratio and frequency or Rayleigh stiffness/mass coefficients")
        if "frequency" not in d:
            raise r.fail(f"{key}.frequency", "is required with a damping ratio (the frequency it holds at)")
        raw_ratio = r.unwrap(d["ratio"], f"{key}.ratio")
        if not (isinstance(raw_ratio, str) and ("%" in raw_ratio or "percent" in raw_ratio)):
            # A plain "2" would be 200 %: the ratio is written in percent, always.
            raise r.fail(f"{key}.ratio", "write the damping ratio in percent, e.g. '2 %'", raw_ratio)
        ratio = r.quantity(raw_ratio, f"{key}.ratio", "", nonnegative=True)
        if ratio >= MAX_DAMPING_RATIO:
            raise r.fail(f"{key}.ratio", f"must be below {100 * MAX_DAMPING_RATIO:g} % (critical damping is 100 %; "
                                         "a linkage's structural damping is a few percent)", raw_ratio)
        return Damping.modal(ratio, r.quantity(d["frequency"], f"{key}.frequency", "Hz", positive=True))
    return Damping(r.quantity(d.get("stiffness", "0 s"), f"{key}.stiffness", "s", nonnegative=True),
                   r.quantity(d.get("mass", "0 1/s"), f"{key}.mass", "1/s", nonnegative=True))


def link(r: Reader, name, data, sections, materials, viscos, segments) -> Link:
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
    sec = lookup(r, sections, r.text(d["section"], f"{key}.section"), f"{key}.section", "section")
    mat_name = r.text(d["material"], f"{key}.material")
    mat = lookup(r, materials, mat_name, f"{key}.material", "material")
    n = r.number(d.get("segments", segments), f"{key}.segments", int, positive=True)
    if n > MAX_SEGMENTS:
        raise r.fail(f"{key}.segments", f"must be at most {MAX_SEGMENTS}", n)
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
        pos = r.quantity(p["position"], f"{pk}.position", "m")
        if not 0 <= pos <= length * (1 + 1e-12):
            raise r.fail(f"{pk}.position", f"must lie on the {name}, between 0 and its length {length:.6g} m",
                         p["position"])
        masses.append(PointMass(pos, mass,
                                r.quantity(p.get("inertia", "0 kg*m^2"), f"{pk}.inertia", "kg*m**2", nonnegative=True),
                                r.text(p.get("label", f"{name} mass {i}"), f"{pk}.label")))
    blocks = {}
    for end in ("start_block", "end_block"):
        if end in d:
            bk = f"{key}.{end}"
            b = r.table(d[end], bk, {"length", "section", "material"}, {"length", "section", "material"})
            blocks[end] = EndBlock(r.quantity(b["length"], f"{bk}.length", "m", positive=True),
                                   lookup(r, sections, r.text(b["section"], f"{bk}.section"), f"{bk}.section", "section"),
                                   lookup(r, materials, r.text(b["material"], f"{bk}.material"), f"{bk}.material",
                                           "material"))
    link_damping = damping(r, d["damping"], f"{key}.damping") if "damping" in d else Damping()
    try:
        built = Link(name, length, sec, mat, n, tuple(masses), link_damping, None if rigid else viscos.get(mat_name),
                     **blocks, rigid=rigid)
    except TMMError as exc:
        raise r.fail(key, str(exc)) from None
    x = built.stations
    for i, pm in enumerate(masses):       # every engine lumps a point mass at a node of the mesh
        if min(abs(x - pm.position_m)) > 1e-9 * length:
            raise r.fail(f"{key}.point_masses[{i}].position",
                         f"is not at a node of the {name}'s mesh of {n} segments (nodes at "
                         f"{', '.join(f'{v:.6g}' for v in x)} m): move it to one, or change {key}.segments",
                         pms[i].get("position") if isinstance(pms[i], dict) else None)
    return built


def step(r: Reader, value, key: str) -> float:
    """A time step in seconds, or a crank angle converted with the drive speed."""
    raw = r.unwrap(value, key)
    try:
        q = parse_quantity(raw) if isinstance(raw, str) else None
    except Exception:
        q = None
    if isinstance(q, pint.Quantity) and q.dimensionality == UREG.Quantity(1, "rad").dimensionality and \
            str(q.units) != "dimensionless":
        if not r.speed:
            raise r.fail(key, "a crank-angle step needs a non-zero drive.speed", raw)
        return r.quantity(raw, key, "rad", positive=True) / abs(r.speed)
    return r.quantity(raw, key, "s", positive=True)


def coupling(r: Reader, data) -> CouplingSettings:
    d = r.table(data, "coupling", {"macro_step", "scheme", "extrapolation", "interface_jacobian", "tolerance",
                                   "max_iterations", "start"})
    c = CouplingSettings(
        step(r, d["macro_step"], "coupling.macro_step") if "macro_step" in d else None,
        r.number(d.get("scheme", "gauss_seidel"), "coupling.scheme", choices=("jacobi", "gauss_seidel", "iterated")),
        r.number(d.get("extrapolation", "linear"), "coupling.extrapolation", choices=("constant", "linear")),
        r.number(d.get("interface_jacobian", True), "coupling.interface_jacobian", bool),
        r.number(d.get("tolerance", 1e-6), "coupling.tolerance", positive=True),
        r.number(d.get("max_iterations", 20), "coupling.max_iterations", int, positive=True),
        r.number(d.get("start", "steady"), "coupling.start", choices=("steady", "rest")))
    return c


def drive(r: Reader, data) -> DriveSpec:
    d = r.table(data, "drive", {"mode", "speed", "rotation", "start_angle", "type", "fmu"})
    mode = r.number(d.get("mode", "prescribed"), "drive.mode", choices=("prescribed", "motor"))
    speed = r.quantity(d.get("speed", "0 rpm"), "drive.speed", "rad/s", nonnegative=True)
    rotation = r.number(d.get("rotation", "ccw"), "drive.rotation", choices=("ccw", "cw"))
    kind = r.number(d.get("type", "motor"), "drive.type", choices=("motor", "fmu"))
    fmu = None
    if kind == "fmu":
        from .fmi.drive_spec import read_fmu_drive
        fmu = read_fmu_drive(r, d.get("fmu"))
    elif "fmu" in d:
        raise r.fail("drive.fmu", 'is read only with drive.type = "fmu"')
    return DriveSpec(mode, speed if rotation == "ccw" else -speed,
                     r.quantity(d.get("start_angle", "0 deg"), "drive.start_angle", "rad"), kind, fmu)


def tmm_settings(r: Reader, data) -> TMMSettings:
    d = r.table(data, "solver.tmm", {"segments", "integrator", "step", "beam_column", "start", "coupling",
                                     "axial_force", "model", "modes"})
    step_s = step_rad = None
    if "step" in d:
        raw = r.unwrap(d["step"], "solver.tmm.step")
        try:
            q = parse_quantity(raw) if isinstance(raw, str) else None
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
    # 2-4 % and the geometrically exact exudyn model has them (docs/validation.md, "Engines that agree").
    coupling = Coupling(*(r.number(cp.get(k, True), f"solver.tmm.coupling.{k}", bool)
                          for k in ("coriolis", "centrifugal", "angular_acceleration")))
    if peek(d.get("beam_column", True)) is False and peek(d.get("axial_force", "none")) != "none":
        raise r.fail("solver.tmm.axial_force", "has no effect with beam_column = false (linear theory, no axial "
                                               "force in the bending equations); remove one of them", d["axial_force"])
    if peek(d.get("axial_force")) == "iterated":
        raise r.fail("solver.tmm.axial_force", "'iterated' was replaced by 'dynamic' (the step's own axial force "
                                               "together with the axial shortening from bending)", "iterated")
    segments = r.number(d.get("segments", 8), "solver.tmm.segments", int, positive=True)
    if segments > MAX_SEGMENTS:
        raise r.fail("solver.tmm.segments", f"must be at most {MAX_SEGMENTS}", segments)
    # The reduced model (tmm_core.reduced): link modes plus a static correction, for periodic solves.
    model = r.number(d.get("model", "full"), "solver.tmm.model", choices=("full", "reduced"))
    if "modes" in d and model != "reduced":
        raise r.fail("solver.tmm.modes", "only applies to the reduced model: add solver.tmm.model = \"reduced\" or "
                                         "remove it", d["modes"])
    modes = r.number(d.get("modes", TMMSettings.modes), "solver.tmm.modes", int, positive=True)
    if model == "reduced" and peek(d.get("axial_force")) == "quasi_static":
        raise r.fail("solver.tmm.axial_force", "'quasi_static' is not carried by the reduced model (it carries the "
                                               "step's own axial force, 'dynamic', or none): use model = \"full\"",
                     "quasi_static")
    return TMMSettings(
        segments,
        r.number(d.get("integrator", "generalized_alpha"), "solver.tmm.integrator",
                 choices=("generalized_alpha", "newmark", "houbolt")),
        step_s, step_rad,
        r.number(d.get("beam_column", True), "solver.tmm.beam_column", bool),
        r.number(d.get("start", "quasi_static"), "solver.tmm.start", choices=("quasi_static", "rest")),
        coupling,
        r.number(d.get("axial_force", "dynamic"), "solver.tmm.axial_force",
                 choices=("dynamic", "quasi_static", "none")), model=model, modes=modes)
