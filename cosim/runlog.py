"""Run folders under ``./logs/`` and small writers used by scenario scripts.

Results go where the user is: ``logs/`` under the *current working directory*, not next to the
package (an installed package's folder may be read-only, and a user running from their own
project expects their results there). ``--out`` on every command overrides it.

Owns: run folders and atomic JSON/CSV writers. Boundaries: nothing is written outside the folder
it makes or is given.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import math
import time
from pathlib import Path

from .files import write_atomic


def log_root() -> Path:
    """``./logs`` of the current working directory (evaluated at each call: the cwd may change)."""
    return Path.cwd() / "logs"


def __getattr__(name):
    # ``LOG_ROOT`` stays importable for the benchmark scripts; it is ./logs at import time.
    if name == "LOG_ROOT":
        return log_root()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def out_folder(text: str) -> Path:
    """An ``--out`` option's folder; an empty text is refused (``Path("")`` is the current folder,
    which a run would fill with its files)."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError("an empty --out would write into the current folder; give a folder name")
    return Path(text)


def run_folder(name: str, out: Path | None = None) -> Path:
    """``out`` or ``./logs/<name>-<timestamp>`` (created). Two runs started in the same second get
    distinct folders (``-2``, ``-3`` ...) rather than writing into each other; an ``out`` that
    already holds a run (its ``summary.json``) is refused, and ``name`` must be a plain name (no
    path: the folder stays under ``./logs``)."""
    if out is not None:
        folder = Path(out)
        if folder.exists() and not folder.is_dir():
            raise FileExistsError(f"{folder}: exists and is not a folder; give another --out")
        if (folder / "summary.json").exists():
            raise FileExistsError(f"{folder}: holds another run (its summary.json); give a new folder with --out, "
                                  "or remove that one")
        folder.mkdir(parents=True, exist_ok=True)
        return folder
    if not name or Path(name).name != name or name in (".", "..") or "\\" in name:
        raise ValueError(f"run folder name {name!r} must be a plain name, not a path")
    stem = log_root() / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    for k in range(1, 1000):
        folder = stem if k == 1 else stem.with_name(f"{stem.name}-{k}")
        try:
            folder.mkdir(parents=True, exist_ok=False)     # atomic: a parallel run takes the next name
            return folder
        except FileExistsError:
            continue
    raise FileExistsError(f"{stem}: 999 run folders with this name and second already exist")


def _clean(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:
        return _clean(value.item())
    return value


def write_json(path: Path, data) -> Path:
    """Write JSON atomically (temporary file, then rename): a crash never leaves half a file, and a
    symlink in the way is replaced, never written through (:func:`cosim.files.write_atomic`)."""
    return write_atomic(path, json.dumps(_clean(data), indent=2))


def write_csv(path: Path, rows: list[dict]) -> Path:
    text = io.StringIO(newline="")
    fields = list(dict.fromkeys(k for row in rows for k in row))      # union, in first-seen order
    writer = csv.DictWriter(text, fieldnames=fields)
    writer.writeheader()
    writer.writerows(rows)
    return write_atomic(path, text.getvalue())
