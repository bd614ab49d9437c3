"""Whether numba's on-disk cache already holds the compiled time-domain kernels.

The first run on a machine (or after the kernels' source changed) compiles them, which takes
one to two minutes on a small machine; a caller can say so before it starts instead of sitting
silent. Kept apart from :mod:`tmm_core.kernels` because numba invalidates a module's cache whenever its
source file changes.

Owns: the cold-cache check and the compile-time estimate. Boundaries: never imports numba.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import os
from pathlib import Path

#: Wall time [s] of compiling the time-domain kernels when numba's cache is empty, measured on a
#: shared 2-core machine: the first prescribed run of the FE rig took 100 and 107 s, of which
#: about 2 s were the run itself.
COMPILE_ESTIMATE_S = 100.0

_KERNELS = Path(__file__).with_name("kernels.py")


def cache_is_cold(source: Path = _KERNELS) -> bool:
    """True when numba's on-disk cache holds no compiled march for ``source`` as it is now, so
    the first use compiles every kernel (~COMPILE_ESTIMATE_S). A cache index
    ``<module>.march-*.nbi`` counts when it carries this numba's version and the source's SHA-256
    (the stamp numba checks: a changed source or another numba is recompiled). Cheap: a few
    small files read where numba writes them (``__pycache__`` beside the source;
    ``NUMBA_CACHE_DIR``; the user's cache when the source folder is read-only). False without
    numba (nothing is compiled)."""
    try:
        version = importlib.metadata.version("numba").encode()
    except importlib.metadata.PackageNotFoundError:
        return False
    digest = hashlib.sha256(source.read_bytes()).digest()
    folders = [source.parent / "__pycache__"]
    if os.environ.get("NUMBA_CACHE_DIR"):
        folders = [Path(os.environ["NUMBA_CACHE_DIR"])]
    elif not os.access(source.parent, os.W_OK):
        folders.append(Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "numba")
    for folder in folders:
        for index in folder.rglob(f"{source.stem}.march-*.nbi") if folder.is_dir() else ():
            data = index.read_bytes()
            if digest in data and version in data:
                return False
    return True
