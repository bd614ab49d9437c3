"""Numba's on-disk cache of the compiled kernels: where it lives, when it is stale, whether it is
cold.

Numba checks a cached kernel against the source file that defines it only, while the kernels
call (and inline) functions of other files: after an edit of ``dense.py`` a kernel of
``structure.py`` would be loaded stale from the cache. So the whole compiled layer shares one
cache folder keyed by the SHA-256 of its sources and numba's version
(:data:`COMPILED_SOURCES`): an edit of any of them, or another numba, starts an empty folder by
itself, and the folders of other keys beside the package are removed. Every kernel module gets numba through
:func:`numba_module`, which points numba's cache there before the first kernel is made.

The first run on a machine (or after the kernels' source changed) compiles them, which takes
about 17 s on a 2-core machine (helper processes compile some of them side by side:
:mod:`tmm_core.compiled.ahead`); :func:`cache_is_cold` lets a caller say so before it starts
instead of sitting silent.

Owns: the compiled layer's cache folder and key, the cold-cache check and the compile-time
estimate. Boundaries: imports numba only in :func:`numba_module`.
"""
from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import importlib.util
import os
import shutil
from pathlib import Path

#: Time [s] of compiling the time-domain kernels when numba's cache is empty, on an idle 2-core
#: machine: the first run's warm-up process of the FE rig (``tests/benchmarks/bench_compile.py``)
#: took 15.6-18.8 s whole (median 16.9 s), its helper processes included; longer on a loaded one
#: (beside a first run's numpy engine, about 19 s).
COMPILE_ESTIMATE_S = 17.0
#: Time [s] of compiling the kernels of a periodic sweep (the periodic solver's linearized
#: revolutions as well) on an empty cache: a 2-point full-model sweep of the FE rig (241 and 373
#: rpm, one worker) took 34.6 s whole, of which about 1.5 s are the points.
PERIODIC_COMPILE_ESTIMATE_S = 33.0

HERE = Path(__file__).resolve().parent
#: The package the compiled sources are named relative to (tmm_core).
ROOT = HERE.parent
#: The files numba compiles the kernels from: every kernel module of ``compiled/``,
#: ``matrices.py`` (its constants are compiled into them), ``integrators.py`` (the linearized
#: revolutions' drivers read its linear maps) and the binding (its numba options are part of what
#: is compiled); the Python drivers (``compiled/statics.py``, this module) are not.
#: A test checks that the kernels import nothing else of tmm_core at module level but these, the
#: errors and this module.
COMPILED_SOURCES = ("compiled/march.py", "compiled/dense.py", "compiled/riccati.py", "compiled/time_step.py",
                    "compiled/step_data.py", "compiled/integrators.py", "compiled/periodic.py", "compiled/reduced_periodic.py",
                    "compiled/structure.py", "compiled/binding.py", "matrices.py", "integrators.py")
PREFIX = "kernels-"
#: Whether numba is installed: without it the numpy reference path runs everything.
AVAILABLE = importlib.util.find_spec("numba") is not None


def _numba_version() -> str | None:
    try:
        return importlib.metadata.version("numba")
    except importlib.metadata.PackageNotFoundError:
        return None


def sources_key(folder: Path = ROOT) -> str:
    """16 hex digits of the SHA-256 of the compiled sources (names and bytes) and numba's version."""
    h = hashlib.sha256((_numba_version() or "").encode())
    for name in COMPILED_SOURCES:
        h.update(name.encode() + b"\0" + (folder / name).read_bytes())
    return h.hexdigest()[:16]


def cache_root() -> Path:
    """Where the keyed folders live: ``NUMBA_CACHE_DIR`` when the user set it, else the package's
    ``__pycache__`` when it can be written, else the user's cache (an installed, read-only
    package)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    if os.access(ROOT, os.W_OK):
        return ROOT / "__pycache__"
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "flexlink-bench"


def cache_dir(folder: Path = ROOT) -> Path:
    """The compiled layer's cache folder for its sources (in ``folder``) as they are now."""
    return cache_root() / f"{PREFIX}{sources_key(folder)}"


def remove_stale(current: Path) -> None:
    """Remove the keyed folders beside ``current`` (caches of sources that have since changed),
    and the per-file cache numba kept beside the sources before there were keyed folders."""
    if not current.parent.is_dir():
        return
    for folder in current.parent.glob(f"{PREFIX}*"):
        if folder.is_dir() and folder.name != current.name and len(folder.name) == len(current.name):
            shutil.rmtree(folder, ignore_errors=True)
    if current.parent == ROOT / "__pycache__":
        for stem in COMPILED_SOURCES:
            for old in current.parent.glob(f"{Path(stem).stem}.*.nb[ic]"):
                old.unlink(missing_ok=True)


@functools.lru_cache(maxsize=1)
def numba_module():
    """numba, with its cache pointed at :func:`cache_dir` (once per process, before any kernel
    is made: numba reads the folder when a kernel is decorated). Import numba only through this."""
    import numba
    folder = cache_dir()
    with contextlib.suppress(OSError):
        folder.mkdir(parents=True, exist_ok=True)
        if folder.parent == ROOT / "__pycache__":      # this checkout's own: a shared folder may
            remove_stale(folder)                        # hold other checkouts' current caches
    numba.config.CACHE_DIR = str(folder)
    return numba


def cache_is_cold(folder: Path = ROOT) -> bool:
    """True when the cache folder of the compiled sources (in ``folder``) as they are now holds
    no compiled march (``march.march-*.nbi``), so the first use compiles every kernel
    (~COMPILE_ESTIMATE_S). Cheap: a directory listing. False without numba (nothing is
    compiled)."""
    if _numba_version() is None:
        return False
    cache = cache_dir(folder)
    return not (cache.is_dir() and any(cache.rglob("march.march-*.nbi")))
