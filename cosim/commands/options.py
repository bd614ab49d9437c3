"""Checks and conversions of the options the subcommands share: engines, positive counts, the
wall-time cap, the recording flags, and the exit status of a finished command.

Owns: the shared option checks and exit statuses. Boundaries: the options are declared in
:mod:`cosim.cli`.
"""
from __future__ import annotations

import math
from pathlib import Path

from ..defaults import MAX_HOURS
from ..engines import ENGINES
from ..interrupts import exit_status
from ..recording.options import viewer_from_args
from ..recording.sinks import show_file
from ..run_outcome import MISSING_OUTPUTS
from ..scenario import load

#: The largest counts the command line takes (each sample or trajectory is a model run; more would
#: allocate their design, gigabytes, before anything could say so).
MAX_COUNT = {"--samples": 10_000, "--trajectories": 1_000, "--workers": 1_024}
#: Exit status of a run whose engines completed but some of whose outputs (recording, parquet,
#: figure, model.xml, scores) are missing (cosim.run_outcome): its results are computed, yet a
#: script that goes on to read them must not take it for a whole run (0), nor for a failure (1).
EXIT_MISSING_OUTPUTS = 3


def engines(text: str) -> tuple:
    """``--engines a,b``: the engine names, each known, at least one, none twice."""
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    for n in names:
        if n not in ENGINES:
            raise ValueError(f"--engines: unknown engine {n!r}; choose from {', '.join(ENGINES)}")
    if not names:
        raise ValueError("--engines: give at least one engine")
    if len(set(names)) != len(names):
        raise ValueError(f"--engines: an engine is named twice ({text!r})")
    return names


def positive(args, flags) -> None:
    """Each numeric flag given must be a positive finite number (counts at most MAX_COUNT); the
    error names the flag. Checked before anything runs."""
    for flag in flags:
        value = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{flag} must be a positive finite number, got {value!r}")
        if value is not None and value > MAX_COUNT.get(flag, math.inf):
            raise ValueError(f"{flag} must be at most {MAX_COUNT[flag]}, got {value!r}")


def max_hours(args) -> float:
    """``--max-hours``, checked positive and finite (default :data:`cosim.defaults.MAX_HOURS`)."""
    positive(args, ("--max-hours",))
    return MAX_HOURS if getattr(args, "max_hours", None) is None else args.max_hours


def viewer(args):
    """(ViewerOptions or None, --save path or None) of the recording flags (cosim.recording.options)."""
    return viewer_from_args(args)


def show(path: Path, viewer_options, save) -> None:
    """A finished sweep/uncertainty recording in the viewer the flags ask for (and --save, --stdout)."""
    if viewer_options is None or not path.exists():
        return
    show_file(path, viewer_options, save)


def exit_code(status: str) -> int:
    """A command's exit status from its summary's status: 0 when it completed (with failed samples
    or unsolved points too: the band, and a speed without a periodic solution, are results),
    :data:`EXIT_MISSING_OUTPUTS` when a run completed but some of its files are missing, 128 + the
    signal when a signal interrupted it, 1 otherwise."""
    if status == MISSING_OUTPUTS:
        return EXIT_MISSING_OUTPUTS
    if status.startswith("completed"):
        return 0
    return exit_status() if status == "interrupted" else 1


def refuse_structure(scenario: str, command: str) -> None:
    """A structure held at one position has no speed: ``sweep`` and ``uncertainty`` refuse it."""
    sc = load(scenario)
    if getattr(sc, "kind", None) == "structure":
        raise ValueError(f"scenario '{scenario}' is a structure held at one position (linkage.type = 'structure'): "
                         f"it has no crank speed, so `cosim {command}` cannot run it; use `cosim run {scenario}`")
