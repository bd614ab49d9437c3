"""Run folders under ``logs/`` and small writers used by scenario scripts."""
from __future__ import annotations

import csv
import json
import math
import time
from pathlib import Path

LOG_ROOT = Path(__file__).resolve().parent.parent / "logs"


def run_folder(name: str, out: Path | None = None) -> Path:
    """``out`` or ``logs/<name>-<timestamp>`` (created)."""
    folder = Path(out) if out is not None else LOG_ROOT / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}"
    folder.mkdir(parents=True, exist_ok=True)
    return folder


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
    """Write JSON atomically (temporary file, then rename): a crash never leaves half a file."""
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(_clean(data), indent=2))
    tmp.replace(path)
    return path


def write_csv(path: Path, rows: list[dict]) -> Path:
    path = Path(path)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", newline="") as fh:
        fields = list(dict.fromkeys(k for row in rows for k in row))      # union, in first-seen order
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)
    return path
