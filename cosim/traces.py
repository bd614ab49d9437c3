"""The run's trace table, ``traces.csv``: one time column and one column per trace.

Columns are named ``<engine>.<quantity>_<unit>`` (``tmm.drive_torque_Nm``,
``exudyn.coupler_mid.bending_ue`` with ue = microstrain, ``motor.tmm.current_A``); the first is
``time_s``. Engines sample at different times (exudyn once per macro step, the transfer-matrix
model and MuJoCo at every internal step), so the rows are the union of all sample times and a
cell is empty where a trace has no sample.

The file is appended in blocks of macro steps, one write and flush at most every
:data:`FLUSH_EVERY_S` of wall time and at :meth:`TraceWriter.close`: an interrupted run (Ctrl-C,
SIGTERM, an error: the run closes the writer) keeps every completed step, a killed one (SIGKILL)
every step up to the last flush. (A write per macro step cost the run ~9 us a row, 0.47 s on
0.7 s of engine time for 150 revolutions of the FE rig at 1 deg; the union of the engines' times
and the table per block instead of per step leave the rows' formatting, ~4 us a row.)
:func:`read_traces` reads a killed run's file and drops (and reports) a last line cut off by the
kill.

Owns: ``traces.csv``: column names with units, appending per macro step. Boundaries: no post-
processing.
"""
from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from .motor import MotorTrace

MOTOR_FIELDS = ("current_A", "voltage_V", "torque_em_Nm", "drive_torque_Nm", "motor_speed_rad_s",
                "setpoint_rad_s", "electrical_power_W", "copper_loss_W", "friction_loss_W")
TIME_DECIMALS = 12         # engines' clocks agree to an ulp; round before taking the union
FLUSH_EVERY_S = 0.25       # wall time between writes: what a killed run can lose at most


def engine_columns(engine: str, out) -> list:
    """(column, values) of one engine's EngineOutput."""
    cols = [(f"{engine}.crank_angle_rad", out.crank_angle), (f"{engine}.crank_speed_rad_s", out.crank_speed),
            (f"{engine}.drive_torque_Nm", out.drive_torque)]
    for g, (bending, axial) in out.gauges.items():
        cols += [(f"{engine}.{g}.bending_ue", np.asarray(bending) * 1e6), (f"{engine}.{g}.axial_ue",
                                                                          np.asarray(axial) * 1e6)]
    for name, (unit, values) in out.extras.items():
        unit = unit.replace(" ", "").replace("/", "_")
        cols.append((f"{engine}.{name if name.endswith('_' + unit) else f'{name}_{unit}'}", values))
    return cols


def motor_columns(engine: str, trace: MotorTrace) -> list:
    return [(f"motor.{engine}.{f}", getattr(trace, f)) for f in MOTOR_FIELDS]


class TraceWriter:
    """Appends macro steps to ``traces.csv`` in blocks (module docstring); the header is fixed by
    the first step's outputs (engines that failed before it have no columns)."""

    def __init__(self, path: Path, flush_every_s: float = FLUSH_EVERY_S):
        self.path = Path(path)
        self.flush_every_s = flush_every_s
        self.columns = None
        self.fh = None
        self.rows = 0
        self._pending = []           # (column, t, values) of the steps since the last write
        self._last_write = time.monotonic()

    def write_step(self, outputs: dict) -> None:
        """``outputs``: {engine: (EngineOutput, MotorTrace | None)} of one macro step; on disk at the
        next block's write (at most ``flush_every_s`` later) or at :meth:`close`."""
        series = []     # (column, t, values)
        for engine, (out, trace) in outputs.items():
            series += [(c, out.t, v) for c, v in engine_columns(engine, out)]
            if trace is not None:
                series += [(c, trace.t, v) for c, v in motor_columns(engine, trace)]
        if not series:
            return
        if self.columns is None:
            self.columns = [c for c, _, _ in series]
            self.fh = open(self.path, "w", newline="", encoding="utf-8")
            self.fh.write(",".join(["time_s"] + self.columns) + "\n")
            self.fh.flush()
        self._pending += series
        if time.monotonic() - self._last_write >= self.flush_every_s:
            self.flush()

    def flush(self) -> None:
        """Write the steps collected since the last write (one block: the union of their sample
        times, one row each)."""
        self._last_write = time.monotonic()
        if not self._pending:
            return
        index = {c: j for j, c in enumerate(self.columns)}
        by_column = {}
        for c, t, v in self._pending:
            if c in index:      # a column the first step did not have cannot happen with fixed engines
                ts, vs = by_column.setdefault(c, ([], []))
                ts.append(t)
                vs.append(v)
        self._pending = []
        by_column = {c: (np.round(np.concatenate(ts, axis=None, dtype=float), TIME_DECIMALS),
                         np.concatenate(vs, axis=None, dtype=float)) for c, (ts, vs) in by_column.items()}
        times = np.unique(np.concatenate([t for t, _ in by_column.values()]))
        table = np.full((len(times), len(self.columns)), np.nan)
        for c, (t, v) in by_column.items():
            table[np.searchsorted(times, t), index[c]] = v
        # One %-format per row (a cell at a time was the run's largest cost, ~8 us a row); Python
        # prints every NaN as "nan", and no number contains it: those cells become empty.
        fmt = "%r" + ",%.10g" * len(self.columns) + "\n"
        text = "".join([fmt % tuple(r) for r in np.column_stack([times, table]).tolist()])
        self.fh.write(text.replace("nan", ""))   # one write per block, then flush: a kill loses at most it
        self.fh.flush()
        self.rows += len(times)

    def close(self) -> None:
        if self.fh is not None:
            self.flush()
            self.fh.close()
            self.fh = None


def read_traces(path: Path) -> tuple:
    """``(columns, array, note)`` from a traces.csv; empty cells are NaN. A last line cut short
    (a killed run) is dropped and ``note`` says so; any other malformed line raises ValueError
    naming the line."""
    path = Path(path)
    with open(path, newline="", encoding="utf-8") as fh:
        text = fh.read()
    complete = text.endswith("\n")
    lines = text.splitlines()
    note = None
    if not lines:
        raise ValueError(f"{path}: empty trace file")
    header = next(csv.reader([lines[0]]))
    body = lines[1:]
    if body and not complete:
        body = body[:-1]
        note = f"{path}: the last line was cut off (interrupted run) and is ignored"
    data = np.full((len(body), len(header)), np.nan)
    for i, line in enumerate(body):
        cells = line.split(",")
        if len(cells) != len(header):
            raise ValueError(f"{path}, line {i + 2}: {len(cells)} cells, the header has {len(header)}")
        for j, cell in enumerate(cells):
            if cell:
                try:
                    data[i, j] = float(cell)
                except ValueError:
                    raise ValueError(f"{path}, line {i + 2}, column '{header[j]}': not a number: {cell!r}") from None
    return header, data, note
