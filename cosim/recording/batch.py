"""Collect the master's macro steps into batches for the recording: numpy only, no rerun.

A run calls :meth:`StepBatcher.add` after every macro step; its samples go into a
:class:`cosim.samples.SampleCollector` (references to the step's arrays, concatenated at the
take), unless the run collects them once for all its consumers and hands the block to
:meth:`StepBatcher.take` (``cosim run`` does: ``traces.csv`` takes the same block). A batch is
``{"engines": {engine: the block's arrays + "frames"}, "events": [...]}``, the linkage frames
stacked in :class:`FrameBlock`, which the writer sends as one chunk per entity
(:mod:`cosim.recording.writer`). The linkage is kept at *display rate*: the last sample of a
macro step, at most ``linkage_fps`` frames per simulated second (and every ``linkage_every``-th
macro step), and always the run's last step. Drawing every macro step cost most of the
recording's time and gave frames no viewer shows.

Owns: macro steps collected into batches; the linkage at display rate. Boundaries: no rerun
import; the samples are cosim.samples.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..samples import SampleCollector


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


class StepBatcher:
    """Macro steps -> batches (see the module docstring)."""

    def __init__(self, linkage_every: int = 1, linkage_fps: float | None = None):
        check_linkage_rate(linkage_every, linkage_fps)
        self.linkage_every = linkage_every
        self.linkage_fps = linkage_fps
        self._samples = SampleCollector()
        self._frames: dict[str, list] = {}
        self._events: list = []
        self._last_frame: dict[str, float] = {}

    @property
    def samples(self) -> int:
        """Samples collected since the last take."""
        return self._samples.samples

    def due(self, max_samples: int | None = None, every_s: float | None = None) -> bool:
        """A batch is due (:meth:`cosim.samples.SampleCollector.due`)."""
        return self._samples.due(max_samples, every_s)

    def add(self, step, samples: bool = True) -> None:
        """Collect one :class:`cosim.master.MacroStep` (engines with no sample are skipped);
        ``samples=False``: its linkage frames and events only (the caller collects the samples and
        hands them to :meth:`take`)."""
        if samples:
            self._samples.add(step.outputs)
        last = step.step == step.n_steps
        stride = (step.step - 1) % self.linkage_every == 0
        for engine, (out, trace) in step.outputs.items():
            if out.nodes and np.size(out.t):
                t_end = float(out.t[-1])
                if last or (stride and self._frame_due(engine, t_end)):
                    # The macro step's last sample (a view; copied when the batch is stacked).
                    self._frames.setdefault(engine, []).append(
                        (t_end, float(out.crank_angle[-1]), {link: np.asarray(v)[-1] for link, v in out.nodes.items()}))
                    self._last_frame[engine] = t_end
        for engine, message in (step.failed or {}).items():
            self._events.append((float(step.t), engine, str(message)))

    def _frame_due(self, engine, t) -> bool:
        if self.linkage_fps is None or engine not in self._last_frame:
            return True
        return t - self._last_frame[engine] >= (1.0 - 1e-6) / self.linkage_fps

    def take(self, block: dict | None = None) -> dict | None:
        """Everything collected since the last take ({"engines": {engine: arrays}, "events": [...]}),
        or None when nothing was; ``block``: the samples, collected by the caller
        (:meth:`cosim.samples.SampleCollector.take`), instead of this batcher's own."""
        own = self._samples.take()
        block = own if block is None else block
        if not block and not self._events:
            return None
        # A frame is the last sample of a macro step whose samples are in the block.
        engines = {e: {**arrays, "frames": frame_blocks(self._frames.pop(e, []))} for e, arrays in block.items()}
        batch = {"engines": engines, "events": self._events}
        self._events = []
        return batch
