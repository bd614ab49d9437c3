"""Names, colours and timelines of the run recording: pure Python/numpy, no rerun import.

Everything that decides *what* goes where (entity paths, series names, colours, timeline
values) lives here, so the writer (:mod:`cosim.recording.writer`), the blueprint
(:mod:`cosim.recording.blueprint`) and the tests agree on one definition, and the main process
of a run can prepare data for the recording without importing rerun (see
:mod:`cosim.recording.process`).

Owns: entity names, colours and timeline values. Boundaries: no rerun import.
"""
from __future__ import annotations

import math
import re
import uuid
from pathlib import Path

import numpy as np

MODES = ("prescribed", "motor")                # as cosim.master.MODES (not imported: keeps this module light)
MICRO = 1e6                                    # dimensionless strain -> microstrain

# Timelines. Rerun timelines are integer sequences, durations or timestamps: crank angles are
# integer millidegrees.
SIM_TIME = "sim_time"                          # duration [s] (stored in ns)
CRANK_ANGLE = "crank_angle_mdeg"               # cumulative crank angle [mdeg], does not wrap
CRANK_ANGLE_WRAPPED = "crank_angle_wrapped_mdeg"   # 0 <= angle < 360 000 [mdeg]: revolutions overlaid
REVOLUTION = "revolution"                      # floor(crank angle / 360 deg): which revolution
TIMELINES = (SIM_TIME, CRANK_ANGLE, CRANK_ANGLE_WRAPPED, REVOLUTION)
MDEG_PER_REV = 360_000

ENGINE_COLORS = {"tmm": (31, 119, 180), "exudyn": (255, 127, 14), "mujoco": (44, 160, 44)}
SPARE_COLORS = [(148, 103, 189), (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34)]
# Records: mid-tone colours, readable on the viewer's dark plots and on its light label boxes.
RECORD_COLORS = [(214, 39, 40), (188, 189, 34), (227, 119, 194), (140, 86, 75)]
STRAIGHT_COLOR = (150, 150, 150)

# Motor trace fields grouped into multi-series entities (the rest get one entity each), with the
# words each series is called by. The engine name comes first ("tmm motor current [A]"); the
# words never repeat "motor" ("motor motor speed" was a bug of the field-name derivation).
MOTOR_GROUPS = {
    "current": ("current_A",),
    "voltage": ("voltage_V",),
    "torque": ("torque_em_Nm", "drive_torque_Nm"),
    "speed": ("motor_speed_rad_s", "crank_speed_rad_s", "setpoint_rad_s"),
    "power": ("electrical_power_W", "copper_loss_W", "friction_loss_W"),
    "energy": ("energy_in_J", "copper_loss_J", "friction_loss_J", "drive_work_J"),
}
MOTOR_LABELS = {
    "current_A": "motor current", "voltage_V": "motor voltage",
    "torque_em_Nm": "electromagnetic torque", "drive_torque_Nm": "drive torque",
    "motor_speed_rad_s": "motor shaft speed", "crank_speed_rad_s": "crank speed",
    "setpoint_rad_s": "speed set-point", "crank_angle_rad": "crank angle",
    "crank_acceleration_rad_s2": "crank acceleration",
    "electrical_power_W": "electrical power", "copper_loss_W": "copper loss", "friction_loss_W": "friction loss",
    "energy_in_J": "electrical energy", "copper_loss_J": "copper loss", "friction_loss_J": "friction loss",
    "drive_work_J": "work on the crank",
}
_UNIT_SUFFIXES = ("_rad_s2", "_rad_s", "_rad", "_Nm", "_A", "_V", "_W", "_J")


def recording_id(label: str, path) -> str:
    """The recording id of a summary recording (sweep, uncertainty, identification) written to
    ``path``: ``label``, the run folder's name and a random suffix, so that two recordings opened
    together in the viewer stay two (the same id merges them) while their application id, which
    groups them, stays fixed. The suffix is there because ``--out`` can give two runs folders of
    the same name."""
    folder = Path(path).parent.name
    stem = folder if folder.startswith(label) else f"{label}-{folder}" if folder else label
    return f"{stem}-{uuid.uuid4().hex[:8]}"


def part(name) -> str:
    """One entity-path part from a free-form name (no slashes, spaces or other specials), so the
    blueprint's queries can name the same path without escaping."""
    s = re.sub(r"[^A-Za-z0-9_.\-]+", "_", str(name)).strip("_")
    return s or "unnamed"


def engine_color(engine: str, engines=()) -> tuple:
    """The engine's colour: fixed for the bench's engines, a spare one (by position among the
    other engines) for any other."""
    if engine in ENGINE_COLORS:
        return ENGINE_COLORS[engine]
    others = [e for e in engines if e not in ENGINE_COLORS]
    i = others.index(engine) if engine in others else len(others)
    return SPARE_COLORS[i % len(SPARE_COLORS)]


def shades(color, n: int) -> list:
    """``n`` distinguishable shades of one colour: the colour, then lighter and darker ones."""
    out = []
    for i in range(n):
        f = (0.0, 0.45, -0.35, 0.7, -0.55)[i % 5]
        target = 255 if f > 0 else 0
        out.append(tuple(int(round(c + abs(f) * (target - c))) for c in color))
    return out


def motor_label(field: str) -> str:
    """Readable words for a MotorTrace field (unit suffix dropped)."""
    if field in MOTOR_LABELS:
        return MOTOR_LABELS[field]
    for suffix in _UNIT_SUFFIXES:
        if field.endswith(suffix):
            field = field[: -len(suffix)]
            break
    words = field.replace("_", " ")
    return words if words.startswith("motor") else f"motor {words}"


def motor_groups(fields) -> dict:
    """{entity name: [fields]} for the motor fields present: the fixed groups, then one entity
    per other field (``crank_angle_rad`` is a timeline, not a series)."""
    fields = [f for f in fields if f not in ("t", "crank_angle_rad")]
    groups = {g: [f for f in fs if f in fields] for g, fs in MOTOR_GROUPS.items()}
    grouped = {f for fs in groups.values() for f in fs}
    groups.update({part(f): [f] for f in fields if f not in grouped})
    return {g: fs for g, fs in groups.items() if fs}


def mdeg(angle_rad) -> np.ndarray:
    """Crank angle [rad] -> integer millidegrees (the crank-angle timelines' unit)."""
    return np.rint(np.degrees(np.asarray(angle_rad, dtype=float)) * 1000.0).astype(np.int64)


def angle_indexes(angle_rad) -> tuple:
    """(cumulative, wrapped, revolution) timeline values of crank angles [rad]: the wrapped angle
    and the revolution come from the same integer millidegrees, so wrapped + 360 000 revolution
    is the cumulative value exactly."""
    m = mdeg(angle_rad)
    rev, wrapped = np.divmod(m, MDEG_PER_REV)
    return m, wrapped, rev


def nice_factor(x: float) -> float:
    """The largest 1-2-5 number (..., 10, 20, 50, 100, ...) not above ``x``; 1 for x <= 1."""
    if not (x > 1 and math.isfinite(x)):
        return 1.0
    e = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10 ** e <= x * (1 + 1e-12):
            return m * 10 ** e
    return 10 ** e
