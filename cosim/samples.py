"""A run's macro steps collected into blocks of arrays, once for every consumer: ``traces.csv``
(:class:`cosim.traces.TraceWriter`) and the recording (:mod:`cosim.recording`) take the same
block.

:meth:`SampleCollector.add` keeps references to a macro step's arrays (a few appends per engine,
while they are in the cache: reading them out of the macro steps at the take cost twice as much);
:meth:`SampleCollector.take` concatenates them into one dict of arrays per engine::

    {"t", "angle", "speed", "torque": (k,) [s, rad, rad/s, N m],
     "gauges": {gauge: (bending, axial)} (dimensionless strain),
     "extras": {name: (unit, (k,) values)},
     "motor": {MotorTrace field: (k,) values} or None, "motor_units": {field: unit}}

The run takes a block at most every :data:`BLOCK_EVERY_S` of wall time (or every
:data:`BLOCK_SAMPLES` samples, so that a live viewer's batches stay small). Collecting the
arrays once for both consumers halved the recording's cost in the run's loop.

Owns: macro steps' samples collected into blocks. Boundaries: numpy only; no file, no rerun.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

BLOCK_EVERY_S = 0.25       # wall time between blocks: what a killed run's traces.csv can lose at most
BLOCK_SAMPLES = 5_000      # samples of all engines from which a block is taken at once


class EngineSamples:
    """One engine's samples since the last take."""

    def __init__(self):
        self.t, self.angle, self.speed, self.torque = [], [], [], []
        self.gauges, self.extras, self.units = {}, {}, {}
        self.motor, self.motor_units = {}, {}

    def add(self, out, trace) -> None:
        """``out``: an EngineOutput; ``trace``: its MotorTrace or None."""
        self.t.append(out.t)
        self.angle.append(out.crank_angle)
        self.speed.append(out.crank_speed)
        self.torque.append(out.drive_torque)
        for g, (bending, axial) in out.gauges.items():
            b, a = self.gauges.setdefault(g, ([], []))
            b.append(bending)
            a.append(axial)
        for name, (unit, values) in out.extras.items():
            self.extras.setdefault(name, []).append(values)
            self.units[name] = unit
        if trace is not None:
            self.motor_units = getattr(type(trace), "UNITS", {})
            for f in dataclasses.fields(trace):
                self.motor.setdefault(f.name, []).append(getattr(trace, f.name))

    def take(self) -> dict:
        cat = _cat
        return {"t": cat(self.t), "angle": cat(self.angle), "speed": cat(self.speed), "torque": cat(self.torque),
                "gauges": {g: (cat(b), cat(a)) for g, (b, a) in self.gauges.items()},
                "extras": {n: (self.units[n], cat(v)) for n, v in self.extras.items()},
                "motor": ({f: cat(v) for f, v in self.motor.items()} if self.motor else None),
                "motor_units": dict(self.motor_units)}


def _cat(arrays) -> np.ndarray:
    # axis=None ravels each piece (a scalar sample too) in the one C call.
    return np.concatenate(arrays, axis=None, dtype=float) if arrays else np.zeros(0)


class SampleCollector:
    """Macro steps -> blocks ``{engine: arrays}`` (module docstring)."""

    def __init__(self, every_s: float = BLOCK_EVERY_S, max_samples: int = BLOCK_SAMPLES):
        self.every_s, self.max_samples = every_s, max_samples
        self._engines: dict[str, EngineSamples] = {}
        self.samples = 0                  # samples collected since the last take
        self._last_take = time.monotonic()

    def add(self, outputs: dict) -> None:
        """``outputs``: {engine: (EngineOutput, MotorTrace | None)} of one macro step (engines
        without a sample are skipped)."""
        for engine, (out, trace) in outputs.items():
            n = np.size(out.t)
            if n == 0:
                continue
            buf = self._engines.get(engine)
            if buf is None:
                buf = self._engines[engine] = EngineSamples()
            buf.add(out, trace)
            self.samples += n

    def due(self, max_samples: int | None = None, every_s: float | None = None) -> bool:
        """A block is due: ``max_samples`` samples collected or ``every_s`` [s] of wall time since
        the last take (default: this collector's)."""
        max_samples = self.max_samples if max_samples is None else max_samples
        every_s = self.every_s if every_s is None else every_s
        return self.samples >= max_samples or time.monotonic() - self._last_take >= every_s

    def take(self) -> dict:
        """Everything collected since the last take, ``{engine: arrays}`` (empty when nothing was)."""
        block = {e: b.take() for e, b in self._engines.items()}
        self._engines, self.samples, self._last_take = {}, 0, time.monotonic()
        return block
