"""The recorder with its rerun side in a child process (what ``cosim run`` uses).

Why a process: importing rerun and converting arrays to chunks cost a TMM run of a few seconds
more than the TMM itself (about 0.35 s for the import and the first send alone). The child
writes while the engines run, on another core; the run only picks the linkage frames
(:mod:`cosim.recording.batch`) and hands a pickled batch of the sample blocks it collects for
its files anyway (:mod:`cosim.samples`) to a pipe a few times a second (from a thread, so a slow
child never stalls the run).

When the child starts: a live viewer's at once (the viewer opens while the engines set up). A
file's :data:`CHILD_START_AFTER_S` after the run's first data (the engines' stations or first
batch), or when the run hands the recording over, whichever comes first (or when
:data:`CHILD_START_BYTES` wait in the queue); until then the messages wait in the queue. The
child's start is ~0.5 s of CPU (Python, numpy, rerun's import), and on a machine of two vCPUs it
slows the engines beside it: started with the engines' set-up it made the TMM's set-up ~60 %
slower (0.041 -> 0.065 s median at 241 rpm), started at the first data it made the loop of a
30-revolution run 10-18 % slower (with the start delayed past the loop: 1 % and less, the
recording's own batching). A short run's child now starts while the run writes its other files;
a long run's pays the start once. A run killed (SIGKILL) within its first
:data:`CHILD_START_AFTER_S` of data leaves no recording (``traces.csv`` holds its steps); a run
interrupted (Ctrl-C, SIGTERM) hands its recording over as every run does.

The child ignores Ctrl-C (it runs in its own session): the run closes the recording when it
ends, interrupted or not. If the run's process dies, the child sees its input end and finishes
the file all the same. ``RecorderProcess.close`` waits for the child at most
``close_timeout_s``; with ``--serve`` the child keeps serving until
:meth:`RecorderProcess.serve_until_interrupted` returns (Ctrl-C).

Messages (pickled tuples on the child's stdin): ``("open", kwargs of StreamWriter)``,
``("stations", {...})``, ``("batch", batch)``, ``("reference", Reference)``,
``("text", path, text)``, ``("close",)``. The child answers on its stdout with JSON lines:
``{"serving": url}`` (serve mode, once everything is flushed) and ``{"warnings": [...]}`` when the
file is finished.

Owns: the recorder in a child process. Boundaries: the rerun side is cosim.recording.recorder.
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import pickle
import queue
import selectors
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from ..children import stop_process
from .batch import StepBatcher
from .recorder import Recorder, checked_arguments
from .sinks import ViewerOptions, serve_until_interrupted

log = logging.getLogger("cosim.recording")
_DONE = object()
_BEFORE_DATA = ("open", "text", "reference")    # messages that do not start a file's child
CHILD_START_AFTER_S = 2.0     # a file's child starts this long after the run's first data (or at its end)
CHILD_START_BYTES = 64e6      # ... or when this many bytes of messages wait for it
WRITER_NICE = 10              # the child's scheduling priority offset (Unix nice)


class RecorderProcess(Recorder):
    """:class:`cosim.recording.recorder.Recorder` with the rerun side in a child process (same
    arguments and methods, plus ``close_timeout_s``)."""

    close_timeout_s = 120.0

    def __init__(self, scenario, engines: dict | None = None, mode: str = "prescribed", *, save_path=None,
                 spawn: bool = False, connect: str | None = None, viewer: ViewerOptions | None = None,
                 exaggeration: float | None = None, linkage_every: int = 1, linkage_fps: float | None = None,
                 application_id: str = "flexlink-bench"):
        self.spec, viewer = checked_arguments(scenario, engines, mode, save_path, spawn, connect, viewer,
                                              exaggeration, linkage_every, linkage_fps)
        self.save_path, self.viewer = save_path, viewer
        self.batcher = StepBatcher(linkage_every, linkage_fps)
        self._record_colors, self._closed = {}, False
        self._broken = None
        self._proc: subprocess.Popen | None = None
        self._queue: queue.Queue = queue.Queue()
        self._thread = threading.Thread(target=self._pump, name="recording-pipe", daemon=True)
        self._starting = threading.Lock()
        if viewer.viewer != "save":
            self._start_child()
        self._send("open", dict(spec=self.spec, save_path=None if save_path is None else str(save_path),
                                viewer=viewer, exaggeration=exaggeration, application_id=application_id,
                                stations=engines))

    # -- transport ---------------------------------------------------------------------------------
    def set_stations(self, stations: dict) -> None:
        self._check_open()
        self._send("stations", stations)

    def _take(self, block=None):
        batch = self.batcher.take(block)
        if batch is not None:
            self._send("batch", batch)

    def _reference(self, ref):
        self._send("reference", ref)

    def _text(self, path, text):
        self._send("text", path, text)

    def _start_child(self):
        # Once, from the run's thread or the start timer's, whichever comes first.
        with self._starting:
            if self._proc is not None:
                return
            root = str(Path(__file__).resolve().parents[2])            # so the child imports this cosim
            env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
            # rerun's own log lines (coloured, one per failed write) would repeat what the child
            # reports as warnings; a user's RUST_LOG still wins.
            env.setdefault("RUST_LOG", "off")
            level = logging.getLogger("cosim").getEffectiveLevel()
            # -P: not the working directory first on the child's path (another cosim there would be
            # imported instead of this one).
            try:
                self._proc = subprocess.Popen([sys.executable, "-P", "-m", "cosim.recording.process", str(level)],
                                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env,
                                              start_new_session=True)
                self._thread.start()
            except (OSError, RuntimeError) as exc:       # no memory (or processes) left for it
                self._not_started = exc
                if self._proc is not None:
                    self._proc.kill()
                    self._proc = None

    def _send(self, *message):
        item = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
        self._queue.put(item)
        if self._proc is None and message[0] not in _BEFORE_DATA:
            if self._timer is None and message[0] != "close":
                # CHILD_START_AFTER_S after the first data even if no message follows (a long
                # macro step): a run killed later leaves its recording.
                self._timer = threading.Timer(CHILD_START_AFTER_S, self._start_child)
                self._timer.daemon = True
                try:
                    self._timer.start()
                except RuntimeError:        # no thread to be had (memory): start the child now
                    self._start_child()
            self._waiting_bytes += len(item)
            if message[0] == "close" or self._waiting_bytes >= CHILD_START_BYTES:
                self._start_child()

    @property
    def writer_started(self) -> bool:
        """Whether the child process has been started (see the module docstring for when)."""
        return self._proc is not None

    _timer = None                 # starts the child CHILD_START_AFTER_S after the first data
    _not_started = None           # why the child could not be started (OSError, RuntimeError)
    #: After :meth:`close`: why the file may be incomplete (the writer died, did not start, was
    #: stopped, or stopped reading), None when it finished.
    incomplete = None
    _waiting_bytes = 0            # bytes of data messages queued before the child started

    def _pump(self):
        """Thread: queued messages into the child's stdin (blocking here, not in the run)."""
        while True:
            item = self._queue.get()
            if item is _DONE:
                break
            if self._broken is None:
                try:
                    self._proc.stdin.write(item)
                    self._proc.stdin.flush()            # a live viewer sees each batch now
                except (BrokenPipeError, OSError) as exc:
                    self._broken = exc
        try:
            self._proc.stdin.close()
        except OSError:
            pass

    # -- the end -----------------------------------------------------------------------------------
    def hand_over(self) -> None:
        """Send the rest and the close message without waiting: the child finishes the file
        while the run writes its parquet and figures (:meth:`close` waits)."""
        super().hand_over()
        self._take()
        self._send("close")
        if self._timer is not None:
            self._timer.cancel()
        self._queue.put(_DONE)

    def close(self) -> list:
        """Hand over the rest (unless :meth:`hand_over` did) and wait for the child to finish the
        file (at most ``close_timeout_s``); with ``--serve`` until it serves everything. Returns
        warnings."""
        if self._closed:
            return []
        if not self._handed_over:
            self.hand_over()
        self._closed = True
        with self._starting:        # a start in progress on the timer's thread finishes first: its
            pass                    # child is assigned before its pipe thread starts
        if self._proc is None:
            self.incomplete = (f"the recording writer could not be started ({self._not_started}); "
                               f"{self.save_path} is not written")
            log.warning("recording: %s", self.incomplete)
            return [self.incomplete]
        deadline = time.monotonic() + self.close_timeout_s
        self._thread.join(timeout=self.close_timeout_s)
        problems, finished = [], False
        for status in self._status_lines(deadline):
            problems += status.get("warnings", [])
            if "serving" in status:
                self.serving = status["serving"]
                break
            if "warnings" in status:          # the file is finished: no need to wait for the exit
                finished = True
                break
        broken = []                           # why the file may be incomplete
        if self.serving is None and not finished:
            try:
                self._proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                self._proc.kill()
                broken.append(f"the recording writer did not finish within {self.close_timeout_s:g} s and was "
                              f"stopped; {self.save_path} may be incomplete")
            if self._proc.returncode not in (0, None) and not broken:
                broken.append(f"the recording writer failed (exit status {self._proc.returncode}, its error is "
                              f"above); {self.save_path} may be incomplete")
        if self._broken is not None:
            broken.append(f"the recording writer stopped reading ({self._broken}); {self.save_path} may be "
                          "incomplete")
        self.incomplete = "; ".join(broken) or None
        for p in problems + broken:
            log.warning("recording: %s", p)
        return problems + broken

    serving = None              # the gRPC URL while the child serves (viewer 'serve')

    def serve_until_interrupted(self) -> None:
        """With ``--serve``: keep the child serving until Ctrl-C, then let it finish the file."""
        if self.serving is None:
            return

        def stop(signum, frame):
            raise KeyboardInterrupt
        previous = signal.signal(signal.SIGTERM, stop)       # SIGTERM stops serving as Ctrl-C does
        try:
            while self._proc.poll() is None:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
        finally:
            signal.signal(signal.SIGTERM, previous)
            self.stop_serving()

    def stop_serving(self) -> None:
        """Stop the child's servers; it finishes its file (footer) on SIGTERM."""
        stop_process(self._proc, grace_s=30)

    def _status_lines(self, deadline):
        """The child's JSON status lines until it closes its stdout or the deadline passes."""
        sel = selectors.DefaultSelector()
        sel.register(self._proc.stdout, selectors.EVENT_READ)
        try:
            while time.monotonic() < deadline:
                if not sel.select(timeout=max(0.0, deadline - time.monotonic())):
                    return
                line = self._proc.stdout.readline()
                if not line:
                    return
                try:
                    yield json.loads(line)
                except ValueError:
                    continue
        finally:
            sel.close()


# -- the child ----------------------------------------------------------------------------------------
class _NoPandas:
    """Import hook refusing pandas. pyarrow imports pandas on the first ``pa.array`` of strings only
    to check whether the data are pandas objects (rerun's text conversion goes through it): 0.2-0.4 s
    of CPU that the writer never needs, on the core the engines run on."""

    def find_spec(self, name, path=None, target=None):
        if name == "pandas" or name.startswith("pandas."):
            raise ImportError("the recording writer does not use pandas")


def _child(level: int) -> int:
    parent = os.getppid()
    sys.meta_path.insert(0, _NoPandas())
    try:
        # The recording yields to the simulation when the cores are busy (it catches up at close).
        os.nice(WRITER_NICE)
    except (AttributeError, OSError):
        pass
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def terminate(signum, frame):
        raise KeyboardInterrupt
    signal.signal(signal.SIGTERM, terminate)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Prefix())
    logger = logging.getLogger("cosim")
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False
    status = sys.stdout

    def report(**kw):
        try:
            status.write(json.dumps(kw) + "\n")
            status.flush()
        except (BrokenPipeError, OSError, ValueError):
            pass

    writer, inp = None, sys.stdin.buffer
    try:
        while True:
            try:
                message = pickle.load(inp)
            except EOFError:                          # the run's process ended without "close"
                break
            kind, *args = message
            if kind == "open":
                from .writer import StreamWriter          # imports rerun: ~0.5 s of CPU
                writer = StreamWriter(**args[0])
            elif kind == "close":
                break
            elif writer is not None:
                {"stations": writer.set_stations, "batch": writer.write, "reference": writer.reference,
                 "text": writer.text}[kind](*args)
    except KeyboardInterrupt:
        pass
    except Exception as exc:          # one line for the run's console, not a traceback
        what = "out of memory" if isinstance(exc, MemoryError) else f"{type(exc).__name__}: {exc}"
        logger.error("recording: the writer stopped: %s", what)
        with contextlib.suppress(Exception):
            if writer is not None:
                writer.finish()       # the footer, if it can
        return 1
    if writer is None:
        return 0
    try:
        writer.complete()
        if writer.viewer.viewer == "serve" and writer.urls:
            writer.rec.flush(timeout_sec=writer.viewer.timeout_s)
            report(serving=writer.urls[0])
            serve_until_interrupted(parent)
    except KeyboardInterrupt:
        pass
    report(warnings=writer.finish())
    return 0


class _Prefix(logging.Formatter):
    """As the ``cosim`` command's messages: warnings and errors prefixed, the rest as they are."""

    def format(self, record):
        text = record.getMessage()
        return text if record.levelno < logging.WARNING else f"{record.levelname.lower()}: {text}"


if __name__ == "__main__":
    sys.exit(_child(int(sys.argv[1]) if len(sys.argv) > 1 else logging.WARNING))
