"""Experimental and published records: format, loading with strict validation, and ingestion of raw
lab recordings.

A record is a CSV file with a TOML sidecar of the same stem (``table1.csv`` + ``table1.toml``)::

    [record]
    name = "fe_table1"                      # unique
    format = "history" | "peaks" | "values"
    kind = "measurement" | "published_model" | "published_comparison" | "synthetic"
    rig = "fe_crank_rocker"                 # matched against [scenario] rig of a scenario
    speed = "373 rpm"                       # history records: the crank speed (peaks/values: per row)
    description = "..."
    sign_convention = "tension positive" | "not stated"
    [provenance]   source, table, figure, page, notes (OCR caveats)     (required; free text)
    [index]        column = "time_s" | "crank_angle_deg", unit = "s" | "deg"   (history records)
    [channels.<column>]                     (history records; one per data column)
        gauge = "coupler_mid"               # the scenario gauge it measures (or link/position)
        face = "top" | "bottom" | "unknown"
        quantity = "bending" | "axial" | "surface" | "deflection" | "raw" | "trigger"
        unit = "microstrain" | "uin/in" | "strain" | "mm" | "in" | "V" | ...
        calibration = 250.0                 # raw records: physical units per raw unit
        calibration_unit = "microstrain"    # what the calibration gives
    [acquisition]  sample_rate = "2751 Hz", trigger_channel = "trig", trigger_angle = "0 deg",
                   filter = "none" | "low-pass 200 Hz" (what was applied before the file was written)

``peaks`` records have the columns ``rpm, gauge, peak (+|-), quantity (bending|axial), value, unit``
and may carry ``percent`` (as printed); ``values`` records ``quantity, link, value, unit, note``.

Every malformed input raises :class:`RecordError` naming the file, the line and the column: a
missing column, a non-monotonic index, a trigger with no pulses, a unit that is not a strain or
length (or, for raw channels, has no calibration), a non-numeric cell or NaN. Nothing is dropped
silently: a partially usable record is refused with the first bad line.

Ingestion (:func:`ingest`) turns a raw, time-sampled recording with a once-per-revolution
trigger into a one-revolution history over crank angle: trigger pulses -> crank angle (constant
speed within each revolution), calibration, drift removal (a slow trend of the per-revolution
means, zero at the start of the recording), zero-phase low-pass filtering (Butterworth, filtfilt) at a declared
cut-off, ensemble averaging over revolutions with a spread band, bending/axial separation from
top and bottom gauges, and strain-to-deflection calibration as Wang used (a simply supported
span under a central load: deflection / surface strain = L^2 / (6 h)).

Owns: the record format, strict loading and ingestion of raw recordings. Boundaries: no scoring
(cosim.compare); units through cosim.units.
"""
from __future__ import annotations

import csv
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tmm_core import InputError

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
def _fail(path, msg, line=None, column=None) -> RecordError:
    where = str(path)
    if line is not None:
        where += f", line {line}"
    if column is not None:
        where += f", column '{column}'"
    return RecordError(f"record {where}: {msg}")


def _quantity_value(text, path, key, unit_kind):
    """'373 rpm' -> rpm; '2751 Hz' -> Hz; '0 deg' -> deg (simple, strict)."""
    try:
        return to_si(text, unit_kind)
    except UnitError:
        raise _fail(path, f"key '{key}' = {text!r}: expected a quantity in {unit_kind}") from None


def _read_csv(path: Path, required: list):
    """Header and rows of a CSV, checking required columns, empty and NaN cells."""
    if not path.exists():
        raise _fail(path, "file not found")
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.reader(fh)
        rows = [(reader.line_num, r) for r in reader]       # keep the file's line numbers for messages
    rows = [(n, r) for n, r in rows
            if r and not (len(r) == 1 and not r[0].strip()) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise _fail(path, "empty file")
    header_line, header = rows[0][0], [h.strip() for h in rows[0][1]]
    for col in required:
        if col not in header:
            raise _fail(path, f"missing column (the header has {', '.join(header)})", line=header_line, column=col)
    return header, rows[1:]


def _numeric(path, header, rows, columns):
    out = {c: np.empty(len(rows)) for c in columns}
    for i, (line, row) in enumerate(rows):
        if len(row) != len(header):
            raise _fail(path, f"{len(row)} cells, the header has {len(header)}", line=line)
        for c in columns:
            cell = row[header.index(c)].strip()
            try:
                v = float(cell)
            except ValueError:
                raise _fail(path, f"not a number: {cell!r}", line=line, column=c) from None
            if not math.isfinite(v):
                raise _fail(path, f"{cell!r} is not a finite number", line=line, column=c)
            out[c][i] = v
    return out


def _check_unit(path, key, ch_unit, quantity, calibration):
    if quantity == "trigger":
        return
    if quantity == "raw":
        if ch_unit not in RAW_UNITS and not _is_unit(ch_unit, "microstrain") and not _is_unit(ch_unit, "m"):
            raise _fail(path, f"key '{key}.unit' = {ch_unit!r}: a raw channel is in V, mV or counts")
        if calibration is None:
            raise _fail(path, f"key '{key}.calibration' is required for a raw channel (physical units per {ch_unit})")
        return
    if quantity == "deflection":
        if not _is_unit(ch_unit, "m"):
            raise _fail(path, f"key '{key}.unit' = {ch_unit!r}: not a length unit (e.g. m, mm, in, mil)")
        return
    if not _is_unit(ch_unit, "microstrain"):
        raise _fail(path, f"key '{key}.unit' = {ch_unit!r}: not a strain unit (e.g. microstrain, ue, µε, in/in)")


def load_record(path) -> Record:
    """Load a record from its sidecar (``.toml``) or data (``.csv``) path."""
    path = Path(path)
    side, data_path = path.with_suffix(".toml"), path.with_suffix(".csv")
    if not side.exists():
        raise _fail(side, "sidecar not found (each record is <name>.csv with <name>.toml)")
    try:
        meta = tomllib.loads(side.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise _fail(side, f"not valid TOML: {exc}") from None
    rec = meta.get("record")
    if not isinstance(rec, dict):
        raise _fail(side, "table [record] is required")
    for key in ("name", "format", "kind"):
        if key not in rec:
            raise _fail(side, f"key 'record.{key}' is required")
    fmt, kind = rec["format"], rec["kind"]
    if fmt not in FORMATS:
        raise _fail(side, f"key 'record.format' = {fmt!r}: one of {', '.join(FORMATS)}")
    if kind not in KINDS:
        raise _fail(side, f"key 'record.kind' = {kind!r}: one of {', '.join(KINDS)}")
    prov = meta.get("provenance")
    if not isinstance(prov, dict) or "source" not in prov:
        raise _fail(side, "table [provenance] with a 'source' is required")
    speed = _quantity_value(rec["speed"], side, "record.speed", "rpm") if "speed" in rec else None
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
        if fmt == "peaks":
            if d["peak"] not in ("+", "-"):
                raise _fail(data_path, f"peak must be + or -, got {d['peak']!r}", line=line, column="peak")
            if d["quantity"] not in ("bending", "axial"):
                raise _fail(data_path, f"quantity must be bending or axial, got {d['quantity']!r}", line=line,
                            column="quantity")
            if not _is_unit(d["unit"], "microstrain"):
                raise _fail(data_path, f"{d['unit']!r} is not a strain unit", line=line, column="unit")
            d["value_ue"] = d["value"] * factor(d["unit"], "microstrain")
        out.append(d)
    return Record(**common, rows=tuple(out))


def _load_history(side, data_path, meta, common) -> Record:
    idx = meta.get("index")
    if not isinstance(idx, dict) or "column" not in idx or "unit" not in idx:
        raise _fail(side, "table [index] with 'column' and 'unit' (s or deg) is required for a history record")
    if idx["unit"] not in ("s", "deg"):
        raise _fail(side, f"key 'index.unit' = {idx['unit']!r}: s (time) or deg (crank angle)")
    chans = meta.get("channels")
    if not isinstance(chans, dict) or not chans:
        raise _fail(side, "table [channels.<column>] is required (one per data column)")
    channels = []
    for col, c in chans.items():
        key = f"channels.{col}"
        q = c.get("quantity")
        if q not in QUANTITIES:
            raise _fail(side, f"key '{key}.quantity' = {q!r}: one of {', '.join(QUANTITIES)}")
        unit = c.get("unit", "")
        _check_unit(side, key, unit, q, c.get("calibration"))
        face = c.get("face", "unknown")
        if face not in ("top", "bottom", "unknown"):
            raise _fail(side, f"key '{key}.face' = {face!r}: top, bottom or unknown")
        channels.append(Channel(col, q, unit, c.get("gauge"), face, c.get("calibration"), c.get("calibration_unit")))
    header, rows = _read_csv(data_path, [idx["column"]] + [c.column for c in channels])
    data = _numeric(data_path, header, rows, [idx["column"]] + [c.column for c in channels])
    t = data[idx["column"]]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise _fail(data_path, f"the index is not increasing ({t[i - 1]!r} then {t[i]!r})", line=rows[i][0],
                    column=idx["column"])
    acq = dict(meta.get("acquisition", {}))
    if "trigger_channel" in acq and acq["trigger_channel"] not in data:
        raise _fail(side, f"key 'acquisition.trigger_channel' = {acq['trigger_channel']!r}: no such channel")
    return Record(**common, index=(idx["column"], idx["unit"]), channels=tuple(channels), acquisition=acq, data=data)


def shipped_records(directory: Path = RECORD_DIR) -> list:
    """Every record in ``directory`` (sidecars; default the shipped ``scenarios/records``). A
    directory that does not exist is an error, not an empty list: a mistyped ``--records DIR``
    must not look like a rig without records."""
    directory = Path(directory)
    if not directory.is_dir():
        raise RecordError(f"records directory {directory}: not found (or not a directory)")
    return [load_record(p) for p in sorted(directory.glob("*.toml"))]


def records_for(scenario, directory: Path | None = RECORD_DIR) -> list:
    """Records of the scenario's rig at its speed (history records: same speed within 0.5 rpm;
    peaks records: rows at that speed), from ``directory`` (``None``: the shipped records; a
    user's own directory with ``cosim run --records DIR``)."""
    directory = Path(RECORD_DIR if directory is None else directory)
    if not directory.is_dir():           # checked even for a scenario without rig: a typo is never silent
        raise RecordError(f"records directory {directory}: not found (or not a directory)")
    rig = getattr(scenario, "rig", None)
    if not rig:
        return []
    rpm = abs(scenario.drive.speed_rad_s) * 30 / math.pi
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


# -- ingestion of raw lab recordings ---------------------------------------------------------------
def trigger_times(t, signal, threshold: float | None = None, path="<signal>", column="trigger") -> np.ndarray:
    """Times of the rising edges of a once-per-revolution trigger (linear interpolation of the
    threshold crossing; threshold default: midway between the signal's extremes)."""
    t, s = np.asarray(t, float), np.asarray(signal, float)
    lo, hi = np.min(s), np.max(s)
    if not hi > lo:
        raise _fail(path, "the trigger channel has no pulses (constant signal)", column=column)
    thr = 0.5 * (lo + hi) if threshold is None else threshold
    k = np.nonzero((s[:-1] < thr) & (s[1:] >= thr))[0]
    if len(k) < 2:
        raise _fail(path, f"the trigger channel has {len(k)} rising edge(s); at least two pulses (one complete "
                          "revolution) are needed", column=column)
    return t[k] + (thr - s[k]) / (s[k + 1] - s[k]) * (t[k + 1] - t[k])


def crank_angle_from_trigger(t, marks, trigger_angle: float = 0.0, direction: float = 1.0) -> tuple:
    """Crank angle [rad] at samples ``t`` between the first and last trigger mark (constant
    speed within each revolution), and the mask of those samples."""
    t = np.asarray(t, float)
    inside = (t >= marks[0]) & (t <= marks[-1])
    rev = np.interp(t[inside], marks, np.arange(len(marks), dtype=float))
    return trigger_angle + direction * 2 * math.pi * rev, inside


def remove_drift(t, x, marks, order: int = 1) -> np.ndarray:
    """Subtract a slow drift: a polynomial (``order``) through the per-revolution means, taken as
    zero at the start of the recording (the bridge is balanced then), so the periodic signal's own
    mean is kept."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    centers, means = [], []
    for a, b in zip(marks[:-1], marks[1:]):
        sel = (t >= a) & (t < b)
        if np.any(sel):
            centers.append(0.5 * (a + b))
            means.append(float(np.mean(x[sel])))
    if len(centers) <= order:
        return x.copy()
    coef = np.polyfit(centers, means, order)
    return x - (np.polyval(coef, t) - np.polyval(coef, t[0]))


def lowpass(x, sample_rate_Hz: float, cutoff_Hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward-backward, so no phase lag)."""
    from scipy.signal import butter, sosfiltfilt
    if not 0 < cutoff_Hz < 0.5 * sample_rate_Hz:
        raise InputError(f"low-pass cut-off {cutoff_Hz!r} Hz must lie between 0 and half the sample rate "
                         f"({0.5 * sample_rate_Hz:g} Hz)")
    sos = butter(order, cutoff_Hz, btype="low", fs=sample_rate_Hz, output="sos")
    return sosfiltfilt(sos, np.asarray(x, float))


def ensemble_average(angle, x, n_bins: int = 360) -> dict:
    """Average over revolutions on a uniform one-revolution grid: ``angle_rad`` (bin centres from
    the trigger angle), ``mean``, ``std``, ``min``, ``max``, ``revolutions``."""
    angle, x = np.asarray(angle, float), np.asarray(x, float)
    start = angle[0]
    rev = np.floor((angle - start) / (2 * math.pi)).astype(int)
    grid = (np.arange(n_bins) + 0.5) / n_bins * 2 * math.pi
    curves = []
    for r in range(rev.max() + 1):
        sel = rev == r
        phase = angle[sel] - start - 2 * math.pi * r
        if phase.size < 4 or phase[-1] - phase[0] < 2 * math.pi * 0.98:
            continue                                       # incomplete revolution at either end
        curves.append(np.interp(grid, phase, x[sel]))
    if not curves:
        raise InputError("no complete revolution between trigger pulses")
    c = np.array(curves)
    return {"angle_rad": start + grid, "mean": c.mean(0), "std": c.std(0), "min": c.min(0), "max": c.max(0),
            "revolutions": len(curves)}


def bending_axial(top, bottom) -> tuple:
    """Bending strain of the top face and axial strain from top and bottom surface strains."""
    top, bottom = np.asarray(top, float), np.asarray(bottom, float)
    return 0.5 * (top - bottom), 0.5 * (top + bottom)


def deflection_per_strain(span_m: float, depth_m: float) -> float:
    """Static calibration of a midspan gauge as deflection: a simply supported span under a
    central load has midspan deflection P L^3 / (48 EI) and surface strain (P L / 4)(h / 2) / EI,
    so deflection / strain = L^2 / (6 h) [m per unit strain]."""
    if not (span_m > 0 and depth_m > 0):
        raise InputError(f"span and depth must be positive, got {span_m!r}, {depth_m!r}")
    return span_m**2 / (6 * depth_m)


def ingest(record: Record, cutoff_Hz: float | None = None, n_bins: int = 360, drift_order: int = 1) -> dict:
    """Raw time record -> one-revolution history per gauge: {"angle_rad", "revolutions",
    gauge: {"bending_ue", "axial_ue", "bending_std_ue", ... (surface channels per face)}}.

    Steps: trigger pulses -> crank angle; calibration to microstrain; drift removal; zero-phase
    low-pass at ``cutoff_Hz`` (default: the sidecar's ``acquisition.cutoff``, none if absent);
    ensemble average; bending/axial from top and bottom surface channels of a gauge."""
    col, unit = record.index
    if unit != "s":
        raise RecordError(f"record {record.path}: ingestion needs a time index, not {unit!r}")
    acq = record.acquisition
    trig = acq.get("trigger_channel")
    if trig is None:
        raise RecordError(f"record {record.path.with_suffix('.toml')}: key 'acquisition.trigger_channel' is required "
                          "for ingestion")
    t = record.data[col]
    marks = trigger_times(t, record.data[trig], path=record.path, column=trig)
    fs = _quantity_value(acq["sample_rate"], record.path.with_suffix(".toml"), "acquisition.sample_rate", "Hz") \
        if "sample_rate" in acq else 1.0 / float(np.median(np.diff(t)))
    if cutoff_Hz is None and "cutoff" in acq:
        cutoff_Hz = _quantity_value(acq["cutoff"], record.path.with_suffix(".toml"), "acquisition.cutoff", "Hz")
    trigger_angle = math.radians(_quantity_value(acq.get("trigger_angle", "0 deg"), record.path, "trigger_angle",
                                                 "deg"))
    direction = -1.0 if acq.get("rotation", "ccw") == "cw" else 1.0
    angle, inside = crank_angle_from_trigger(t, marks, trigger_angle, direction)
    surfaces = {}
    for c in record.channels:
        if c.quantity == "trigger":
            continue
        x = record.data[c.column]
        if c.quantity == "raw":
            x = x * c.calibration * factor(c.calibration_unit or "microstrain", "microstrain")
            q = "surface"
        else:
            x = x * factor(c.unit, "microstrain")
            q = c.quantity
        x = remove_drift(t, x, marks, drift_order)
        if cutoff_Hz:
            x = lowpass(x, fs, cutoff_Hz)
        surfaces.setdefault(c.gauge or c.column, {})[(q, c.face)] = x[inside]
    out = {"marks_s": marks, "sample_rate_Hz": fs, "cutoff_Hz": cutoff_Hz}
    for gauge, chans in surfaces.items():
        g = {}
        if ("surface", "top") in chans and ("surface", "bottom") in chans:
            b, a = bending_axial(chans[("surface", "top")], chans[("surface", "bottom")])
            series = {"bending": b, "axial": a}
        else:
            series = {f"{q}_{face}" if q == "surface" else q: v for (q, face), v in chans.items()}
        for name, v in series.items():
            avg = ensemble_average(angle, v, n_bins)
            g[f"{name}_ue"], g[f"{name}_std_ue"] = avg["mean"], avg["std"]
            g[f"{name}_min_ue"], g[f"{name}_max_ue"] = avg["min"], avg["max"]
            out["angle_rad"], out["revolutions"] = avg["angle_rad"], avg["revolutions"]
        out[gauge] = g
    return out
