"""Signals during a command: remembered, raised as KeyboardInterrupt, and the exit status.

SIGINT and SIGTERM are remembered and raised as KeyboardInterrupt at the next macro step, even
when an engine's own solver swallows the exception (the run is then cut back to what was
written: :mod:`cosim.interrupted`).

This module imports the standard library only: the ``cosim`` command imports it before anything
else, and an import of numpy or tmm_core here (3 s on a loaded machine) was a window in which
Ctrl-C printed a traceback instead of ending quietly.

Owns: the signal handling and the exit status after a signal. Boundaries: no files, no numerics.
"""
from __future__ import annotations

import contextlib
import signal
import sys


#: The signals this process has been interrupted by, in order (the exit status follows the last).
_received: list[int] = []
#: Interrupts Python could not raise while a command started (before a run's :class:`Interrupts`):
#: the signal of each, taken by the next :class:`Interrupts` (:class:`LostInterrupts`).
_lost: list[int] = []


def note_signal(signum: int) -> None:
    """Remember that ``signum`` interrupted this process (for :func:`exit_status`)."""
    _received.append(int(signum))


def exit_status() -> int:
    """The exit status of a command ended by a signal, by the shell's convention 128 + the signal:
    130 after Ctrl-C (SIGINT, also when Python raised KeyboardInterrupt itself), 143 after SIGTERM."""
    return 128 + (_received[-1] if _received else signal.SIGINT)


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in ``exc``'s chain of causes. A Ctrl-C while a compiled
    extension initialises comes back as ``ImportError('initialization failed')`` caused by it
    (pybind11 modules: mujoco); taken for a broken install, it dropped the engine and the run
    went on as if no Ctrl-C had come."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _raise_interrupt(signum, frame):
    note_signal(signum)
    raise KeyboardInterrupt(f"signal {signum}")


def interrupt_on_sigterm() -> None:
    """Make SIGTERM end a command the way Ctrl-C does (KeyboardInterrupt: files are finished,
    summaries say ``interrupted``, workers are ended) instead of killing it mid-write. For the
    main thread of a command-line process."""
    with contextlib.suppress(ValueError):       # not the main thread: Python's own handling stays
        signal.signal(signal.SIGTERM, _raise_interrupt)


class LostInterrupts:
    """A command's start (imports, parsing, set-up) with interrupts Python cannot raise kept. A
    KeyboardInterrupt that lands in a callback Python runs and whose errors it ignores (importlib's
    module-lock weakref callback while a module loads, a finalizer, an at-fork hook) was printed as
    "Exception ignored ... Traceback" and dropped: a Ctrl-C at 0.5 s of `cosim run` went unheeded
    (seen in CI). Within this context such an interrupt is noted quietly; the next
    :class:`Interrupts` (a run's, a sweep's) raises it at its first check, and :meth:`pending`
    tells a command that has none."""

    def __enter__(self):
        _lost.clear()
        self.unraisable = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def _unraisable(self, unraisable) -> None:
        if issubclass(unraisable.exc_type, KeyboardInterrupt):
            _lost.append(_received[-1] if _received else int(signal.SIGINT))
            return
        self.unraisable(unraisable)

    @staticmethod
    def pending() -> bool:
        """Whether an interrupt was lost and no :class:`Interrupts` has taken it."""
        return bool(_lost)

    def __exit__(self, *exc):
        sys.unraisablehook = self.unraisable
        _lost.clear()
        return False


class Interrupts:
    """SIGINT and SIGTERM during a run: remembered, then raised as KeyboardInterrupt. An engine
    that swallows the exception in its own solver (exudyn's Newton loop calls Python user
    functions) cannot hide it: the run stops at the end of that macro step.

    Where Python itself cannot raise it (a signal that lands in a hook it calls and whose errors
    it ignores, e.g. logging's at-fork hook while a worker process is forked), it printed
    "Exception ignored ... Traceback" on stderr and dropped it. Such a KeyboardInterrupt, once
    remembered, is not printed: :meth:`check` raises it at the next step or point."""

    def __init__(self):
        self.signal = None
        self.previous = {}
        self.unraisable = None

    def __enter__(self):
        if _lost:                       # lost while the command started (LostInterrupts)
            self.signal = _lost.pop()
            _lost.clear()
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self.previous[sig] = signal.signal(sig, self._handle)
            except ValueError:          # not the main thread: Python's own handling stays
                pass
        self.unraisable = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        return self

    def _unraisable(self, unraisable) -> None:
        """Python's hook for an exception it cannot raise: a remembered interrupt stays quiet
        (:meth:`check` raises it), anything else is reported as before."""
        if self.signal is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            return
        self.unraisable(unraisable)

    def _handle(self, signum, frame):
        self.signal = signum
        _raise_interrupt(signum, frame)

    def check(self) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt(f"signal {self.signal}")

    def __exit__(self, *exc):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        if self.unraisable is not None:
            sys.unraisablehook = self.unraisable
        return False
