"""A run's final status from what it computed and what it wrote.

* Out of memory anywhere in a run (a MemoryError, or the dynamic loader unable to map a library:
  the same shortage of address space) fails the run: ``status = "failed"`` and the summary's
  ``error`` says "out of memory while <what the run was doing>"; every macro step written to
  ``traces.csv`` before stays there.
* A run whose engines completed but one of whose outputs is missing or may be incomplete (the
  recording, ``traces.parquet``, the strain figure, ``model.xml``, the scores against records)
  is :data:`MISSING_OUTPUTS`, the summary's ``missing`` listing each with its reason: its
  ``traces.csv`` and its summary's numbers are whole, but "completed" promised the rest too.

Owns: the statuses "failed: out of memory" and :data:`MISSING_OUTPUTS`. Boundaries: no files;
the run (cosim.runs) calls it.
"""
from __future__ import annotations

import errno
import logging

log = logging.getLogger("cosim.runs")
#: The status of a run whose engines completed but some of whose outputs are missing.
MISSING_OUTPUTS = "completed with missing outputs"
#: The dynamic loader's words when it cannot map a library (mmap failed: no address space left).
_NO_MAPPING = "failed to map segment"


def out_of_memory(exc: BaseException) -> bool:
    """Whether ``exc`` or one of its causes means the process ran out of memory (address space
    under RLIMIT_AS); a library that wraps the loader's failure (llvmlite: "Could not find/load
    shared object file") keeps it as the cause."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, MemoryError) or (isinstance(exc, OSError) and exc.errno == errno.ENOMEM):
            return True
        if isinstance(exc, (ImportError, OSError)) and _NO_MAPPING in str(exc):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def fail_out_of_memory(summary: dict, notes: list, doing: str, exc: BaseException) -> str:
    """Mark the run failed for want of memory while ``doing`` (e.g. "drawing the strain figure"):
    the summary's ``error`` and ``out_of_memory`` (what it was doing), which :func:`final_status`
    reads; returns the message."""
    detail = str(exc).strip() or "no memory left"
    message = f"out of memory while {doing} ({type(exc).__name__}: {detail})"
    summary["out_of_memory"] = doing
    summary["error"] = message
    notes.append(f"{message}; traces.csv keeps every macro step written before it")
    return message


def missing(summary: dict, what: str, reason: str) -> None:
    """Note that the output ``what`` (a file name, or "scores") is missing or may be incomplete."""
    summary.setdefault("missing", []).append({"what": what, "reason": reason})


def final_status(status: str, summary: dict) -> str:
    """``status`` ("completed", ...) as the run ends: "failed" when it ran out of memory, else
    :data:`MISSING_OUTPUTS` when it completed but the summary lists missing outputs."""
    if summary.get("out_of_memory"):
        return "failed"
    return MISSING_OUTPUTS if status == "completed" and summary.get("missing") else status


def attempt(summary: dict, notes: list, output: tuple, make):
    """``make()`` for one of a run's outputs, ``output = (what, doing, note)`` (e.g.
    ``("strains.png", "drawing the strain figure", "strain figure not drawn")``). A failure never
    loses the run: out of memory fails it (:func:`fail_out_of_memory`), anything else is a note
    and a :func:`missing` output. Returns make's value, or None when it failed."""
    what, doing, note = output
    try:
        return make()
    except Exception as exc:
        if out_of_memory(exc):
            log.error("%s", fail_out_of_memory(summary, notes, doing, exc))
            return None
        notes.append(f"{note}: {type(exc).__name__}: {exc}")
        missing(summary, what, notes[-1])
        log.warning("%s", notes[-1])
        return None
