"""Collect the master's macro steps into batches for the recording: numpy only, no rerun.

A run calls :meth:`StepBatcher.add` after every macro step (a few microseconds: it keeps
references to the step's arrays, while they are in the cache: reading them out of the macro
steps' outputs at the take cost twice as much); :meth:`StepBatcher.take` concatenates what was
collected into one :class:`dict` per engine, the linkage frames stacked in :class:`FrameBlock`,
which the writer sends as one chunk per entity (:mod:`cosim.recording.writer`). The linkage is
kept at *display rate*: the last sample of a macro step, at most ``linkage_fps`` frames per simulated second (and every ``linkage_every``-th
macro step), and always the run's last step. Drawing every macro step cost most of the
recording's time and gave frames no viewer shows.

Owns: macro steps collected into batches; the linkage at display rate. Boundaries: no rerun
import.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np


def check_linkage_rate(linkage_every, linkage_fps) -> None:
    if not (isinstance(linkage_every, int) and not isinstance(linkage_every, bool) and linkage_every >= 1):
        raise ValueError(f"linkage_every must be a positive integer, got {linkage_every!r}")
    if linkage_fps is not None and not (isinstance(linkage_fps, (int, float)) and math.isfinite(linkage_fps)
                                        and linkage_fps > 0):
        raise ValueError(f"linkage_fps (--linkage-fps) must be a positive number of frames per simulated "
                         f"second, got {linkage_fps!r}")


@dataclasses.dataclass(frozen=True)
class FrameBlock:
    """Consecutive linkage frames of one engine with the same links and node counts, stacked:
    one array a link, so a batch pickles a few arrays instead of one small array a link and
    frame (~2 ms of a 30-revolution run's ~450 frames)."""
    t: np.ndarray            # (F,) simulated time [s]
    angle: np.ndarray        # (F,) cumulative crank angle [rad]
    nodes: dict              # {link: (F, n, 2)} deformed node positions [m], global frame


def frame_blocks(frames: list) -> list:
    """``[(t, angle, {link: (n, 2) nodes})]`` -> the fewest :class:`FrameBlock`: one, unless the
    links or a link's node count change between frames (a new block there)."""
    if not frames:
        return []
    links = frames[0][2].keys()
    if all(f[2].keys() == links for f in frames):
        try:
            return [_block(frames)]
        except ValueError:            # node counts differ between frames
            pass
    blocks, group, key = [], [], None
    for f in frames:
        k = tuple((link, np.shape(v)) for link, v in f[2].items())
        if group and k != key:
            blocks.append(_block(group))
            group = []
        group.append(f)
        key = k
    return blocks + [_block(group)]


def _block(frames) -> FrameBlock:
    return FrameBlock(np.array([f[0] for f in frames], dtype=float), np.array([f[1] for f in frames], dtype=float),
                      {link: np.array([f[2][link] for f in frames], dtype=float)
                       for link in frames[0][2]})


class _EngineBuffer:
    """One engine's samples since the last :meth:`StepBatcher.take`."""

    def __init__(self):
        self.t, self.angle, self.speed, self.torque = [], [], [], []
        self.gauges, self.extras, self.units = {}, {}, {}
        self.motor, self.motor_units = {}, {}
        self.frames = []

    def add(self, out, trace) -> None:
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
        out = {"t": cat(self.t), "angle": cat(self.angle), "speed": cat(self.speed), "torque": cat(self.torque),
               "gauges": {g: (cat(b), cat(a)) for g, (b, a) in self.gauges.items()},
               "extras": {n: (self.units[n], cat(v)) for n, v in self.extras.items()},
               "motor": ({f: cat(v) for f, v in self.motor.items()} if self.motor else None),
               "motor_units": dict(self.motor_units), "frames": frame_blocks(self.frames)}
        self.__init__()
        return out


def _cat(arrays) -> np.ndarray:
    # axis=None ravels each piece (a scalar sample too) in the one C call.
    return np.concatenate(arrays, axis=None, dtype=float) if arrays else np.zeros(0)


class StepBatcher:
    """Macro steps -> batches (see the module docstring)."""

    def __init__(self, linkage_every: int = 1, linkage_fps: float | None = None):
        check_linkage_rate(linkage_every, linkage_fps)
        self.linkage_every = linkage_every
        self.linkage_fps = linkage_fps
        self._engines: dict[str, _EngineBuffer] = {}
        self._events: list = []
        self._last_frame: dict[str, float] = {}
        self.samples = 0                 # samples collected since the last take

    def add(self, step) -> None:
        """Collect one :class:`cosim.master.MacroStep` (engines with no sample are skipped)."""
        last = step.step == step.n_steps
        stride = (step.step - 1) % self.linkage_every == 0
        for engine, (out, trace) in step.outputs.items():
            n = np.size(out.t)
            if n == 0:
                continue
            buf = self._engines.get(engine)
            if buf is None:
                buf = self._engines[engine] = _EngineBuffer()
            buf.add(out, trace)
            self.samples += n
            if out.nodes:
                t_end = float(out.t[-1])
                if last or (stride and self._frame_due(engine, t_end)):
                    # The macro step's last sample (a view; copied when the batch is stacked).
                    buf.frames.append((t_end, float(out.crank_angle[-1]),
                                       {link: np.asarray(v)[-1] for link, v in out.nodes.items()}))
                    self._last_frame[engine] = t_end
        for engine, message in (step.failed or {}).items():
            self._events.append((float(step.t), engine, str(message)))

    def _frame_due(self, engine, t) -> bool:
        if self.linkage_fps is None or engine not in self._last_frame:
            return True
        return t - self._last_frame[engine] >= (1.0 - 1e-6) / self.linkage_fps

    def take(self) -> dict | None:
        """Everything collected since the last take ({"engines": {engine: arrays}, "events": [...]}),
        or None when nothing was."""
        if not self._engines and not self._events:
            return None
        batch = {"engines": {e: b.take() for e, b in self._engines.items()}, "events": self._events}
        self._engines, self._events, self.samples = {}, [], 0
        return batch
