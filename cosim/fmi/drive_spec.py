"""The ``[drive.fmu]`` table of a scenario: which FMU drives the crank and how its variables map
onto the master's interface.

::

    [drive]
    mode = "motor"                  # the crank is driven (not prescribed)
    type = "fmu"                    # by an FMU instead of the [motor] table
    speed = "373 rpm"               # the crank speed the run starts at (and its length in revolutions)

    [drive.fmu]
    file = "motor.fmu"              # relative to the scenario file
    torque = { variable = "drive_torque", unit = "N*m" }     # output: torque on the crank, CCW positive
    speed = { variable = "crank_speed", unit = "rad/s" }     # input: the crank speed
    angle = { variable = "crank_angle", unit = "rad" }       # input (optional): the crank angle
    inertia = { variable = "crank_side_inertia", unit = "kg*m^2" }   # or a value: "0.37 kg*m^2"

``unit`` is the unit the FMU's variable is in (any pint spelling of the right kind, :mod:`cosim.units`):
the master converts to and from SI at the FMU's boundary. ``inertia`` is the drive's inertia turning
with the crank (rotor and flywheel), which the crank's model carries: a value, or the FMU variable
(a parameter or calculated parameter) that holds it.

Owns: ``FmuDriveSpec``, ``FmuVariable``, ``read_fmu_drive``. Boundaries: no FMU is opened here
(:mod:`cosim.fmi.drive` checks the FMU against the mapping when a run builds the drive).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..units import UnitError, factor

#: The mapped variables: key -> (the SI unit inside the bench, required).
SIGNALS = {"torque": ("N*m", True), "speed": ("rad/s", True), "angle": ("rad", False), "inertia": ("kg*m^2", True)}


@dataclass(frozen=True)
class FmuVariable:
    """One FMU variable of the mapping: SI value = FMU value x ``to_si``."""

    key: str              # the scenario key, e.g. "drive.fmu.torque"
    name: str             # the FMU's variable name
    unit: str             # its unit as the scenario declares it
    to_si: float


@dataclass(frozen=True)
class FmuDriveSpec:
    """An FMU drive: the file (absolute), the scenario file it was declared in (for messages),
    the mapped variables and the drive inertia [kg m^2] when given as a value."""

    file: str
    torque: FmuVariable
    speed: FmuVariable
    angle: FmuVariable | None = None
    inertia: FmuVariable | None = None
    inertia_kg_m2: float | None = None


def read_fmu_drive(r, data) -> FmuDriveSpec:
    """The ``[drive.fmu]`` table read with the scenario's reader ``r`` (errors name the file, the
    key and the value)."""
    if data is None:
        raise r.fail("drive.fmu", 'is required with drive.type = "fmu" (file, torque, speed, inertia)')
    d = r.table(data, "drive.fmu", {"file", "torque", "speed", "angle", "inertia"}, {"file", "torque", "speed", "inertia"})
    file = d["file"]
    if not isinstance(file, str) or not file:
        raise r.fail("drive.fmu.file", "must be the path of an .fmu file", file)
    here = Path(r.path).parent if Path(str(r.path)).is_file() else Path.cwd()
    path = (here / file).resolve()
    if not path.is_file():
        raise r.fail("drive.fmu.file", f"no such file {path}", file)
    mapped = {key: _variable(r, key, d[key], SIGNALS[key][0]) for key in ("torque", "speed", "angle") if key in d}
    inertia, inertia_value = None, None
    if isinstance(d["inertia"], dict) and "variable" in d["inertia"]:
        inertia = _variable(r, "inertia", d["inertia"], SIGNALS["inertia"][0])
    else:
        inertia_value = r.quantity(d["inertia"], "drive.fmu.inertia", "kg*m^2", positive=True)
    return FmuDriveSpec(str(path), mapped["torque"], mapped["speed"], mapped.get("angle"), inertia, inertia_value)


def _variable(r, key: str, data, si_unit: str) -> FmuVariable:
    full = f"drive.fmu.{key}"
    v = r.table(data, full, {"variable", "unit"}, {"variable", "unit"})
    name, unit = v["variable"], v["unit"]
    if not isinstance(name, str) or not name:
        raise r.fail(f"{full}.variable", "must be the name of an FMU variable", name)
    try:
        to_si = factor(str(unit), si_unit)
    except UnitError as exc:
        raise r.fail(f"{full}.unit", f"must be a unit of {si_unit} ({exc})", unit) from None
    return FmuVariable(full, name, str(unit), to_si)
