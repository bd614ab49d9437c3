"""Kernels compiled ahead, in a second process, into numba's on-disk cache.

Numba compiles one kernel at a time in one thread, and a first run on an empty cache waits for
all of them in turn (the kernels a default run needs: about 30 s of compilation on a 2-core
machine). Where a caller knows a kernel's signature before it needs the kernel, it hands it to a
helper process (``python -m tmm_core.compiled``) that compiles it into the cache, and goes on with
its own; when it needs the kernel, it waits for the helper (:func:`wait`) and loads the kernel from
the cache. Two cores then compile side by side. Nothing depends on the helper: if it fails or
is too slow, the caller compiles the kernel itself, as without it.

A helper starts only where it pays: numba installed, at least two cores, and no cached
compilation of the kernel yet (a look at the cache folder). No helper outlives the process
that started it (ended at exit, and when a wait is interrupted); a forked child does not own
its parent's helpers.

Owns: the helper processes (start, wait, end) and the list of kernels waiting on them.
Boundaries: which kernel lives where and how it is compiled are the binding's; the cache folder
is :mod:`tmm_core.compiled.cache`'s. Imports numba nowhere (the signatures come typed).
"""
from __future__ import annotations

import atexit
import os
import pickle
import subprocess
import sys
import threading
import time

from .cache import AVAILABLE, ROOT, cache_dir

#: The longest wait [s] for a helper before the caller compiles the kernel itself (a loaded
#: machine: the helper's kernels compile in 5-10 s idle).
WAIT_LIMIT_S = 120.0

_pending: dict[str, subprocess.Popen] = {}     # kernel name -> the helper compiling it
_lock = threading.Lock()
_seen_cached: set = set()       # (source, name) found in the cache: a listing costs about 1 ms


def cached(source: str, name: str) -> bool:
    """Whether the cache folder holds a compilation of kernel ``name`` of the compiled module
    ``source`` (its file stem, e.g. ``"march"``), for any signature (once found, not looked for
    again: a periodic solve starts a march every revolution)."""
    if (source, name) in _seen_cached:
        return True
    folder = cache_dir()
    found = folder.is_dir() and any(folder.rglob(f"{source}.{name}-*.nbi"))
    if found:
        _seen_cached.add((source, name))
    return found


def worth_it(source: str, name: str) -> bool:
    """Whether a helper would save time on kernel ``name`` of module ``source``: numba installed,
    at least two cores, the kernel not cached yet and not already being compiled ahead."""
    return (AVAILABLE and (os.cpu_count() or 1) >= 2 and name not in _pending
            and not cached(source, name))


def start(requests) -> None:
    """Compile ``requests``, a list of ``(name, signature)`` (the kernel's name as the binding
    knows it, its numba argument types), in one helper process. Returns at once."""
    requests = [(name, signature) for name, signature in requests if name not in _pending]
    if not requests:
        return
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT.parent),
                                                                     os.environ.get("PYTHONPATH")])))
    process = subprocess.Popen([sys.executable, "-m", "tmm_core.compiled"], stdin=subprocess.PIPE,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    try:
        process.stdin.write(pickle.dumps(requests))
        process.stdin.close()
    except OSError:         # the helper died at start: the caller compiles by itself
        _stop(process)
        return
    with _lock:
        for name, _ in requests:
            _pending[name] = process


def wait(name: str) -> None:
    """Wait for the helper compiling kernel ``name`` (nothing to do if none is), at most
    :data:`WAIT_LIMIT_S`; it is ended if the wait is cut short (an interrupt, the limit)."""
    with _lock:
        process = _pending.pop(name, None)
    if process is None:
        return
    try:
        process.wait(timeout=WAIT_LIMIT_S)
    except subprocess.TimeoutExpired:       # the caller compiles the kernel by itself
        _stop(process)
    except BaseException:                   # an interrupt: the caller stops
        _stop(process)
        raise


def _stop(process: subprocess.Popen) -> None:
    """End a helper at once (SIGKILL) and reap it. It holds nothing to save: numba writes each
    cache file under a temporary name and renames it when complete, and SIGTERM would end it as
    abruptly."""
    if process.poll() is None:
        process.kill()
        process.wait()


@atexit.register
def _stop_all() -> None:
    """No helper outlives its process."""
    with _lock:
        helpers = set(_pending.values())
        _pending.clear()
    for process in helpers:
        _stop(process)


def follow_parent(poll_s: float = 0.2) -> None:
    """In a helper: end this process when the process that started it ends (a watcher thread).
    A parent killed outright (SIGKILL, or SIGTERM without its exit handlers: a stopped warm-up)
    cannot end its helpers; they end themselves, within about a second while numba compiles."""
    parent = os.getppid()

    def watch():
        while os.getppid() == parent:
            time.sleep(poll_s)
        os._exit(1)
    threading.Thread(target=watch, name="follow-parent", daemon=True).start()


def _forget_in_child() -> None:
    # A forked child (a sweep's worker) did not start its parent's helpers: it must neither wait
    # for nor end them (and a lock held by another thread at the fork would never be released).
    global _lock
    _lock = threading.Lock()
    _pending.clear()


os.register_at_fork(after_in_child=_forget_in_child)
