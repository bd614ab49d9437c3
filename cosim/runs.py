"""One run of a scenario through the engines, with its log folder and rerun recording.

``./logs/<scenario>-<timestamp>/`` (under the current directory; ``RunOptions.out`` overrides) receives:

* ``scenario.resolved.toml``: the scenario as run (every value in SI after units, defaults and
  derivations; every assumption with its rationale; the file as written);
* ``traces.csv``: time column and one column per trace, units in the names
  (:mod:`cosim.traces`), appended in blocks of macro steps (:mod:`cosim.samples`, at most every 0.25 s);
* ``run.rrd``: the rerun recording (:mod:`cosim.recording`; written by a child process, to
  ``RunOptions.save_path`` instead if given, and streamed to a viewer as ``RunOptions.viewer``
  says, never waiting on one without a bound);
* ``model.xml`` (MuJoCo's MJCF, with visual capsules) and ``exudyn_solution.txt`` (exudyn's
  solution file for its ``SolutionViewer``) when those engines ran; ``linkage.gif`` with
  ``RunOptions.animation``;
* ``traces.parquet``: the traces as one long table, written when the run ends
  (:mod:`cosim.results`, ``cosim.load_run``);
* ``strains.png`` / ``strains.svg``: strain against crank angle per gauge, engines and records
  (:mod:`cosim.figures`); a figure that fails is a note and a missing output in the summary
  (status ``completed with missing outputs``, :mod:`cosim.run_outcome`), never a lost run;
* ``summary.json``: ``scenario``, ``status``, per engine ``wall_time_s``, ``sim_time_s``,
  ``status``, ``error`` and, for the last revolution, ``gauges.<g>.{bending,axial}_{max,min}_ue``
  and the drive torque range, ``flags`` (:mod:`cosim.physics_flags`); in motor mode the speed
  fluctuation and the energy balance.

``summary.json`` is written at the start with ``status = "incomplete"`` and rewritten every few
seconds, so a run that is killed leaves a summary that says so; an interrupted run (Ctrl-C,
SIGTERM) writes ``"interrupted"``; a run in which an engine failed writes ``"failed"`` with the
engine's message and keeps the other engines' results; a run out of memory anywhere writes
``"failed"`` with "out of memory while ..." (:mod:`cosim.run_outcome`).

Owns: one run: folder, traces, recording, summary, scores, figures, interruption. Boundaries: no
engine numerics and no recording internals (cosim.recording).
"""
from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomli_w

from tmm_core import FourBarMechanism, TMMError
from tmm_core.fourbar_limits import limit_positions

from . import __version__
from . import figures as run_figures      # through the module: a test puts a failing stand-in there
from .compare import convention_warnings, score_history, score_peaks, sign_check
from .engines import ENGINES, EngineUnavailable, check_engine_names, make_engine
from .files import write_atomic
from .interrupted import mark_interrupted
from .interrupts import Interrupts
from .kernel_warmup import KernelWarmup, first_run_in_numpy
from .master import CoSimulation, InputError
from tmm_core.revolution import last_revolution, revolutions_completed

from .metrics import link_rotations, steadiness
from .physics_flags import attach_flags, questionable
from .recording.animation import write_gif
from .recording.batch import check_linkage_rate
from .recording.process import RecorderProcess
from .recording.recorder import check_exaggeration
from .recording.sinks import ViewerOptions
from .records import history_over_angle, peaks_at, records_for
from .results import write_parquet
from .run_guards import MAX_HOURS, check_cost, plausibility_notes
from .run_outcome import attempt, fail_out_of_memory, final_status, missing, out_of_memory
from .run_progress import RunProgress, compile_notice
from .runlog import run_folder, write_json
from .samples import SampleCollector
from .scenario import Scenario, load, resolved
from .scenario_types import to_rpm
from .traces import TraceWriter, TracesNotWritten

SUMMARY_EVERY_S = 2.0
#: Revolutions of every engine's outputs a run holds in memory (the rest is in traces.csv): the
#: steady-state check, the scores and the figures use the last two.
KEEP_REVOLUTIONS = 4
log = logging.getLogger(__name__)


@dataclass
class RunOptions:
    engines: tuple = ENGINES
    mode: str | None = None              # 'prescribed' | 'motor'; default: the scenario's drive.mode
    revolutions: float | None = None     # default: the scenario's output.revolutions, else until steady
    out: Path | None = None              # default: logs/<scenario>-<timestamp>
    viewer: str = "save"                 # 'save' (headless, default) | 'spawn' | 'connect' | 'serve' | 'none'
    connect_url: str | None = None
    save_path: Path | None = None        # the recording file (default: <run folder>/run.rrd)
    viewer_timeout_s: float = 5.0        # connecting to / flushing to a viewer (cosim.recording.sinks)
    serve_address: str = "127.0.0.1"      # viewer 'serve': where its servers listen (this machine only)
    exaggeration: float | None = None    # linkage drawing; None: from the largest deformation
    linkage_fps: float | None = 60.0     # linkage frames per simulated second in the recording (None: every step)
    animation: bool = False              # linkage.gif in the run folder (matplotlib)
    progress: bool = True
    records: Path | None = None          # records directory (default: the shipped scenarios/records)
    figures: bool = True                 # strains.png/.svg in the run folder
    max_hours: float = MAX_HOURS         # refuse a run estimated to take longer (estimate_cost)
    #: Called with the summary as soon as the engines' results are summarised, before the
    #: parquet copy and the figures are written (seconds more): the command line prints its
    #: table there. The status it sees may still become 'completed with missing outputs'.
    on_results: object = None


@dataclass
class RunResult:
    folder: Path
    summary: dict
    result: object = None                # cosim.master.CoSimResult
    notes: list = field(default_factory=list)
    recorder: object = None              # the closed recorder (``serve_until_interrupted`` with viewer 'serve')


def last_revolution_stats(run, period: float | None = None, t0: float = 0.0) -> dict:
    """Gauge and torque extremes over the engine's last crank revolution [microstrain, N m]
    (by crank angle, :func:`tmm_core.revolution.last_revolution`)."""
    if len(run.t) == 0:
        return {}
    mask = last_revolution(run.crank_angle)
    complete = revolutions_completed(run.crank_angle) >= 1 - 1e-9
    out = {"window_s": [float(run.t[mask][0]), float(run.t[-1])], "complete_revolution": bool(complete),
           "drive_torque_max_Nm": float(np.max(run.drive_torque[mask])),
           "drive_torque_min_Nm": float(np.min(run.drive_torque[mask])), "gauges": {}}
    for g, (bending, axial) in run.gauges.items():
        b, a = np.asarray(bending)[mask] * 1e6, np.asarray(axial)[mask] * 1e6
        out["gauges"][g] = {"bending_max_ue": float(b.max()), "bending_min_ue": float(b.min()),
                            "axial_max_ue": float(a.max()), "axial_min_ue": float(a.min())}
    return out


def linkage_summary(sc: Scenario) -> dict | None:
    """Limit positions and transmission-angle range of a four-bar scenario [deg]
    (:func:`tmm_core.fourbar_limits.limit_positions`); None for other linkages or a non-Grashof one."""
    if not isinstance(sc.mechanism, FourBarMechanism):
        return None
    try:
        lim = limit_positions(sc.mechanism.geometry)
    except TMMError as exc:
        return {"note": str(exc)}
    return {k.replace("_rad", "_deg"): (None if v is None else math.degrees(v)) if k.endswith("_rad") else v
            for k, v in lim.items()}


def _engine_summary(ch, scenario: Scenario, sim_t0: float) -> dict:
    """One engine's entry of summary.json; the simulated time [s] and the revolutions are the
    whole run's (the master's step count), the rest of the revolutions the run holds."""
    run = ch.run
    d = {"status": ch.status, "error": ch.error, "wall_time_s": float(run.wall_time_s),
         "sim_time_s": float(ch.sim_time_s), "revolutions_run": float(ch.revolutions_run),
         "samples": int(len(run.t)),
         "coupling_passes_mean": float(np.mean(ch.passes)) if len(ch.passes) else 0.0}
    d.update(last_revolution_stats(run, t0=sim_t0))
    d.update(steadiness(run, scenario.output.steady_tolerance))
    rotations = link_rotations(run)
    if rotations:
        d["link_rotation_max_deg"] = rotations
    if ch.motor is not None and len(run.t):
        f = ch.speed_fluctuation()
        if len(f["mean"]):
            d["speed"] = {"mean_rpm_last": float(to_rpm(f["mean"][-1])),
                          "fluctuation_last": float(f["fluctuation"][-1]),
                          "fluctuation_per_revolution": [float(x) for x in f["fluctuation"]]}
        try:
            d["energy_J"] = ch.energy_balance()
        except InputError as exc:
            d["energy_J"] = {"note": str(exc)}
        ext = ch.motor_extrema or {}
        if "current_A" in ext:           # over the whole run, not only the revolutions held
            d["motor"] = {"current_max_A": ext["current_A"][1], "current_min_A": ext["current_A"][0],
                          "voltage_max_V": ext["voltage_V"][1], "voltage_min_V": ext["voltage_V"][0]}
    return d


def run_scenario(scenario, options: RunOptions = RunOptions(), callback=None) -> RunResult:
    """Run a scenario (name, path or :class:`Scenario`) through ``options.engines`` and write the
    log folder. Returns the folder and the summary; never raises for an engine's failure (it is
    in the summary), only for bad input before anything runs.

    The pipeline: the plan (every check before anything is written), the folder with its opening
    summary, the engines' loop (traces and recording written as it goes), the summary of the
    results (printed through ``options.on_results``), then the slower files."""
    # Signals are remembered from the start: a library may catch the KeyboardInterrupt of a
    # Ctrl-C while the engines load (exudyn's import falls back to its other build when one fails
    # to import, and an interrupted import fails), and the run would go on as if none had come.
    with Interrupts() as interrupts:
        plan = _plan(scenario, options)
        interrupts.check()
        folder = run_folder(plan.sc.name, options.out)
        summary = _open_folder(plan, options, folder)
        warmup = KernelWarmup.start(folder / "scenario.resolved.toml") if plan.first_run_numpy else None
        try:
            return _run_and_write(plan, options, callback, folder, summary, warmup, interrupts)
        except BaseException:
            if warmup is not None:
                warmup.stop()
            raise


def _run_and_write(plan: _Plan, options: RunOptions, callback, folder: Path, summary: dict,
                   warmup: KernelWarmup | None, interrupts: Interrupts) -> RunResult:
    """The run's engines, results and files (:func:`run_scenario`, after its folder is opened;
    ``interrupts`` its signals); last, the kernels' compilation beside a first run is awaited."""
    writer = TraceWriter(folder / "traces.csv")
    notes = []
    # Started before the engines set up: its child process imports rerun meanwhile.
    recorder = _start_recorder(plan.sc, plan.mode, plan.engines, folder, options, plan.viewer, summary)
    exports = _start_exports(plan.engines, folder)
    status, result, write_failed = _run_engines(plan, options, callback, folder, summary, notes, writer, recorder,
                                                interrupts)
    _summarise_results(plan, options, folder, summary, notes, status, result, recorder, exports)
    if options.on_results is not None:
        options.on_results(dict(summary, status=final_status(status, summary)))
    if writer.columns is not None and status == "interrupted":
        # Stop promptly (a signal asks for it): traces.csv is the run's file, which cosim.load_run
        # reads; the parquet copy and the figure are not made.
        notes.append("traces.parquet and the strain figure are not written for an interrupted run "
                     "(cosim.load_run reads traces.csv)")
    elif writer.columns is not None and not write_failed and "out_of_memory" not in summary:
        _write_results(folder, plan.sc, summary, notes, options)
    if recorder is not None:
        _close_recorder(recorder, summary, notes)
    if warmup is not None and status == "interrupted":
        warmup.stop()
    elif warmup is not None:
        notes.append(warmup.finish())
    summary["status"] = final_status(status, summary)
    if notes:
        summary["notes"] = notes
    write_json(folder / "summary.json", summary)
    return RunResult(folder, summary, result, notes, recorder)


@dataclass(frozen=True)
class _Plan:
    """A run as checked before anything is written: the scenario, drive mode, engines (and those
    unavailable, with the reason), the master, its length [revolutions, s] and cost estimate."""

    sc: Scenario
    mode: str
    engines: dict
    unavailable: dict
    cosim: CoSimulation
    revolutions: float
    until_steady: bool
    duration_s: float
    cost: dict
    viewer: object
    #: The transfer-matrix engine runs in numpy while its kernels compile beside it
    #: (cosim.kernel_warmup: a cold numba cache and a run shorter in numpy than the compilation).
    first_run_numpy: bool = False


def _plan(scenario, options: RunOptions) -> _Plan:
    """Every check that can refuse the run, before its folder exists: engines, viewer, drive mode,
    length, cost and the records directory."""
    sc = scenario if isinstance(scenario, Scenario) else load(scenario)
    check_engine_names(options.engines)
    viewer = _viewer_options(options)                    # refuses a bad viewer before anything runs
    mode = options.mode or sc.drive.mode
    engines, unavailable = {}, {}
    for name in options.engines:
        try:
            engines[name] = make_engine(name)
        except EngineUnavailable as exc:
            unavailable[name] = str(exc)
    if not engines:
        raise InputError("no engine could be started: " + "; ".join(unavailable.values()))
    cosim = CoSimulation(sc, engines, mode=mode)         # checks mode, motor table and macro step
    revolutions = sc.output.revolutions if options.revolutions is None else options.revolutions
    until_steady = revolutions is None
    if until_steady:
        revolutions = sc.output.max_revolutions
    if not (isinstance(revolutions, (int, float)) and math.isfinite(revolutions) and revolutions > 0):
        raise InputError(f"revolutions must be a positive finite number, got {revolutions!r}")
    duration = cosim.duration_for(revolutions)
    if not (isinstance(options.max_hours, (int, float)) and options.max_hours > 0):
        raise InputError(f"max_hours (--max-hours) must be a positive number of hours, got {options.max_hours!r}")
    cost = check_cost(sc, list(engines), duration, cosim.macro_step_s, options.max_hours)
    if options.records is not None:       # a bad user records directory is refused before the run
        records_for(sc, Path(options.records))
    first_run_numpy = first_run_in_numpy(sc, engines, duration)
    if first_run_numpy:
        engines["tmm"].backend = "numpy"    # set before the engine is reset: its model is built then
    return _Plan(sc, mode, engines, unavailable, cosim, revolutions, until_steady, duration, cost, viewer,
                 first_run_numpy)


def _open_folder(plan: _Plan, options: RunOptions, folder: Path) -> dict:
    """The run folder's first files: the resolved scenario and the opening summary (status
    'incomplete' until the run ends), which is returned."""
    sc, cosim = plan.sc, plan.cosim
    log.info("%s at %.4g rpm through %s (%s, %s); results to %s", sc.name, sc.drive.speed_rpm,
             ", ".join(plan.engines), plan.mode,
             "until steady" if plan.until_steady else f"{plan.revolutions:g} revolutions", folder)
    write_atomic(folder / "scenario.resolved.toml", tomli_w.dumps(resolved(sc)))
    summary = {"scenario": sc.name, "status": "incomplete", "bench_version": __version__, "mode": plan.mode,
               "engines_requested": list(options.engines), "revolutions": plan.revolutions,
               "until_steady": plan.until_steady, "steady_tolerance": sc.output.steady_tolerance,
               "duration_s": plan.duration_s, "macro_step_s": cosim.macro_step_s,
               "estimate": {"wall_time_s": plan.cost["seconds"], "trace_bytes": plan.cost["bytes"]},
               "coupling": {"scheme": cosim.coupling.scheme, "extrapolation": cosim.coupling.extrapolation}
               if plan.mode == "motor" else None,
               "started": time.strftime("%Y-%m-%dT%H:%M:%S"), "progress": 0.0,
               "engines": {n: {"status": "unavailable", "error": msg} for n, msg in plan.unavailable.items()},
               "files": {"traces": "traces.csv", "recording": None, "scenario": "scenario.resolved.toml"}}
    summary["linkage"] = linkage_summary(sc)
    write_json(folder / "summary.json", summary)
    return summary


def _run_engines(plan: _Plan, options: RunOptions, callback, folder: Path, summary: dict, notes: list,
                 writer: TraceWriter, recorder, interrupts: Interrupts) -> tuple:
    """The master's loop, every macro step's samples written to traces.csv and the recording as
    it goes; returns ``(status, CoSimResult or None, whether the traces could not be written)``.
    An interrupt, a full disk or running out of memory ends it with the steps so far on disk."""
    engines = plan.engines
    if "tmm" in engines and not plan.first_run_numpy:     # (a first run's engine runs in numpy)
        compile_notice()
    progress = RunProgress(plan.until_steady, f"{plan.sc.name} ({', '.join(engines)})", bar=options.progress)
    last_write = [time.monotonic()]
    failures = {}
    written_t = [None]
    stations = [False]

    # The macro steps' samples, collected once for traces.csv and the recording, go to both in
    # blocks (cosim.samples).
    samples = SampleCollector()

    def take_block():
        block = samples.take()
        if block:
            writer.write_block(block)
            if recorder is not None:
                recorder.log_samples(block)

    def on_step(step):
        interrupts.check()              # a signal an engine swallowed: this macro step is not written
        samples.add(step.outputs)
        written_t[0] = step.t
        if recorder is not None:
            if not stations[0]:         # the engines are reset now and know their meshes
                recorder.set_stations({n: e.node_stations() for n, e in engines.items() if _has_stations(e)})
                stations[0] = True
            recorder.log_macro_step(step, samples=False)
        if samples.due():
            take_block()
        failures.update(step.failed)
        frac = progress.update(step)
        if time.monotonic() - last_write[0] > SUMMARY_EVERY_S:
            summary["progress"] = frac
            summary["sim_time_s"] = step.t
            write_json(folder / "summary.json", summary)
            last_write[0] = time.monotonic()
        return callback(step) if callback is not None else None

    status, result, write_failed = None, None, False
    try:
        interrupts.check()              # one an engine's set-up or the recorder's start caught
        result = plan.cosim.run(plan.duration_s, callback=on_step, until_steady=plan.until_steady,
                                keep_revolutions=KEEP_REVOLUTIONS)
        take_block()                    # the last macro steps
        status = result.status
        if interrupts.signal is not None:
            mark_interrupted(result, written_t[0], failures)
            status = result.status
        if status == "interrupted":
            notes.append("interrupted by the user or a signal; the files hold every completed macro step")
    except KeyboardInterrupt:          # during set-up, before the master's loop
        with contextlib.suppress(Exception):
            take_block()
        status = "interrupted"
        notes.append("interrupted during set-up")
    except TracesNotWritten as exc:    # a full disk or a file-size limit: the run cannot keep its data
        status, write_failed = "failed", True
        summary["error"] = f"stopped: traces.csv could not be written: {exc.strerror}"
        notes.append(f"{summary['error']}; the traces kept are whole rows; no parquet copy or figure is made")
        log.error("%s", exc.strerror)
        _stopped_with_the_run(summary, engines, "its traces could not be written")
    except BaseException as exc:
        with contextlib.suppress(Exception):     # the steps computed before the error stay on disk
            take_block()
        if not out_of_memory(exc):
            # The summary must not stay 'incomplete' (a killed run's word) for a run that ended.
            summary.update(status="failed", error=f"{type(exc).__name__}: {exc}")
            with contextlib.suppress(Exception):
                write_json(folder / "summary.json", summary)
            if recorder is not None:
                recorder.close()
            raise
        status, write_failed = "failed", True   # no parquet copy or figure: no memory for them
        log.error("%s", fail_out_of_memory(summary, notes, "running the engines", exc))
        _stopped_with_the_run(summary, engines, "out of memory")
    finally:
        writer.close()
        progress.close(completed=status not in (None, "interrupted"))
    return status, result, write_failed


def _summarise_results(plan: _Plan, options: RunOptions, folder: Path, summary: dict, notes: list, status: str,
                       result, recorder, exports: dict) -> None:
    """The summary after the loop: status, how it stopped, each engine's results, steadiness,
    scores, and the engines' own files; running out of memory here keeps the data as written."""
    summary["status"] = status
    if result is not None:
        summary["stop"] = {"steady": "every engine steady", "end": "revolution limit" if plan.until_steady else
                           "fixed length"}.get(result.stop, result.stop)
    summary["finished"] = time.strftime("%Y-%m-%dT%H:%M:%S")
    try:
        if result is not None:
            _summarise(plan.sc, result, summary, notes, recorder, options)
        if recorder is not None:
            _log_steadiness(recorder, summary)
            recorder.hand_over()         # the child finishes the file while the results are written
        for name in plan.engines:
            summary["engines"].setdefault(name, {"status": "interrupted"})
        _finish_exports(exports, plan.engines, result, folder, summary, notes, options)
    except Exception as exc:              # out of memory after the loop: the run's data stay as written
        if not out_of_memory(exc):
            raise
        log.error("%s", fail_out_of_memory(summary, notes, "summarising the results", exc))


def _stopped_with_the_run(summary: dict, engines, why: str) -> None:
    """Every engine's entry when the run itself could not go on (``why``): failed with it, its
    numbers not summarised."""
    for name in engines:
        summary["engines"][name] = {"status": "failed", "error": f"stopped with the run: {why}"}


def _summarise(sc: Scenario, result, summary: dict, notes: list, recorder, options: RunOptions) -> None:
    """The engines' entries of the summary after the loop, steadiness and plausibility notes, the
    physics flags and the scores against records (a scoring failure is a missing output)."""
    status = summary["status"]
    summary["progress"] = 1.0 if status == "completed" else summary.get("progress", 0.0)
    summary["sim_time_s"] = result.sim_time_s
    for name, ch in result.channels.items():
        summary["engines"][name] = _engine_summary(ch, sc, 0.0)
    unsteady = [n for n, e in summary["engines"].items() if e.get("status") == "completed" and not e.get("steady")]
    if unsteady:
        notes.append(f"not steady: {', '.join(unsteady)} (the last two revolutions differ by more than "
                     f"{100 * sc.output.steady_tolerance:.2g} %); its peaks are a transient, not a steady state")
    implausible = plausibility_notes(sc, summary)
    for text in implausible:
        log.warning(text)
    notes += implausible
    # engines.<engine>.flags: buckling, toggle, resonance, rigid model; the linkage's own
    # frequencies (seconds) only when the results are in question
    attach_flags(sc, summary, linkage_map=questionable(summary, bool(implausible)), progress=options.progress)
    try:
        score_records(sc, result, summary, recorder, options.records)
        if options.records is not None:
            summary["records_dir"] = str(Path(options.records).resolve())
            if not summary.get("records_used"):
                notes.append(f"no record in {options.records} is of rig {getattr(sc, 'rig', None)!r} at "
                             "this speed; nothing was scored")
    except Exception as exc:          # scoring must never lose the run's own results
        if out_of_memory(exc):
            raise
        notes.append(f"scoring against records failed: {type(exc).__name__}: {exc}")
        missing(summary, "scores", notes[-1])


def _log_steadiness(recorder, summary: dict) -> None:
    """Each engine's steady-state verdict as a text entry of the recording."""
    for name, e in summary["engines"].items():
        if "steady" in e:
            change = e.get("revolution_change")
            recorder.log_text(f"{name}/steady_state", (
                "steady" if e["steady"] else "NOT STEADY: the last revolution is a transient") +
                ("" if change is None else f" (last two revolutions differ by {100 * change:.2f} % of the "
                                           f"peak-to-peak; tolerance {100 * e['steady_tolerance']:.2g} %)"))


def _close_recorder(recorder, summary: dict, notes: list) -> None:
    """Wait for the recording's writer; its warnings are notes, a file it could not finish (the
    writer died, did not start, or stopped reading) a missing output."""
    try:
        notes += [f"recording: {p}" for p in recorder.close()]
    except Exception as exc:
        if not out_of_memory(exc):
            raise
        log.error("%s", fail_out_of_memory(summary, notes, "closing the recording", exc))
    if getattr(recorder, "incomplete", None):
        missing(summary, summary["files"].get("recording") or "run.rrd", recorder.incomplete)


def _viewer_options(options: RunOptions):
    """The recording's viewer (cosim.recording.sinks.ViewerOptions), None for no recording;
    a bad choice is refused naming the option."""
    try:
        check_exaggeration(options.exaggeration)          # the recording's and the animation's
        if options.viewer == "none":
            return None
        check_linkage_rate(1, options.linkage_fps)
        return ViewerOptions(options.viewer, url=options.connect_url, timeout_s=options.viewer_timeout_s,
                             bind=options.serve_address)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def _start_recorder(sc: Scenario, mode: str, engines: dict, folder: Path, options: RunOptions, viewer, summary):
    """The run's recorder (rerun in a child process, cosim.recording.process), with the resolved
    scenario as text; None with viewer 'none'. The file goes to ``options.save_path`` or
    <folder>/run.rrd and is named in the summary's files."""
    if viewer is None:
        return None
    path = Path(options.save_path) if options.save_path is not None else folder / "run.rrd"
    # The engines' stations come with the first macro step (set_stations): they know their meshes then.
    rec = RecorderProcess(sc, {name: {} for name in engines}, mode, save_path=path, viewer=viewer,
                          exaggeration=options.exaggeration, linkage_fps=options.linkage_fps)
    summary["files"]["recording"] = path.name if path.parent.resolve() == folder.resolve() else str(path.resolve())
    rec.log_text("scenario", (folder / "scenario.resolved.toml").read_text(encoding="utf-8"))
    return rec


def _start_exports(engines: dict, folder: Path) -> dict:
    """Files for the engines' own tools, asked for before the run: exudyn writes its solution
    file while it runs (``ExudynEngine.write_solution``). Returns {engine: file name}."""
    exports = {}
    if hasattr(engines.get("exudyn"), "write_solution"):
        engines["exudyn"].write_solution(folder / "exudyn_solution.txt")
        exports["exudyn"] = "exudyn_solution.txt"
    return exports


def _finish_exports(exports: dict, engines: dict, result, folder: Path, summary: dict, notes: list,
                    options: RunOptions) -> None:
    """After the run: MuJoCo's MJCF (``model.xml``), the exudyn solution file written meanwhile,
    and with ``options.animation`` a GIF of the linkage; each named in the summary's files, a
    failure a note (never a lost run)."""
    files = summary["files"]
    if "exudyn" in exports and (folder / exports["exudyn"]).exists():
        files["exudyn_solution"] = exports["exudyn"]
    def mjcf():
        engines["mujoco"].export_model(folder / "model.xml")
        return "model.xml"

    def gif():
        runs = {n: ch.run for n, ch in result.channels.items()}
        stations = {n: e.node_stations() for n, e in engines.items() if _has_stations(e)}
        return write_gif(folder / "linkage.gif", runs, stations, options.exaggeration).name

    if hasattr(engines.get("mujoco"), "export_model") and getattr(engines["mujoco"], "xml", None):
        files["mujoco_model"] = attempt(summary, notes, MJCF, mjcf)
    if options.animation and result is not None and "out_of_memory" not in summary:
        files["animation"] = attempt(summary, notes, GIF, gif)
    for key in ("mujoco_model", "animation"):
        if key in files and files[key] is None:
            del files[key]


#: The run's outputs after the loop as :func:`cosim.run_outcome.attempt` names them: (file, what the
#: run was doing, the note when it fails).
MJCF = ("model.xml", "writing model.xml", "model.xml not written")
GIF = ("linkage.gif", "drawing linkage.gif", "linkage.gif not drawn")
PARQUET = ("traces.parquet", "writing traces.parquet", "traces.parquet not written")
FIGURE = ("strains.png", "drawing the strain figure", "strain figure not drawn")


def _write_results(folder: Path, sc: Scenario, summary: dict, notes: list, options: RunOptions) -> None:
    """traces.parquet and strains.png/.svg after the run. Neither may lose the run: a failure is
    a note and a missing output, running out of memory fails the run and stops here
    (:func:`cosim.run_outcome.attempt`; traces.csv stays the run's crash-safe file)."""
    def parquet():
        return write_parquet(folder).name

    def figures():
        return [p.name for p in run_figures.write_run_figures(folder, sc, options.records)]

    write_json(folder / "summary.json", summary)          # the figure reads the final verdicts
    files = summary["files"]
    files["traces_parquet"] = attempt(summary, notes, PARQUET, parquet)
    if options.figures and "out_of_memory" not in summary:
        files["figures"] = attempt(summary, notes, FIGURE, figures)
    for key in ("traces_parquet", "figures"):
        if key in files and files[key] is None:
            del files[key]


def score_records(sc: Scenario, result, summary: dict, recorder=None, directory=None) -> None:
    """Records of the scenario's rig at its speed: listed in the summary, scored against every
    engine's last revolution (peaks records: peak errors; histories over crank angle: peak, RMS,
    correlation, phase lag, scale, envelope), drawn in the recording under /records."""

    recs = records_for(sc, directory)
    if not recs:
        return
    rpm = sc.drive.speed_rpm
    gauges = {g.name: g for g in sc.gauges}
    summary["records"], scores, warnings = {}, [], []
    summary["records_used"] = [{"name": r.name, "kind": r.kind, "format": r.format,
                                "source": r.provenance.get("source"), "table": r.provenance.get("table")}
                               for r in recs]
    for rec in recs:
        if rec.format == "peaks":
            for g, p in peaks_at(rec, rpm).items():
                summary["records"].setdefault(g, []).append({"label": rec.label, "title": rec.title,
                                                             "format": rec.format, **p})
                if recorder is not None:
                    recorder.log_reference(g, rec.name, bending_ue=(p.get("bending_max_ue"), p.get("bending_min_ue")),
                                           kind=rec.kind)
                if g in gauges:
                    warnings += convention_warnings(rec, gauges[g])
                for engine, ch in result.channels.items():
                    stats = summary["engines"][engine].get("gauges", {}).get(g)
                    if stats is None:
                        continue
                    sc_ = score_peaks(stats["bending_max_ue"], stats["bending_min_ue"], p.get("bending_max_ue"),
                                      p.get("bending_min_ue"))
                    scores.append({"engine": engine, "gauge": g, "record": rec.name, "kind": rec.kind, **sc_})
        elif rec.format == "history" and rec.index[1] == "deg":
            hist = history_over_angle(rec)
            for g, series in hist.items():
                if g == "angle_rad" or g not in gauges or "bending_ue" not in series:
                    continue
                warnings += convention_warnings(rec, gauges[g])
                rb = series["bending_ue"]
                summary["records"].setdefault(g, []).append({"label": rec.label, "title": rec.title,
                                                             "format": rec.format, "bending_max_ue": float(rb.max()),
                                                             "bending_min_ue": float(rb.min())})
                if recorder is not None:
                    recorder.log_reference(g, rec.name, angle=hist["angle_rad"], bending_ue=rb, kind=rec.kind)
                for engine, ch in result.channels.items():
                    run = ch.run
                    if not len(run.t) or g not in run.gauges:
                        continue
                    last = last_revolution(run.crank_angle)
                    sc_ = score_history(run.crank_angle[last], run.gauges[g][0][last] * 1e6, hist["angle_rad"], rb)
                    hint = sign_check(sc_)
                    if hint:
                        warnings.append(f"{engine} vs {rec.name} at {g}: {hint}")
                    scores.append({"engine": engine, "gauge": g, "record": rec.name, "kind": rec.kind, **sc_})
        else:
            summary["records"].setdefault("_values", []).append(
                {"label": rec.label, "values": [{k: v for k, v in r.items() if k in ("quantity", "link", "value",
                                                                                      "unit", "note")}
                                                for r in rec.rows]})
    for sc_ in scores:
        # A transient scored against a measured steady state is flagged, never hidden.
        sc_["steady"] = bool(summary["engines"].get(sc_["engine"], {}).get("steady", False))
        if not sc_["steady"]:
            warnings.append(f"{sc_['engine']} is not steady: its scores compare a transient with the record")
    summary["scores"] = scores
    summary["record_warnings"] = sorted(set(warnings))
    if recorder is not None and scores:
        lines = [f"{s['engine']:8s} {s['gauge']:12s} {s['record']:18s} +peak {_pct(s.get('plus_peak_error'))} "
                 f"-peak {_pct(s.get('minus_peak_error'))}{'' if s['steady'] else '  NOT STEADY'}" for s in scores]
        recorder.log_text("records/scores", "\n".join(lines + [""] + summary["record_warnings"]))


def _pct(x):
    return "   -   " if x is None or x != x else f"{100 * x:+6.1f}%"


def _has_stations(engine) -> bool:
    try:
        engine.node_stations()
        return True
    except Exception:        # an engine whose reset failed has no mesh
        return False
