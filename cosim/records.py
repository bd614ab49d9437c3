"""Experimental and published records: format, loading with strict validation, and ingestion of raw
lab recordings.

A record is a CSV file with a TOML sidecar of the same stem (``table1.csv`` + ``table1.toml``);
its format (history, peaks and values records, channels, calibration, acquisition) has one home:
docs/user-guide.md, "Records: measurements and published results". Every malformed input raises
:class:`RecordError` naming the file, the line and the column; nothing is dropped silently.
Ingestion of raw recordings is :mod:`cosim.record_ingest`.

Owns: the record format and strict loading. Boundaries: no scoring
(cosim.compare); units through cosim.units.
"""
from __future__ import annotations

import csv
import io
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tmm_core import InputError

from .files import RECORD_BYTES, SCENARIO_BYTES, FileRefused, read_text_bounded
from .units import UnitError, factor, to_si

RECORD_DIR = Path(__file__).resolve().parent.parent / "scenarios" / "records"
KINDS = ("measurement", "published_model", "published_comparison", "synthetic")
FORMATS = ("history", "peaks", "values")
QUANTITIES = ("bending", "axial", "surface", "deflection", "raw", "trigger")
RAW_UNITS = ("V", "mV", "counts")


def _is_unit(unit: str, kind: str) -> bool:
    try:
        factor(unit, kind)
        return True
    except UnitError:
        return False


class RecordError(InputError):
    """A record file or sidecar is malformed; the message names the file, line and column."""


@dataclass(frozen=True)
class Channel:
    column: str
    quantity: str
    unit: str
    gauge: str | None = None
    face: str = "unknown"
    calibration: float | None = None
    calibration_unit: str | None = None


@dataclass(frozen=True)
class Record:
    """A loaded record. ``data``: {column: array} in the file's units (index included)."""

    name: str
    format: str
    kind: str
    path: Path
    meta: dict
    provenance: dict
    rig: str | None = None
    speed_rpm: float | None = None
    sign_convention: str = "not stated"
    index: tuple | None = None              # (column, unit) of history records
    channels: tuple = ()
    acquisition: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)
    rows: tuple = ()                        # peaks / values records: one dict per row

    @property
    def label(self) -> str:
        return f"{self.name} ({self.kind.replace('_', ' ')})"

    @property
    def title(self) -> str:
        """A name for figures and reports, from the provenance instead of the file id:
        ``"FE crank-rocker thesis, TABLE I (measurement)"`` for ``fe_table1``."""
        source = str(self.provenance.get("source") or "").split(",")[0].strip()
        table = str(self.provenance.get("table") or self.provenance.get("figure") or "")
        table = table.split(":")[0].split(" (")[0].strip()       # the table's name, not its caption
        head = ", ".join(x for x in (source, table) if x) or self.name
        return f"{head} ({self.kind.replace('_', ' ')})"

    def channel(self, column: str) -> Channel:
        for c in self.channels:
            if c.column == column:
                return c
        raise KeyError(column)


# -- loading ---------------------------------------------------------------------------------------
def record_error(path, msg, line=None, column=None) -> RecordError:
    """A :class:`RecordError` naming the file, and the line and column where given."""
    where = str(path)
    if line is not None:
        where += f", line {line}"
    if column is not None:
        where += f", column '{column}'"
    return RecordError(f"record {where}: {msg}")


def quantity_value(text, path, key, unit_kind):
    """'373 rpm' -> rpm; '2751 Hz' -> Hz; '0 deg' -> deg (simple, strict)."""
    try:
        return to_si(text, unit_kind)
    except UnitError:
        raise record_error(path, f"key '{key}' = {text!r}: expected a quantity in {unit_kind}") from None


def _read_csv(path: Path, required: list):
    """Header and rows of a CSV, checking required columns, empty and NaN cells."""
    if not path.exists():
        raise record_error(path, "file not found")
    try:
        reader = csv.reader(io.StringIO(read_text_bounded(path, RECORD_BYTES), newline=""))
        rows = [(reader.line_num, r) for r in reader]           # keep the file's line numbers for messages
    except FileRefused as exc:
        raise record_error(path, str(exc)) from None
    except UnicodeDecodeError:
        raise record_error(path, "not a UTF-8 text file") from None
    except csv.Error as exc:
        raise record_error(path, f"not a readable CSV ({exc})") from None
    rows = [(n, r) for n, r in rows
            if r and not (len(r) == 1 and not r[0].strip()) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise record_error(path, "empty file")
    header_line, header = rows[0][0], [h.strip() for h in rows[0][1]]
    for col in required:
        if col not in header:
            raise record_error(path, f"missing column (the header has {', '.join(header)})", line=header_line, column=col)
    if len(rows) < 2:
        raise record_error(path, "no data rows (only the header)", line=header_line)
    return header, rows[1:]


def _numeric(path, header, rows, columns):
    out = {c: np.empty(len(rows)) for c in columns}
    for i, (line, row) in enumerate(rows):
        if len(row) != len(header):
            raise record_error(path, f"{len(row)} cells, the header has {len(header)}", line=line)
        for c in columns:
            cell = row[header.index(c)].strip()
            try:
                v = float(cell)
            except ValueError:
                raise record_error(path, f"not a number: {cell!r}", line=line, column=c) from None
            if not math.isfinite(v):
                raise record_error(path, f"{cell!r} is not a finite number", line=line, column=c)
            out[c][i] = v
    return out


def _check_unit(path, key, ch_unit, quantity, calibration):
    if quantity == "trigger":
        return
    if quantity == "raw":
        if ch_unit not in RAW_UNITS and not _is_unit(ch_unit, "microstrain") and not _is_unit(ch_unit, "m"):
            raise record_error(path, f"key '{key}.unit' = {ch_unit!r}: a raw channel is in V, mV or counts")
        if calibration is None:
            raise record_error(path, f"key '{key}.calibration' is required for a raw channel (physical units per {ch_unit})")
        return
    if quantity == "deflection":
        if not _is_unit(ch_unit, "m"):
            raise record_error(path, f"key '{key}.unit' = {ch_unit!r}: not a length unit (e.g. m, mm, in, mil)")
        return
    if not _is_unit(ch_unit, "microstrain"):
        raise record_error(path, f"key '{key}.unit' = {ch_unit!r}: not a strain unit (e.g. microstrain, ue, µε, in/in)")


def load_record(path) -> Record:
    """Load a record from its sidecar (``.toml``) or data (``.csv``) path."""
    path = Path(path)
    side, data_path = path.with_suffix(".toml"), path.with_suffix(".csv")
    if not side.exists():
        raise record_error(side, "sidecar not found (each record is <name>.csv with <name>.toml)")
    try:
        meta = tomllib.loads(read_text_bounded(side, SCENARIO_BYTES))
    except FileRefused as exc:
        raise record_error(side, str(exc)) from None
    except RecursionError:
        raise record_error(side, "tables or arrays nested too deeply to be a record's sidecar") from None
    except tomllib.TOMLDecodeError as exc:
        raise record_error(side, f"not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise record_error(side, "not a UTF-8 text file") from None
    rec = meta.get("record")
    if not isinstance(rec, dict):
        raise record_error(side, "table [record] is required")
    for key in ("name", "format", "kind"):
        if key not in rec:
            raise record_error(side, f"key 'record.{key}' is required")
    fmt, kind = rec["format"], rec["kind"]
    if fmt not in FORMATS:
        raise record_error(side, f"key 'record.format' = {fmt!r}: one of {', '.join(FORMATS)}")
    if kind not in KINDS:
        raise record_error(side, f"key 'record.kind' = {kind!r}: one of {', '.join(KINDS)}")
    for key in ("name", "rig", "description", "sign_convention"):
        if key in rec and not (isinstance(rec[key], str) and rec[key].strip()):
            raise record_error(side, f"key 'record.{key}' = {rec[key]!r}: must be a non-empty string")
    prov = meta.get("provenance")
    if not isinstance(prov, dict) or "source" not in prov:
        raise record_error(side, "table [provenance] with a 'source' is required")
    if not (isinstance(prov["source"], str) and prov["source"].strip()):
        raise record_error(side, f"key 'provenance.source' = {prov['source']!r}: must be a non-empty string")
    speed = quantity_value(rec["speed"], side, "record.speed", "rpm") if "speed" in rec else None
    common = dict(name=rec["name"], format=fmt, kind=kind, path=data_path, meta=rec, provenance=prov,
                  rig=rec.get("rig"), speed_rpm=speed, sign_convention=rec.get("sign_convention", "not stated"))
    if fmt == "history":
        return _load_history(side, data_path, meta, common)
    required = ["rpm", "gauge", "peak", "quantity", "value", "unit"] if fmt == "peaks" else \
        ["quantity", "link", "value", "unit"]
    header, rows = _read_csv(data_path, required)
    values = _numeric(data_path, header, rows, [c for c in ("rpm", "value", "percent") if c in header])
    out = []
    for i, (line, row) in enumerate(rows):
        d = {h: row[j].strip() for j, h in enumerate(header)}
        for c, arr in values.items():
            d[c] = float(arr[i])
        for c in ("gauge", "unit") if fmt == "peaks" else ("link",):      # a values row may be unitless (a ratio)
            if not d[c]:
                raise record_error(data_path, "empty cell", line=line, column=c)
        if fmt == "peaks" and not d["rpm"] > 0:
            raise record_error(data_path, f"the speed must be positive, got {d['rpm']!r}", line=line, column="rpm")
        if fmt == "peaks":
            if d["peak"] not in ("+", "-"):
                raise record_error(data_path, f"peak must be + or -, got {d['peak']!r}", line=line, column="peak")
            if d["quantity"] not in ("bending", "axial"):
                raise record_error(data_path, f"quantity must be bending or axial, got {d['quantity']!r}", line=line,
                            column="quantity")
            if not _is_unit(d["unit"], "microstrain"):
                raise record_error(data_path, f"{d['unit']!r} is not a strain unit", line=line, column="unit")
            d["value_ue"] = d["value"] * factor(d["unit"], "microstrain")
        out.append(d)
    return Record(**common, rows=tuple(out))


def _load_history(side, data_path, meta, common) -> Record:
    idx = meta.get("index")
    if not isinstance(idx, dict) or "column" not in idx or "unit" not in idx:
        raise record_error(side, "table [index] with 'column' and 'unit' (s or deg) is required for a history record")
    if not isinstance(idx["column"], str):
        raise record_error(side, f"key 'index.column' = {idx['column']!r}: must be the name of a column")
    if idx["unit"] not in ("s", "deg"):
        raise record_error(side, f"key 'index.unit' = {idx['unit']!r}: s (time) or deg (crank angle)")
    chans = meta.get("channels")
    if not isinstance(chans, dict) or not chans:
        raise record_error(side, "table [channels.<column>] is required (one per data column)")
    channels = []
    for col, c in chans.items():
        key = f"channels.{col}"
        if not isinstance(c, dict):
            raise record_error(side, f"key '{key}' = {c!r}: must be a table (quantity, unit, gauge, face)")
        for k in ("unit", "gauge", "calibration_unit"):
            if k in c and not (isinstance(c[k], str) and c[k].strip()):
                raise record_error(side, f"key '{key}.{k}' = {c[k]!r}: must be a non-empty string")
        if c.get("quantity") != "trigger" and "unit" not in c:
            raise record_error(side, f"key '{key}.unit' is required")
        if "calibration" in c and (isinstance(c["calibration"], bool) or not isinstance(c["calibration"], (int, float))
                                   or not math.isfinite(c["calibration"]) or c["calibration"] == 0):
            raise record_error(side, f"key '{key}.calibration' = {c['calibration']!r}: must be a finite non-zero number")
        q = c.get("quantity")
        if q not in QUANTITIES:
            raise record_error(side, f"key '{key}.quantity' = {q!r}: one of {', '.join(QUANTITIES)}")
        unit = c.get("unit", "")
        _check_unit(side, key, unit, q, c.get("calibration"))
        face = c.get("face", "unknown")
        if face not in ("top", "bottom", "unknown"):
            raise record_error(side, f"key '{key}.face' = {face!r}: top, bottom or unknown")
        channels.append(Channel(col, q, unit, c.get("gauge"), face, c.get("calibration"), c.get("calibration_unit")))
    header, rows = _read_csv(data_path, [idx["column"]] + [c.column for c in channels])
    data = _numeric(data_path, header, rows, [idx["column"]] + [c.column for c in channels])
    t = data[idx["column"]]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise record_error(data_path, f"the index is not increasing ({t[i - 1]!r} then {t[i]!r})", line=rows[i][0],
                    column=idx["column"])
    acq = meta.get("acquisition", {})
    if not isinstance(acq, dict):
        raise record_error(side, f"key 'acquisition' = {acq!r}: must be a table")
    acq = dict(acq)
    if "trigger_channel" in acq and (not isinstance(acq["trigger_channel"], str) or acq["trigger_channel"] not in data):
        raise record_error(side, f"key 'acquisition.trigger_channel' = {acq['trigger_channel']!r}: no such channel")
    trig = next((c for c in channels if c.column == acq.get("trigger_channel")), None)
    if trig is not None and trig.quantity != "trigger":      # it would be read as pulses and averaged as a gauge
        raise record_error(side, f"key 'acquisition.trigger_channel' = {trig.column!r}: channel of quantity "
                                 f"{trig.quantity!r}; the trigger channel has quantity = \"trigger\"")
    return Record(**common, index=(idx["column"], idx["unit"]), channels=tuple(channels), acquisition=acq, data=data)


def shipped_records(directory: Path = RECORD_DIR) -> list:
    """Every record in ``directory`` (sidecars; default the shipped ``scenarios/records``). A
    directory that does not exist is an error, not an empty list: a mistyped ``--records DIR``
    must not look like a rig without records."""
    directory = Path(directory)
    if not directory.is_dir():
        raise RecordError(f"records directory {directory} (--records): not found (or not a directory)")
    return [load_record(p) for p in sorted(directory.glob("*.toml"))]


def records_for(scenario, directory: Path | None = RECORD_DIR) -> list:
    """Records of the scenario's rig at its speed (history records: same speed within 0.5 rpm;
    peaks records: rows at that speed), from ``directory`` (``None``: the shipped records; a
    user's own directory with ``cosim run --records DIR``)."""
    directory = Path(RECORD_DIR if directory is None else directory)
    if not directory.is_dir():           # checked even for a scenario without rig: a typo is never silent
        raise RecordError(f"records directory {directory} (--records): not found (or not a directory)")
    rig = getattr(scenario, "rig", None)
    if not rig:
        return []
    rpm = scenario.drive.speed_rpm
    out = []
    for rec in shipped_records(directory):
        if rec.rig != rig:
            continue
        if rec.format == "history" and (rec.speed_rpm is None or abs(rec.speed_rpm - rpm) > 0.5):
            continue
        if rec.format == "peaks" and not any(abs(r["rpm"] - rpm) <= 0.5 for r in rec.rows):
            continue
        if rec.format == "values" and rec.speed_rpm is not None and abs(rec.speed_rpm - rpm) > 0.5:
            continue
        out.append(rec)
    return out


def peaks_at(record: Record, rpm: float) -> dict:
    """{gauge: {"bending_max_ue", "bending_min_ue", "axial_max_ue", "axial_min_ue"}} of a peaks
    record at a speed. A "-" peak printed as a magnitude is stored negative for bending; axial
    values are kept as printed (Table I gives axial magnitudes beside each bending peak)."""
    out = {}
    for r in record.rows:
        if abs(r["rpm"] - rpm) > 0.5:
            continue
        g = out.setdefault(r["gauge"], {})
        v = r["value_ue"]
        if r["quantity"] == "bending":
            g["bending_max_ue" if r["peak"] == "+" else "bending_min_ue"] = abs(v) if r["peak"] == "+" else -abs(v)
        else:
            g["axial_at_max_ue" if r["peak"] == "+" else "axial_at_min_ue"] = v
    return out


def history_over_angle(record: Record) -> dict:
    """A history record over crank angle: {"angle_rad": (n,), gauge: {"bending_ue"/"axial_ue"/...}}
    (strain in microstrain, deflection in m). Time-indexed records must be ingested first."""
    col, unit = record.index
    if unit != "deg":
        raise RecordError(f"record {record.path}: indexed by time; ingest it (cosim.records.ingest) first")
    out = {"angle_rad": np.radians(record.data[col])}
    for c in record.channels:
        if c.quantity in ("trigger", "raw"):
            continue
        v = record.data[c.column]
        if c.quantity == "deflection":
            v = v * factor(c.unit, "m")
            key = "deflection_m"
        else:
            v = v * factor(c.unit, "microstrain")
            key = f"{c.quantity}_ue"
        out.setdefault(c.gauge or c.column, {})[key] = v
    return out
