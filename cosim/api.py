"""The bench from a script: one call runs a scenario or a sweep and returns its results.

    import cosim
    data = cosim.run("crank_rocker_373rpm", engines=["tmm"])
    data.summary["engines"]["tmm"]["gauges"]      # the summary, as `cosim compare` shows it
    data.traces                                    # every engine's traces, a long pandas DataFrame
    data.folder                                    # the run folder (summary.json, traces.csv, ...)

What the command line does with the same options (``cosim run``, ``cosim sweep``), without its
printing: the folder written is the same, and so are the numbers.

Owns: :func:`run` and :func:`sweep`, the scripting entry points that ``cosim/__init__.py``
exports. Boundaries: no logic of its own (cosim.runs, cosim.sweeps and cosim.results do the work).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .results import RunData, load_run
from .runs import RunOptions, run_scenario
from .scenario import load
from .sweeps import run_sweep


def run(scenario, engines=None, *, drive: str | None = None, revolutions: float | None = None,
        out: Path | None = None, record: bool = False, figures: bool = True, progress: bool = False,
        records: Path | None = None) -> RunData:
    """Run ``scenario`` (a name, a path or a loaded :class:`cosim.scenario_types.Scenario`)
    through ``engines`` (default: the scenario's ``output.engines``) and load the folder written.

    ``drive``: 'prescribed' or 'motor' (default: the scenario's ``drive.mode``); ``revolutions``:
    the run's length (default: the scenario's, else until steady); ``out``: the run folder
    (default: ``./logs/<scenario>-<timestamp>``); ``record``: also write the rerun recording
    ``run.rrd``; ``figures``: the strain figures; ``records``: a directory of records to score
    against instead of the shipped ones. Returns :class:`cosim.results.RunData` (``summary``,
    ``traces`` in SI with strains in microstrain as in traces.csv, ``folder``). An engine's failure
    is in the summary (``summary["engines"][name]["status"]``), not raised."""
    sc = load(scenario)
    options = RunOptions(engines=tuple(engines) if engines is not None else sc.output.engines, mode=drive,
                         revolutions=revolutions, out=out, viewer="save" if record else "none",
                         progress=progress, records=records, figures=figures)
    return load_run(run_scenario(sc, options).folder)


@dataclass(frozen=True)
class SweepResult:
    """A finished sweep: its ``folder`` (sweep.csv, summary.json, figures) and its ``summary``
    (peaks per speed, engine and gauge, as ``cosim compare`` shows them)."""

    folder: Path
    summary: dict


def sweep(scenario, rpm, engines=("tmm",), *, method: str = "periodic", revolutions: float | None = None,
          workers: int | None = None, out: Path | None = None, record: bool = False, progress: bool = False,
          resonance: bool = False) -> SweepResult:
    """Peak strains of ``scenario`` at each speed of ``rpm`` [rev/min]: a list of numbers, or the
    command line's text ('100:400:25' or '95,241,373'). ``method``: the TMM's periodic steady
    state ('periodic') or time marching ('march'); ``resonance``: also the natural-frequency map
    and Campbell diagram (four-bars). Points run in ``workers`` local processes (default: the
    cores)."""
    folder, summary = run_sweep(scenario, rpm if isinstance(rpm, str) else [float(x) for x in rpm], tuple(engines), revolutions, workers, None, out, progress=progress,
                                record=record, method=method, resonance=resonance)
    return SweepResult(Path(folder), summary)
