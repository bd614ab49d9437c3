"""The recorder API: stream a co-simulation run into one rerun recording.

:class:`Recorder` does it in the calling process; :class:`cosim.recording.process.RecorderProcess`
has the same methods and does the rerun side in a child process (what ``cosim run`` uses: the
run then pays only for collecting its arrays). Both take a macro step after every step of the
master (``log_macro_step`` is a ready-made callback body), records (``log_reference``) and text
(``log_text``), and :meth:`close` finishes the file.

Owns: ``Recorder``: the recording of one run in this process. Boundaries: no run logic.
"""
from __future__ import annotations

import logging
import math

from ..samples import BLOCK_EVERY_S, BLOCK_SAMPLES
from .batch import StepBatcher, check_linkage_rate
from .layout import part
from .references import make_references
from .sinks import ViewerOptions
from .spec import RecordingSpec, spec_from_scenario

log = logging.getLogger("cosim.recording")


def check_exaggeration(exaggeration) -> None:
    if exaggeration is not None and not (isinstance(exaggeration, (int, float)) and math.isfinite(exaggeration)
                                         and exaggeration > 0):
        raise ValueError(f"exaggeration (--exaggeration) must be a positive finite number (leave it out to choose "
                         f"it from the largest deformation), got {exaggeration!r}")


def viewer_options(save_path, spawn: bool, connect: str | None, viewer: ViewerOptions | None) -> ViewerOptions:
    """The viewer of the old keyword arguments (``spawn``, ``connect``) or ``viewer``; refuses a
    recording with nowhere to go."""
    if viewer is None:
        viewer = (ViewerOptions("spawn") if spawn else ViewerOptions("connect", url=connect) if connect
                  else ViewerOptions("save"))
    if save_path is None and viewer.viewer in ("save", "none"):
        raise ValueError("Recorder needs somewhere to send the recording: give save_path (an .rrd file), "
                         "spawn=True or connect='rerun+http://host:port/proxy'")
    return viewer


def checked_arguments(scenario, engines, mode, save_path, spawn, connect, viewer, exaggeration, linkage_every,
                      linkage_fps) -> tuple:
    """``(spec, viewer)`` of a recorder's arguments, checked (the same for :class:`Recorder` and
    its child-process twin :class:`cosim.recording.process.RecorderProcess`)."""
    viewer = viewer_options(save_path, spawn, connect, viewer)
    check_exaggeration(exaggeration)
    check_linkage_rate(linkage_every, linkage_fps)
    spec = scenario if isinstance(scenario, RecordingSpec) else spec_from_scenario(scenario, mode, engines or ())
    return spec, viewer


def text_path(entity: str) -> str:
    """A relative text entity goes under /scenario (``"records/scores"`` -> ``/scenario/records/scores``)."""
    return entity if entity.startswith("/") else "/scenario/" + "/".join(part(p) for p in entity.split("/"))


class Recorder:
    """Streams a run into one recording, in this process (layout, units and timelines:
    :mod:`cosim.recording`).

    ``scenario``: a :class:`cosim.scenario.Scenario` or a :class:`RecordingSpec`;
    ``engines``: {engine: {link: node stations [m]}} (where each reported node sits on its link;
    an engine left out is still recorded, its nodes taken as evenly spaced);
    ``save_path``: the .rrd file (the default use, headless); ``spawn``/``connect`` or
    ``viewer``: also a viewer (:mod:`cosim.recording.sinks`);
    ``exaggeration``: the factor on each link's deformation in the linkage drawing, None to
    choose it from the largest deformation; ``linkage_every`` / ``linkage_fps``: draw the
    linkage every n-th macro step / at most this many frames per simulated second.
    """

    batch_samples = BLOCK_SAMPLES       # samples collected before a batch goes to the writer
    batch_interval_s = BLOCK_EVERY_S    # ... or this much wall time

    def __init__(self, scenario, engines: dict | None = None, mode: str = "prescribed", *, save_path=None,
                 spawn: bool = False, connect: str | None = None, viewer: ViewerOptions | None = None,
                 exaggeration: float | None = None, linkage_every: int = 1, linkage_fps: float | None = None,
                 application_id: str = "flexlink-bench"):
        spec, viewer = checked_arguments(scenario, engines, mode, save_path, spawn, connect, viewer, exaggeration,
                                         linkage_every, linkage_fps)
        from .writer import StreamWriter             # rerun is imported here, not by the package
        self.spec = spec
        self.save_path = save_path
        self.batcher = StepBatcher(linkage_every, linkage_fps)
        self.writer = StreamWriter(spec, save_path, viewer, exaggeration, application_id, stations=engines)
        self._record_colors: dict = {}
        self._closed = False

    # -- public API --------------------------------------------------------------------------------
    def set_stations(self, stations: dict) -> None:
        """{engine: {link: node stations [m]}}, when the engines know their meshes."""
        self._check_open()
        self.writer.set_stations(stations)

    def log_macro_step(self, step, samples: bool = True) -> None:
        """Collect one :class:`cosim.master.MacroStep`; hand a batch to the writer now and then.
        ``samples=False``: the step's linkage frames and events only; the caller collects the
        samples (:class:`cosim.samples.SampleCollector`, once for the run's files and the
        recording) and hands each block to :meth:`log_samples`."""
        self._check_open()
        self.batcher.add(step, samples)
        if samples and self.batcher.due(self.batch_samples, self.batch_interval_s):
            self._take()

    def log_samples(self, block: dict) -> None:
        """A block of samples (:meth:`cosim.samples.SampleCollector.take`) of the macro steps logged
        with ``samples=False`` since the last block: a batch goes to the writer with their frames
        and events."""
        self._check_open()
        self._take(block)

    def log_reference(self, gauge: str, label: str, t=None, angle=None, bending_ue=None, axial_ue=None,
                      kind: str = "measurement") -> None:
        """A record for a gauge, drawn under ``/records``: a history over time (``t`` [s]), over one
        crank revolution (``angle`` [rad], repeated over every revolution the run covers), or
        constant lines (neither; e.g. (+peak, -peak)). Values in microstrain; placed on the
        timelines at :meth:`close` (:mod:`cosim.alignment`); ``kind`` goes into the series names."""
        self._check_open()
        # One colour per record, the same in every gauge's plot.
        index = self._record_colors.setdefault(label, len(self._record_colors))
        for ref in make_references(gauge, label, t, angle, bending_ue, axial_ue, kind, index):
            self._reference(ref)

    def log_text(self, entity: str, text: str) -> None:
        """A static text document; a relative ``entity`` goes under ``/scenario``."""
        self._check_open()
        self._text(text_path(entity), text)

    def flush(self) -> None:
        """Send everything collected so far."""
        self._check_open()
        self._take()
        self.writer.send()

    def hand_over(self) -> None:
        """Nothing more will be logged: let the writer finish in its own time (a child process
        does it while the run writes its other files; :meth:`close` then waits). In process,
        nothing to do before :meth:`close`. Logging after it raises."""
        self._check_open()
        self._handed_over = True

    _handed_over = False

    def close(self) -> list:
        """Send the rest and the records, finish the file (footer) and the viewer; idempotent.
        Returns the warnings (also logged), e.g. a viewer that did not take everything."""
        if self._closed:
            return []
        self._closed = True
        self._take()
        problems = self.writer.close()
        for p in problems:
            log.warning("recording: %s", p)
        return problems

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- in-process transport (RecorderProcess overrides these three) -----------------------------
    def _take(self, block=None):
        self.writer.write(self.batcher.take(block))

    def _reference(self, ref):
        self.writer.reference(ref)

    def _text(self, path, text):
        self.writer.text(path, text)

    def _check_open(self):
        if self._closed or self._handed_over:
            raise RuntimeError("the Recorder is closed")

