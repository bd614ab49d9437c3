"""The run's trace table, ``traces.csv``: one time column and one column per trace.

Columns are named ``<engine>.<quantity>_<unit>`` (``tmm.drive_torque_Nm``,
``exudyn.coupler_mid.bending_ue`` with ue = microstrain, ``motor.tmm.current_A``); the first is
``time_s``. Engines sample at different times (exudyn once per macro step, the transfer-matrix
model and MuJoCo at every internal step), so the rows are the union of all sample times and a
cell is empty where a trace has no sample.

The file is appended in blocks of macro steps (:mod:`cosim.samples`: one write and flush at most
every 0.25 s of wall time, and at the run's end): an interrupted run (Ctrl-C, SIGTERM, an error:
the run writes its last block) keeps every completed step, a killed one (SIGKILL) every step up
to the last block. (A write per macro step cost the run ~9 us a row, 0.47 s on 0.7 s of engine
time for 150 revolutions of the FE rig at 1 deg; the union of the engines' times and the table
per block instead of per step leave the rows' formatting, ~3 us a row.) :func:`read_traces`
reads a killed run's file and drops (and reports) a last line cut off by the kill.

Owns: ``traces.csv``: column names with units, appending blocks. Boundaries: no post-processing;
the blocks are cosim.samples.
"""
from __future__ import annotations

import contextlib
import csv
import os
from pathlib import Path

import numpy as np

from .files import open_new


MOTOR_FIELDS = ("current_A", "voltage_V", "torque_em_Nm", "drive_torque_Nm", "motor_speed_rad_s",
                "setpoint_rad_s", "electrical_power_W", "copper_loss_W", "friction_loss_W")
TIME_DECIMALS = 12         # engines' clocks agree to an ulp; round before taking the union


def engine_columns(engine: str, arrays: dict) -> list:
    """``(column, t, values)`` of one engine's block (:meth:`cosim.samples.SampleCollector.take`)."""
    t = arrays["t"]
    cols = [(f"{engine}.crank_angle_rad", t, arrays["angle"]), (f"{engine}.crank_speed_rad_s", t, arrays["speed"]),
            (f"{engine}.drive_torque_Nm", t, arrays["torque"])]
    for g, (bending, axial) in arrays["gauges"].items():
        cols += [(f"{engine}.{g}.bending_ue", t, bending * 1e6), (f"{engine}.{g}.axial_ue", t, axial * 1e6)]
    for name, (unit, values) in arrays["extras"].items():
        unit = unit.replace(" ", "").replace("/", "_")
        cols.append((f"{engine}.{name if name.endswith('_' + unit) else f'{name}_{unit}'}", t, values))
    motor = arrays.get("motor")
    if motor:
        cols += [(f"motor.{engine}.{f}", motor["t"], motor[f]) for f in MOTOR_FIELDS]
    return cols


class TracesNotWritten(OSError):
    """``traces.csv`` could not take a block (a full disk, a file-size limit): the file was cut
    back to its last whole row, which the message names."""


class TraceWriter:
    """Appends blocks of macro steps to ``traces.csv`` (module docstring); the header is fixed by
    the first block (engines that failed before it have no columns). A block is written whole or
    not at all: a write that fails part-way (a full disk) is cut back, so the file always ends on
    a whole row."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.columns = None
        self.fh = None
        self.rows = 0
        self.size = 0            # bytes of whole rows in the file
        self.last_t = None       # the time of its last whole row [s]

    def write_block(self, block: dict) -> None:
        """``block``: ``{engine: arrays}`` of :meth:`cosim.samples.SampleCollector.take`; one row
        per sample time of the union of the engines', written and flushed."""
        series = [c for engine, arrays in block.items() for c in engine_columns(engine, arrays)]
        series = [(c, t, v) for c, t, v in series if len(t)]
        if not series:
            return
        if self.columns is None:
            self.columns = [c for c, _, _ in series]
            self.fh = open_new(self.path, "wb", buffering=0)
            self._append((",".join(["time_s"] + self.columns) + "\n").encode())
        index = {c: j for j, c in enumerate(self.columns)}
        series = [(index[c], np.round(t, TIME_DECIMALS), v) for c, t, v in series
                  if c in index]      # a column the first block did not have cannot happen with fixed engines
        times = np.unique(np.concatenate([t for _, t, _ in series]))
        table = np.full((len(times), len(self.columns)), np.nan)
        for j, t, v in series:
            table[np.searchsorted(times, t), j] = v
        # One %-format per row (a cell at a time was the run's largest cost, ~8 us a row); Python
        # prints every NaN as "nan", and no number contains it: those cells become empty.
        fmt = "%r" + ",%.10g" * len(self.columns) + "\n"
        text = "".join([fmt % tuple(r) for r in np.column_stack([times, table]).tolist()])
        self._append(text.replace("nan", "").encode())   # one write per block: a kill loses at most it
        self.rows += len(times)
        self.last_t = float(times[-1])

    def _append(self, data: bytes) -> None:
        """Write ``data`` whole (unbuffered: the bytes are in the file when this returns), or cut
        the file back to where it was and raise :class:`TracesNotWritten`."""
        done = 0
        try:
            while done < len(data):
                done += self.fh.write(memoryview(data)[done:])
        except OSError as exc:
            self._keep_whole_rows(data, done)
            end = "no row" if self.last_t is None else f"its last whole row, t = {self.last_t:.6g} s"
            raise TracesNotWritten(exc.errno, f"{self.path}: {exc.strerror}; the file ends at {end}") from None
        self.size += len(data)

    def _keep_whole_rows(self, data: bytes, done: int) -> None:
        """After a write of ``data`` failed with ``done`` bytes of it in the file: keep the whole
        rows among them (as many as fit), cut the rest."""
        keep = data.rfind(b"\n", 0, done) + 1
        try:
            os.ftruncate(self.fh.fileno(), self.size + keep)
        except OSError:
            return
        self.size += keep
        if keep:
            start = data.rfind(b"\n", 0, keep - 1) + 1
            with contextlib.suppress(ValueError):       # the header's first field is no time
                self.last_t = float(data[start:keep].split(b",", 1)[0])

    def close(self) -> None:
        if self.fh is not None:
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
