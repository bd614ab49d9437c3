"""Results of a run folder in Python: ``cosim.load_run(folder)``.

``traces.csv`` is wide (one column per trace, units in the names: ``tmm.coupler_mid.bending_ue``,
``mujoco.drive_torque_Nm``, ``motor.tmm.current_A``; :mod:`cosim.traces`) because it is appended
block by block during the run and must survive a crash. For analysis it is turned into one *long*
table, one row per sample and trace::

    time_s  crank_angle_deg  engine  gauge  quantity  value  unit

* ``crank_angle_deg``: the engine's own crank angle at that time, cumulative from the ground line
  (take it modulo 360 for the angle within a revolution; :meth:`RunData.last_revolution` does);
  motor samples get the engine's angle interpolated at their times. The crank angle is this
  column, not a ``quantity``.
* ``gauge``: the gauge name for strains, ``""`` for traces not tied to a gauge (drive torque,
  crank speed, motor signals); ``""`` rather than NaN so that ``groupby`` keeps those rows.
* ``quantity``: ``bending``, ``axial`` (gauges), ``drive_torque``, ``crank_speed``, the engine's
  extras (``coupler_angle``, ``loop_closure``, ...) and the motor's signals prefixed ``motor_``
  (``motor_current``, ``motor_voltage``, ``motor_torque_em``, ``motor_drive_torque``,
  ``motor_speed``, ``motor_setpoint``, ``motor_electrical_power``, ...).
* ``unit``: explicit, ``"µε"`` (microstrain, the ``_ue`` of the CSV columns) for strains, ``"N m"``,
  ``"rad/s"``, ``"A"``, ``"V"``, ``"W"``, ``"m"``, ``"rad"``.

Units: the engines return gauges as ``(bending, axial)`` tuples of *dimensionless* strain
(``EngineRun.gauges``, ``EngineOutput.gauges``); ``traces.csv``, ``traces.parquet``,
``summary.json`` (``..._ue``) and this table hold *microstrain* (x 1e6).

When a run ends, :func:`write_parquet` stores the long table as ``traces.parquet`` (smaller and
much faster to read than the CSV); :func:`load_run` reads it, or builds the table from the CSV when
there is no parquet file (a killed run) or the CSV is newer.

Owns: ``cosim.load_run`` and ``traces.parquet``. Boundaries: reads a run folder; never writes
outside it.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .files import clear_link
from tmm_core.revolution import last_revolution
from .report import load_summary

log = logging.getLogger(__name__)

COLUMNS = ["time_s", "crank_angle_deg", "engine", "gauge", "quantity", "value", "unit"]
# Unit suffixes of the CSV column names, longest first so that "_rad_s" wins over "_s".
UNIT_SUFFIXES = (("_rad_s", "rad/s"), ("_Nm", "N m"), ("_ue", "µε"), ("_rad", "rad"), ("_deg", "deg"),
                 ("_Hz", "Hz"), ("_mm", "mm"), ("_m", "m"), ("_A", "A"), ("_V", "V"), ("_W", "W"), ("_J", "J"),
                 ("_N", "N"), ("_s", "s"))


def parse_column(column: str) -> tuple:
    """``(engine, gauge, quantity, unit)`` of a traces.csv column; ``unit`` is ``None`` when the
    name carries no known unit suffix (the quantity is then the whole name)."""
    parts = column.split(".")
    if parts[0] == "motor" and len(parts) == 3:
        engine, gauge, name = parts[1], "", parts[2]
    elif len(parts) == 3:
        engine, gauge, name = parts
    elif len(parts) == 2:
        engine, gauge, name = parts[0], "", parts[1]
    else:
        raise ValueError(f"traces column {column!r}: expected <engine>.<trace>, <engine>.<gauge>.<trace> or "
                         "motor.<engine>.<signal>")
    quantity, unit = name, None
    for suffix, u in UNIT_SUFFIXES:
        if name.endswith(suffix):
            quantity, unit = name[: -len(suffix)], u
            break
    if parts[0] == "motor" and not quantity.startswith("motor_"):
        quantity = f"motor_{quantity}"
    return engine, gauge, quantity, unit


LABELS = ("engine", "gauge", "quantity", "unit")


def long_parts(columns: list, data: np.ndarray) -> tuple:
    """The long table of a wide trace table (``read_traces``) as arrays: ``(numbers, labels)``
    with ``numbers = {"time_s", "crank_angle_deg", "value"}`` (float arrays of the rows) and
    ``labels = {"engine", ...: (codes, names)}`` (int32 codes into the list ``names``), in the
    order of :data:`COLUMNS`: one block of rows per trace column, its valid samples."""
    if not columns or columns[0] != "time_s":
        raise ValueError(f"traces: the first column must be time_s, got {columns[:1]}")
    t = data[:, 0]
    angles = {}                          # engine -> (t, angle_deg) of its valid samples
    for j, c in enumerate(columns):
        if c.endswith(".crank_angle_rad") and c.count(".") == 1:
            ok = np.isfinite(data[:, j])
            angles[c.split(".")[0]] = (t[ok], np.degrees(data[ok, j]))
    times, angle, value, pieces = [], [], [], []
    for j, c in enumerate(columns[1:], start=1):
        if c.endswith(".crank_angle_rad") and c.count(".") == 1:
            continue                     # it is the crank_angle_deg column of its engine
        engine, gauge, quantity, unit = parse_column(c)
        if unit is None:
            log.warning("traces column %r has no known unit suffix; kept with unit ''", c)
        ok = np.isfinite(data[:, j])
        tt = t[ok]
        if engine in angles and len(angles[engine][0]):
            ta, aa = angles[engine]
            ang = np.interp(tt, ta, aa, left=np.nan, right=np.nan)
        else:
            ang = np.full(len(tt), np.nan)
        times.append(tt)
        angle.append(ang)
        value.append(data[ok, j])
        pieces.append(((engine, gauge, quantity, unit or ""), len(tt)))
    cat = (lambda arrays: np.concatenate(arrays) if arrays else np.zeros(0))
    numbers = {"time_s": cat(times), "crank_angle_deg": cat(angle), "value": cat(value)}
    labels = {}
    for k, name in enumerate(LABELS):
        names = sorted({p[0][k] for p in pieces})      # sorted, as pandas' own categories
        code = {n: i for i, n in enumerate(names)}
        labels[name] = (np.repeat(np.array([code[p[0][k]] for p in pieces], dtype=np.int32),
                                  [p[1] for p in pieces]), names)
    return numbers, labels


def long_traces(columns: list, data: np.ndarray):
    """The long table (pandas DataFrame, :data:`COLUMNS`; the labels categorical) of a wide trace
    table (``read_traces``)."""
    import pandas as pd

    numbers, labels = long_parts(columns, data)
    if not labels["engine"][1]:          # no trace column at all
        return _empty()
    return pd.DataFrame({c: numbers[c] if c in numbers else pd.Categorical.from_codes(*labels[c])
                         for c in COLUMNS})


def _empty():
    import pandas as pd
    return pd.DataFrame({c: pd.Series(dtype="float64" if c in ("time_s", "crank_angle_deg", "value") else "object")
                         for c in COLUMNS})


def read_wide(path) -> tuple:
    """``(columns, array, note)`` of a traces.csv like :func:`cosim.traces.read_traces`, with
    pandas' C parser (a long run's CSV has millions of cells). A last line cut off by a kill is
    dropped and ``note`` says so; a malformed line raises ValueError naming the file."""
    import io

    import pandas as pd
    path = Path(path)
    text = path.read_text(encoding="utf-8")
    note = None
    if not text.strip():
        raise ValueError(f"{path}: empty trace file")
    if not text.endswith("\n") and text.count("\n") >= 1:
        text = text[: text.rindex("\n") + 1]
        note = f"{path}: the last line was cut off (interrupted run) and is ignored"
    try:
        df = pd.read_csv(io.StringIO(text), dtype="float64")
    except (ValueError, pd.errors.ParserError) as exc:
        raise ValueError(f"{path}: not a trace table ({' '.join(str(exc).split())})") from None
    return list(df.columns), df.to_numpy(), note


#: Rows of traces.csv converted at a time into the parquet file (memory flat in run length).
PARQUET_CHUNK_ROWS = 2_000


def write_parquet(folder) -> Path:
    """``traces.parquet`` (the long table) beside ``traces.csv``, converted chunk by chunk (one
    row group per :data:`PARQUET_CHUNK_ROWS` rows of the CSV, so the memory does not grow with
    the run's length); written through a temporary file so that a crash never leaves half a file.
    A last line cut off by a kill is dropped with a warning."""
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = Path(folder)
    src = folder / "traces.csv"
    path = folder / "traces.parquet"
    tmp = clear_link(path.with_suffix(".parquet.tmp"))
    with src.open("rb") as fh:
        fh.seek(0, 2)
        size = fh.tell()
        if size:
            fh.seek(size - 1)
            complete = fh.read(1) == b"\n"
    if not size:
        raise ValueError(f"{src}: empty trace file")
    writer = schema = None
    try:
        reader = pd.read_csv(src, dtype="float64", chunksize=PARQUET_CHUNK_ROWS,
                             skipfooter=0 if complete else 1, engine="c" if complete else "python")
        for chunk in reader:
            # Arrow columns straight from the arrays (through pandas frames and categoricals the
            # conversion took 0.4 s for 54,000 rows); the labels stored as plain strings.
            numbers, labels = long_parts(list(chunk.columns), chunk.to_numpy())
            table = pa.Table.from_arrays(
                [pa.array(numbers[c]) if c in numbers else
                 pa.DictionaryArray.from_arrays(labels[c][0], pa.array(labels[c][1], pa.string())).cast(pa.large_string())
                 for c in COLUMNS], names=COLUMNS)
            if writer is None:
                schema = table.schema
                writer = pq.ParquetWriter(tmp, schema)
            writer.write_table(table)
    except (ValueError, pd.errors.ParserError) as exc:
        if writer is not None:
            writer.close()
        tmp.unlink(missing_ok=True)
        raise ValueError(f"{src}: not a trace table ({' '.join(str(exc).split())})") from None
    if writer is None:
        _empty().to_parquet(tmp, index=False)
    else:
        writer.close()
    if not complete:
        log.warning("%s: the last line was cut off (interrupted run) and is ignored", src)
    tmp.replace(path)
    return path


def _tail_filters(path: Path, tail_s: float):
    """Parquet row filter keeping the last ``tail_s`` of the run, from the row groups' statistics
    (nothing is read but the file's footer). An engine that failed earlier has no rows in it."""
    import pyarrow.parquet as pq
    md = pq.ParquetFile(path).metadata
    col = md.schema.names.index("time_s")
    ends = [md.row_group(i).column(col).statistics for i in range(md.num_row_groups)]
    ends = [st.max for st in ends if st is not None and st.has_min_max]
    return [("time_s", ">=", max(ends) - tail_s)] if ends else None


@dataclass
class RunData:
    """A run folder loaded: ``traces`` (long pandas DataFrame, see the module docstring),
    ``summary`` (the parsed summary.json), ``notes`` (what was noticed while loading)."""

    folder: Path
    summary: dict
    traces: object
    notes: list = field(default_factory=list)

    @property
    def engines(self) -> list:
        return [str(e) for e in self.traces["engine"].unique()] if len(self.traces) else []

    @property
    def gauges(self) -> list:
        return sorted(str(g) for g in self.traces["gauge"].unique() if g) if len(self.traces) else []

    def steady(self, engine: str) -> bool | None:
        """The summary's verdict (``None`` when the summary has none, e.g. a killed run)."""
        return (self.summary.get("engines") or {}).get(engine, {}).get("steady")

    def last_revolution(self, engine: str | None = None):
        """Rows of each engine's last crank revolution (by its own crank angle, as the summary's
        extremes), with ``crank_angle_deg`` wrapped to [0, 360)."""
        import pandas as pd
        parts = []
        for e in ([engine] if engine else self.engines):
            rows = self.traces[self.traces["engine"] == e]
            # The engine's own samples (motor samples carry interpolated angles); every engine
            # reports its drive torque at each sample.
            ang = rows[rows["quantity"] == "drive_torque"]
            ang = ang[np.isfinite(ang["crank_angle_deg"])].sort_values("time_s")
            if not len(ang):
                continue
            mask = last_revolution(np.radians(ang["crank_angle_deg"].to_numpy()))
            t0 = float(ang["time_s"].to_numpy()[mask][0])
            part = rows[rows["time_s"] >= t0].copy()
            part["crank_angle_deg"] = np.mod(part["crank_angle_deg"], 360.0)
            parts.append(part)
        return pd.concat(parts, ignore_index=True) if parts else _empty()

    def wide(self):
        """``traces.csv`` as a wide DataFrame (empty cells NaN)."""
        import pandas as pd
        columns, data, _ = read_wide(self.folder / "traces.csv")
        return pd.DataFrame(data, columns=columns)


def load_run(folder, tail_s: float | None = None) -> RunData:
    """Load a run folder (``cosim run`` output): traces as a long DataFrame and the summary.

    Reads ``traces.parquet`` when it is there and not older than ``traces.csv``; otherwise (a
    killed or interrupted run, or a folder written before parquet files existed) builds the table
    from ``traces.csv``. ``tail_s`` [s]: from the parquet file, only the last ``tail_s``
    of simulated time (what a figure of the last revolution needs; memory independent of the
    run's length). Raises FileNotFoundError / ValueError naming the file."""
    import pandas as pd

    folder = Path(folder)
    summary = load_summary(folder)
    notes = []
    if summary.get("status") in ("incomplete", "interrupted"):
        notes.append(f"{folder}: the run is {summary['status']}; the traces hold what was written before it ended")
    if summary.get("kind") == "structure":
        notes.append(f"{folder}: a static structure run has no traces (its results are in nodes.csv)")
        return RunData(folder, summary, _empty(), notes)
    csv_path, pq = folder / "traces.csv", folder / "traces.parquet"
    if not csv_path.exists() and not pq.exists():
        raise FileNotFoundError(f"{folder}: no traces.csv or traces.parquet (is it a `cosim run` folder? sweeps write "
                                "sweep.csv, uncertainty runs band.csv)")
    if pq.exists() and (not csv_path.exists() or pq.stat().st_mtime >= csv_path.stat().st_mtime):
        traces = pd.read_parquet(pq, filters=_tail_filters(pq, tail_s)) if tail_s is not None else pd.read_parquet(pq)
        for c in ("engine", "gauge", "quantity", "unit"):
            if c in traces:
                traces[c] = traces[c].astype("category")
    else:
        columns, data, note = read_wide(csv_path)
        if note:
            notes.append(note)
        traces = long_traces(columns, data)
    for n in notes:
        log.info(n)
    return RunData(folder, summary, traces, notes)

