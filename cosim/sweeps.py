"""Speed sweeps: peak strain against crank speed, per engine and gauge.

Every point is a prescribed-speed run of the scenario at one speed (``drive.speed`` replaced,
steps given as crank angles scale with it), from which the last revolution's peaks are kept. A
full-model periodic sweep continues from speed to speed: its first speed is
solved here before the workers fork, and the others run in contiguous blocks, each solve
starting from the previous orbits (:data:`CONTINUED_MODELS`; the answers are an independent
solve's to its tolerance). Points run in parallel through a ``concurrent.futures`` executor: a process pool on the
local cores, or, given a scheduler address, a Dask distributed cluster (``Client.get_executor``),
so a sweep that outgrows one machine needs an address, not new code.

Output folder ``logs/<scenario>-sweep-<timestamp>/``: ``sweep.csv`` (one row per speed, engine
and gauge), ``summary.json`` and ``sweep.rrd`` (peaks, Floquet multipliers and natural frequencies
against speed as 2D charts, :mod:`cosim.recording.summaries`). The files are rewritten as points
finish (at most once a second, and at the end), so an interrupted sweep keeps what it computed.

Owns: speed sweeps (periodic or marched) and their folder. Boundaries: the recording's charts are
cosim.recording.summaries.
"""
from __future__ import annotations

import json
import logging
import math
import os
import re
import time
from concurrent.futures import Future, as_completed
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

from tmm_core import TMMError
from tmm_core.ked import CrankMotion
from tmm_core.periodic import ORBIT_KINDS, orbit_stability, periodic_steady_state
from tmm_core.reduced import ReducedOptions, build_basis
from tmm_core.reduced_periodic import periodic_steady_state_reduced, stage_points
from tmm_core.reduced_stages import StageCoefficients
from tmm_core.compiled import statics as compiled_statics
from tmm_core.compiled.cache import PERIODIC_COMPILE_ESTIMATE_S

from .engines import check_engine_names
from .figures import peaks_by_speed
from .interrupts import Interrupts
from .master import CoSimulation, macro_step_for
from .metrics import steadiness
from .overrides import apply_overrides, prescribed_speed
from .parallel import describe, executor
from .physics_flags import buckling_flags
from .resonance import campbell, frequency_map, plot_sweep
from .run_progress import compile_notice
from .runs import last_revolution_stats
from .run_guards import MAX_HOURS, check_study, estimate_cost
from .runlog import run_folder, write_csv, write_json
from .scenario import ScenarioError, from_dict, load

log = logging.getLogger(__name__)
RANGE = re.compile(r"^\s*([0-9.eE+-]+)\s*:\s*([0-9.eE+-]+)\s*:\s*([0-9.eE+-]+)\s*$")


#: The most speeds one sweep takes (a range like 1:1e9:1 would allocate gigabytes).
MAX_POINTS = 1000


def parse_rpm(text: str) -> np.ndarray:
    """``"100:400:25"`` (start:stop:step, stop included when on the grid) or ``"95,241,373"`` [rpm]."""
    text = str(text).strip()
    m = RANGE.match(text)
    try:
        if m:
            a, b, h = (float(x) for x in m.groups())
            if not (h > 0 and b >= a > 0 and math.isfinite(b)):
                raise ValueError
            n = math.floor((b - a) / h + 1e-9)
            if n >= MAX_POINTS:         # refused before anything is allocated
                raise OverflowError
            values = a + h * np.arange(n + 1)
        else:
            values = np.array([float(x) for x in text.split(",") if x.strip()])
            if not len(values) or not np.all(np.isfinite(values)) or np.any(values <= 0):
                raise ValueError
            if len(values) > MAX_POINTS:
                raise OverflowError
    except OverflowError:
        raise ValueError(f"--rpm {text!r}: more than {MAX_POINTS} speeds; choose a coarser step") from None
    except ValueError:
        raise ValueError(f"--rpm: malformed rpm range {text!r}: write start:stop:step with 0 < start <= stop and "
                         "step > 0 (e.g. 100:400:25), or a list 95,241,373 of finite speeds") from None
    return values


def sweep_point(raw: dict, path: str, rpm: float, engines: tuple, revolutions: float,
                method: str = "periodic", many: bool = False) -> dict:
    """One speed: last-revolution peaks per engine and gauge (runs in a worker). The transfer-
    matrix engine uses the periodic steady-state solve (``method = "periodic"``, with its Floquet
    multipliers) or time marching like the others (``"march"``)."""

    sc = from_dict(apply_overrides(raw, prescribed_speed(rpm)), path)
    out = {"rpm": rpm, "engines": {}}
    tic = time.perf_counter()
    marched = tuple(e for e in engines if not (e == "tmm" and method == "periodic"))
    if "tmm" in engines and method == "periodic":
        out["engines"]["tmm"] = periodic_point(sc, many)
    if marched:
        res = CoSimulation(sc, marched, mode="prescribed").run(revolutions=revolutions)
        for name, ch in res.channels.items():
            # A marched point's peaks are a steady state's only if its last revolutions agree (near
            # buckling the FE rig's response stays irregular: 40 revolutions at 450 rpm differ by ~100 %).
            out["engines"][name] = {"status": ch.status, "error": ch.error,
                                    **last_revolution_stats(ch.run, sc.revolution_period_s),
                                    **steadiness(ch.run, sc.output.steady_tolerance)}
    out["wall_time_s"] = time.perf_counter() - tic
    return out


#: The reduced model's speed-free parts built in this process, by scenario without its speed:
#: ``{key: [basis, stage coefficients or None]}``. The basis depends on the geometry, not on the
#: speed (50 ms of a ~0.35 s point); the stage coefficients (tmm_core.reduced_stages) replace the
#: ~0.1 s of stage matrices of every further speed by ~0.01 s, but cost ~0.65 s once, so only a
#: process that solves many speeds (``many``) builds them.
_REDUCED: dict = {}
MANY_SPEEDS = 10           # speeds per worker from which a sweep keeps the stage coefficients
#: While points finish, the sweep's files are rewritten at most this often [s] (and always at the
#: end, also when interrupted): rewriting them after every point cost the main process 1.3 s of
#: an 81-point sweep (the summary grows with every point), on cores the workers need.
SAVE_EVERY_S = 1.0


def _speed_free_key(sc, *extra) -> tuple:
    """The scenario without its drive speed (and ``extra``), as a dictionary key."""
    raw = {k: v for k, v in sc.raw.items() if k != "drive"}
    raw["drive"] = {k: v for k, v in sc.raw.get("drive", {}).items() if k != "speed"}
    return (json.dumps(raw, sort_keys=True, default=str), sc.drive.start_angle_rad, *extra)


def _reduced_parts(sc, model, options, many: bool):
    """``(basis, stage coefficients or None)`` of the scenario's time-domain ``model``
    (:class:`tmm_core.discretization.Discretization`) for the reduced model."""
    key = _speed_free_key(sc, repr(options))
    if key not in _REDUCED:
        if len(_REDUCED) >= 2:
            _REDUCED.clear()
        _REDUCED[key] = [build_basis(model, sc.drive.start_angle_rad, options), None]
    parts = _REDUCED[key]
    if many and parts[1] is None:
        # The stage angles of a constant-speed revolution at options.steps steps: every speed's
        # (ReducedModel checks that they are, and builds directly where they are not).
        crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=360.0 / options.steps, revolutions=1.0,
                                           start_angle=sc.drive.start_angle_rad)
        parts[1] = StageCoefficients.of(model, parts[0], stage_points(crank)[1])
    return parts[0], parts[1]


#: The periodic orbits this process solved last, by scenario without its speed and TMM model:
#: ``{key: [(rpm, state), ...]}`` (the last two), the start of the next speed's solve in a sweep's
#: worker (its speeds come in a contiguous ascending block: cosim.parallel.BlockPool).
_ORBITS: dict = {}
#: The TMM models whose sweep continues from speed to speed. Not the reduced model: from the
#: previous orbit it needs as many revolutions as from its linear start (six to eight; the stiff
#: static-correction coordinates' state changes irregularly with speed, docs/theory.md,
#: 'Continuation in speed'), and the contiguous blocks continuation needs balance the workers
#: worse than single points (81-point FE-rig sweep on 2 workers: 19.6 s with continuation, 16.8 s
#: without). Nor its warm-up in the main process (:func:`warm_up`): on as many workers as cores
#: the workers' own kernel loading and stage coefficients run side by side, in the time the main
#: process takes for one copy, so it saved CPU but no time (median of 3: 18.3 s with it, 16.6 s
#: without).
CONTINUED_MODELS = ("full",)
#: A solved orbit starts another speed's solve only within this fraction of that speed: farther,
#: the orbits differ by more than Anderson's revolutions repair faster than the linear start.
CONTINUATION_REACH = 0.1


def predicted_state(history: list, rpm: float) -> np.ndarray | None:
    """The periodic state at ``rpm`` predicted from solved orbits ``[(rpm, state), ...]`` (the
    last two): the secant through them in speed, or the last one alone; None when the last is
    farther than :data:`CONTINUATION_REACH` of ``rpm``. The secant only through neighbours: a
    worker's blocks come highest first, and a secant from 455 rpm through 405 rpm (another
    block's orbit, past the fold) to 415 rpm lost the orbit a start from 405 rpm alone finds."""
    if not history or abs(rpm - history[-1][0]) > CONTINUATION_REACH * rpm:
        return None
    (r1, x1) = history[-1]
    if (len(history) < 2 or history[-2][0] == r1 or len(history[-2][1]) != len(x1)
            or abs(r1 - history[-2][0]) > CONTINUATION_REACH * rpm):
        return x1
    (r0, x0) = history[-2]
    return x1 + (rpm - r1) / (r1 - r0) * (x1 - x0)


def periodic_solution(sc, many: bool = False):
    """The scenario's periodic steady state (``tmm_core.periodic.periodic_steady_state``) with its
    TMM settings at its drive speed. ``many``: this process solves many speeds of the scenario (a
    sweep's worker): the reduced model keeps its speed-free stage matrices, and the full model's
    solve starts from the orbits this process solved last (:func:`predicted_state`; continuation
    in speed, :data:`CONTINUED_MODELS`)."""
    s = sc.tmm
    model = sc.time_domain().model
    key = _speed_free_key(sc, s.model)
    history = _ORBITS.get(key, []) if many and s.model in CONTINUED_MODELS else []
    guess = predicted_state(history, sc.drive.speed_rpm)
    if s.model == "reduced":
        # solver.tmm.model = "reduced": link modes plus a static correction (tmm_core.reduced).
        options = ReducedOptions(modes=s.modes)
        basis, stages = _reduced_parts(sc, model, options, many)
        p = periodic_steady_state_reduced(model, sc.drive.speed_rad_s, start_angle=sc.drive.start_angle_rad,
                                          options=options, basis=basis, stages=stages, initial_state=guess)
    else:
        p = periodic_steady_state(model, sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"),
                                  start_angle=sc.drive.start_angle_rad, initial_state=guess)
    if many:
        if len(_ORBITS) >= 2 and key not in _ORBITS:
            _ORBITS.clear()
        _ORBITS[key] = (history + [(sc.drive.speed_rpm, p.state)])[-2:]
    return p


def warm_up(raw: dict, path: str, rpm: float, engines: tuple, revolutions: float) -> dict:
    """The sweep's first point solved in the parent before the workers start (with ``many``): it
    loads the compiled kernels from their disk cache and builds the speed-free data (the reduced
    model's basis and stage coefficients) once, and the workers, forked after it, inherit both
    and its orbit instead of each paying ~0.7 s of kernel loading and ~0.65 s of stage
    coefficients. One thread (BLAS and the compiled statics): a forked child must not inherit
    a thread pool's state."""
    threads = compiled_statics.THREADS
    compiled_statics.THREADS = 1
    try:
        with threadpool_limits(1, user_api="blas"):
            return sweep_point(raw, path, rpm, engines, revolutions, "periodic", True)
    finally:
        compiled_statics.THREADS = threads


def periodic_point_histories(sc, n_grid: int = 360) -> dict:
    """Periodic TMM response on a uniform crank-angle grid (degrees from 0 to 360 - step, wrapped):
    {"status", "angle_deg", "gauges": {g: {"bending_ue", "axial_ue"}}} (lists, picklable)."""
    try:
        p = periodic_solution(sc)
    except TMMError as exc:
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    grid = np.arange(n_grid) * 360.0 / n_grid
    a = np.mod(np.degrees(p.angle), 360.0)
    order = np.argsort(a)
    out = {"status": "completed", "angle_deg": grid.tolist(), "gauges": {}}
    for g, (b, ax) in p.gauges.items():
        out["gauges"][g] = {"bending_ue": (np.interp(grid, a[order], b[order] * 1e6, period=360.0)).tolist(),
                            "axial_ue": (np.interp(grid, a[order], ax[order] * 1e6, period=360.0)).tolist()}
    return out


def periodic_point(sc, many: bool = False) -> dict:
    """Periodic steady state of the scenario's TMM model at its drive speed: peaks, drive
    torque range and the largest Floquet multiplier (|mu| > 1: parametric resonance); ``many``:
    see :func:`periodic_solution`."""
    try:
        p = periodic_solution(sc, many)
    except TMMError as exc:
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
    orbit = orbit_stability(p.multipliers)
    d = {"status": "completed", "error": None, "method": "periodic", "model": p.info.get("model", "full"),
         "floquet_max": orbit["mu_max"], "parametric_resonance": not orbit["stable"],
         "orbit": "stable" if orbit["stable"] else orbit["kind"], "residual": p.residual,
         "start": p.info.get("start", "linear"),
         "drive_torque_max_Nm": float(p.drive_torque.max()), "drive_torque_min_Nm": float(p.drive_torque.min()),
         "gauges": {}}
    for g, (b, a) in p.gauges.items():
        d["gauges"][g] = {"bending_max_ue": float(b.max() * 1e6), "bending_min_ue": float(b.min() * 1e6),
                          "axial_max_ue": float(a.max() * 1e6), "axial_min_ue": float(a.min() * 1e6)}
    return d


#: The periodic solve counted as this many revolutions of the march (its stored revolution of
#: configurations plus the shooting's few iterations over it) in a sweep's estimate.
PERIODIC_REVOLUTIONS = 3.0


def sweep_point_cost(sc, rpms, engines, revolutions, method: str) -> dict:
    """One point's :func:`cosim.run_guards.estimate_cost` at the sweep's lowest speed (the dearest
    point: steps in seconds grow with the period, steps in degrees do not), an upper bound for
    the others; ``revolutions`` None: the scenario's (until steady: its ``output.max_revolutions``)."""
    slow = sc.with_overrides(prescribed_speed(float(np.min(rpms))))
    period = slow.revolution_period_s
    revs = revolutions or slow.output.revolutions or slow.output.max_revolutions
    marched = [e for e in engines if not (e == "tmm" and method == "periodic")]
    parts = []
    if marched:
        parts.append(estimate_cost(slow, marched, revs * period, macro_step_for(slow, marched, mode="prescribed")))
    if len(marched) < len(engines):
        step = slow.engine_step_s("tmm")
        parts.append(estimate_cost(slow, ["tmm"], PERIODIC_REVOLUTIONS * period, step))
    return {"seconds": sum(p["seconds"] for p in parts), "bytes": sum(p["bytes"] for p in parts),
            "text": "; ".join(p["text"] for p in parts)}


def _sweep_solves(rpm, rpms, revolutions) -> dict:
    """What sets a sweep's size, for :func:`cosim.run_guards.check_study`'s message."""
    if revolutions is not None:
        return {"option": "--revolutions", "value": revolutions, "count": len(rpms), "what": "points"}
    return {"option": "--rpm", "value": rpm if isinstance(rpm, str) else f"{len(rpms)} speeds", "count": len(rpms),
            "what": "points"}


def _rows(point: dict) -> list:
    rows = []
    for engine, e in point["engines"].items():
        gauges = e.get("gauges") or {"": {}}
        for g, stats in gauges.items():
            rows.append({"rpm": point["rpm"], "engine": engine, "gauge": g, "status": e["status"],
                         **{k: stats.get(k) for k in ("bending_max_ue", "bending_min_ue", "axial_max_ue", "axial_min_ue")},
                         "drive_torque_max_Nm": e.get("drive_torque_max_Nm"),
                         "drive_torque_min_Nm": e.get("drive_torque_min_Nm"), "floquet_max": e.get("floquet_max"),
                         "steady": e.get("steady"), "revolution_change": e.get("revolution_change"),
                         "error": e.get("error") or ""})
    return rows


#: A sweep's status when every point ran but at some an engine found no solution: the sweep is
#: whole (those points are results, e.g. no periodic state near buckling), but not every speed has
#: peaks, which a plain "completed" hid (1000 points, 584 of them unsolved, read as a success).
UNSOLVED = "completed with unsolved points"


def _unsolved(point: dict) -> bool:
    """A point that ran but where some engine has no solution (``did_not_run`` is not counted)."""
    return not point.get("did_not_run") and any(e.get("status") != "completed" for e in point["engines"].values())


def sweep_status(points: list) -> str:
    """``"failed"`` when a point did not run at all (a worker died or raised), :data:`UNSOLVED`
    when every point ran but some have no solution, else ``"completed"``."""
    if any(p.get("did_not_run") for p in points):
        return "failed"
    return UNSOLVED if any(_unsolved(p) for p in points) else "completed"


def unsolved_points(sc, points: list) -> dict | None:
    """The points without a solution: ``{"count", "of", "rpm", "reasons": [{"error", "count",
    "rpm"}], "note"}`` (None when every point solved). Errors alike but for their numbers are one
    reason; the note says whether the points lie beyond the last solved speed and what that speed
    showed (its largest |Floquet multiplier| and links' share of their Euler load [%])."""
    bad = sorted((p for p in points if _unsolved(p)), key=lambda p: p["rpm"])
    if not bad:
        return None
    reasons = {}
    for p in bad:
        for e in p["engines"].values():
            if e.get("status") != "completed":
                text = str(e.get("error") or e.get("status"))
                r = reasons.setdefault(re.sub(r"\d+(\.\d+)?([eE][-+]?\d+)?", "#", text),
                                       {"error": text, "count": 0, "rpm": []})
                r["count"] += 1
                r["rpm"].append(p["rpm"])
    return {"count": len(bad), "of": len(points), "rpm": [p["rpm"] for p in bad],
            "reasons": sorted(reasons.values(), key=lambda r: -r["count"]), "note": _unsolved_note(sc, points, bad)}


def _unsolved_note(sc, points: list, bad: list) -> str:
    """Why the points may have no solution: past the last solved speed a periodic solve that
    fails is a finding about the linkage (its response stops being periodic: near buckling or
    past a parametric resonance), not a lost point; between solved speeds it is the solver's."""
    solved = [p for p in points if not p.get("did_not_run") and not _unsolved(p)]
    below = [p for p in solved if p["rpm"] < bad[0]["rpm"]]
    if not below or any(p["rpm"] > bad[0]["rpm"] for p in solved):
        return ("some speeds between solved ones have no solution: see the errors (a solver's failure there, or a "
                "narrow band where the response is not periodic)")
    last = max(below, key=lambda p: p["rpm"])
    tmm = last["engines"].get("tmm") or {}
    seen = []
    if tmm.get("floquet_max") is not None:
        seen.append(f"largest |Floquet multiplier| {tmm['floquet_max']:.3f}")
    seen += [f"{f['message'].split(':')[1].strip()} ({100 * f['value']:.0f} % of its Euler load)"
             for f in buckling_flags(sc, tmm.get("gauges"))]
    return (f"every speed from {bad[0]['rpm']:g} rpm up has no solution; the highest solved speed below, "
            f"{last['rpm']:g} rpm, shows {'; '.join(seen) or 'nothing flagged'}: beyond it the response is not "
            "periodic (near buckling or past a parametric resonance); that is a finding about the linkage, not a "
            "lost point (--method march shows the response there)")


def run_sweep(scenario: str, rpm, engines=("tmm",), revolutions: float | None = None, workers: int | None = None,
              scheduler: str | None = None, out: Path | None = None, progress: bool = True,
              record: bool = True, method: str = "periodic", resonance: bool = True,
              records_dir: Path | None = None, model: str | None = None, max_hours: float = MAX_HOURS) -> tuple:
    """Run the sweep; returns ``(folder, summary)``. ``resonance``: also the natural-frequency map
    and Campbell diagram (four-bars; 36 eigenvalue searches, with a progress bar); ``records_dir``:
    where the recorded peaks drawn on the figure come from (default: the shipped records);
    ``model``: the TMM model of the periodic solves ('full' or 'reduced'; default: the
    scenario's ``solver.tmm.model``); ``max_hours``: refuse a sweep estimated to take longer
    (:func:`cosim.run_guards.check_study`, before any point runs)."""
    sc = load(scenario)
    if model is not None:
        if model not in ("full", "reduced"):
            raise ScenarioError(f"sweep: model must be 'full' or 'reduced', got {model!r}")
        sc = sc.with_overrides({"solver.tmm.model": model})
    if sc.tmm.model == "reduced" and method == "march" and "tmm" in engines:
        raise ScenarioError("sweep: the reduced TMM model solves the periodic steady state only; use --method "
                            "periodic, or the full model (--model full) to march in time")
    rpms = parse_rpm(rpm) if isinstance(rpm, str) else np.asarray(rpm, dtype=float)
    revs = sc.output.revolutions if revolutions is None else revolutions
    check_engine_names(engines)
    check_study(sc, "sweep", _sweep_solves(rpm, rpms, revolutions), sweep_point_cost(sc, rpms, engines, revs, method),
                workers, max_hours)
    record_peaks = peaks_by_speed(getattr(sc, "rig", None), float(rpms.min()), float(rpms.max()), records_dir)
    folder = run_folder(f"{sc.name}-sweep", out)
    log.info("sweep of %s at %d speeds (%s); results to %s", sc.name, len(rpms), ", ".join(engines), folder)
    if "tmm" in engines:
        compile_notice(PERIODIC_COMPILE_ESTIMATE_S)
    summary = {"scenario": sc.name, "status": "incomplete", "rpm": rpms.tolist(), "engines": list(engines),
               "revolutions": revs, "method": method, "model": sc.tmm.model, "executor": describe(scheduler),
               "points": []}
    write_json(folder / "summary.json", summary)
    bar = None
    if progress:
        from tqdm import tqdm
        bar = tqdm(total=len(rpms), unit="point", desc=f"sweep {sc.name}", disable=None)
    rows, points = [], []
    tic = time.perf_counter()
    try:
        # The reduced model: enough speeds per worker to repay its speed-free stage matrices. The
        # full model continues from speed to speed in any sweep (each guess within its reach): a
        # 7-point sweep solved each speed from the linear start and left 415 and 425 rpm of the FE
        # rig unsolved, which continuation from 405 rpm solves.
        continued = sc.tmm.model in CONTINUED_MODELS and len(rpms) > 1
        many = continued or len(rpms) >= MANY_SPEEDS * (workers or os.cpu_count() or 1)
        futures = _first_point(sc, rpms, tuple(engines), revs, method, continued and not scheduler)
        blocks = len(rpms) - len(futures) if continued else None
        # Interrupts: a SIGTERM that lands while a worker is forked raises its KeyboardInterrupt in
        # an at-fork hook, where Python ignores it; remembered, it stops the sweep at the next point.
        with Interrupts() as interrupts, executor(workers, scheduler, blocks) as ex:
            futures.update({ex.submit(sweep_point, sc.raw, str(sc.path or sc.name), float(r), tuple(engines), revs,
                                      method, many): float(r) for r in rpms[len(futures):]})
            saved = -math.inf
            for fut in as_completed(futures):
                interrupts.check()
                try:
                    point = fut.result()
                except Exception as exc:       # a worker that died or raised: keep the others
                    point = {"rpm": futures[fut], "error": f"{type(exc).__name__}: {exc}", "engines": {},
                             "did_not_run": True}
                points.append(point)
                rows += _rows(point)
                if time.perf_counter() - saved >= SAVE_EVERY_S:
                    _save(folder, summary, points, rows)
                    saved = time.perf_counter()
                if bar is not None:
                    bar.update(1)
        summary["points_without_solution"] = sorted(p["rpm"] for p in points if _unsolved(p))
        summary["points_not_steady"] = sorted(p["rpm"] for p in points if any(
            e.get("status") == "completed" and e.get("steady") is False for e in p["engines"].values()))
        summary["unsolved_points"] = unsolved_points(sc, points)
        summary["status"] = sweep_status(points)
    except KeyboardInterrupt:
        summary["status"] = "interrupted"
    finally:
        _save(folder, summary, points, rows)        # whatever finished, also when interrupted
        if bar is not None:
            bar.close()
    summary["wall_time_s"] = time.perf_counter() - tic
    try:
        fmap = _after_points(sc, folder, summary, points, rpms, resonance, progress, record_peaks)
    except KeyboardInterrupt:
        # The points are on disk; the figure or map in progress is not: the summary says so.
        summary["status"] = "interrupted"
        summary.setdefault("notes", []).append("interrupted after the points: figures or recording may be missing")
        write_json(folder / "summary.json", summary)
        raise
    write_json(folder / "summary.json", summary)
    if record and points:
        _record(folder / "sweep.rrd", sc.name, summary["points"], fmap, (float(rpms.min()), float(rpms.max())),
                record_peaks)
    return folder, summary


def _first_point(sc, rpms, engines: tuple, revolutions, method: str, warm: bool) -> dict:
    """``{future: rpm}`` of the sweep's first speed solved in this process as the workers' warm-up
    (:func:`warm_up`; a continued periodic TMM-only sweep on local workers), else empty."""
    if not (warm and method == "periodic" and engines == ("tmm",)):
        return {}
    future = Future()
    future.set_result(warm_up(sc.raw, str(sc.path or sc.name), float(rpms[0]), engines, revolutions))
    return {future: float(rpms[0])}


def _after_points(sc, folder: Path, summary: dict, points: list, rpms, resonance: bool, progress: bool,
                  record_peaks) -> dict | None:
    """The natural-frequency map (four-bars, unless the sweep was interrupted) and the figure;
    fills the summary's resonance keys and figures, returns the map (or None)."""
    fmap = None
    four_bar = type(sc.mechanism).__name__ == "FourBarMechanism"
    if resonance and not four_bar:
        log.info("no Campbell diagram: the natural-frequency map is implemented for four-bars only")
    if resonance and four_bar and points and summary["status"] != "interrupted":
        log.info("natural frequencies over a revolution for the Campbell diagram (--no-campbell skips it)")
        try:
            fmap = frequency_map(sc, progress=progress)
        except KeyboardInterrupt:        # the sweep's points are done: keep them, drop only the map
            log.warning("Campbell map interrupted; the sweep's results are written without it")
            summary.setdefault("notes", []).append("the natural-frequency map was interrupted (no Campbell diagram)")
        if fmap is not None:
            modes = np.where(np.isfinite(fmap["f_Hz"]), fmap["f_Hz"], -1).tolist()
            summary["natural_frequencies_Hz"] = {"angle_deg": np.degrees(fmap["angle_rad"]).tolist(), "modes": modes}
            summary["resonance_candidates"] = campbell(fmap, float(rpms.min()), float(rpms.max()))
    summary["parametric_resonance_rpm"] = sorted(p["rpm"] for p in points if p["rpm"] is not None and
                                                 (p["engines"].get("tmm") or {}).get("parametric_resonance"))
    summary["unstable_orbits"] = unstable_orbits(points)
    summary["records_peaks"] = record_peaks
    if points:
        summary["figures"] = [str(x.name) for x in plot_sweep(folder, sc.name, summary["points"], fmap,
                                                                marks_rpm=[sc.drive.speed_rpm],
                                                                record_peaks=record_peaks,
                                                                not_steady_rpm=summary.get("points_not_steady", ()),
                                                                unstable_rpm=[o["rpm"] for o in summary["unstable_orbits"]])]
    return fmap


def unstable_orbits(points: list) -> list:
    """The TMM's unstable periodic orbits of a sweep, by speed: ``[{"rpm", "mu_max", "kind",
    "meaning"}]`` (``kind`` a key of :data:`tmm_core.periodic.ORBIT_KINDS`, ``meaning`` its text):
    solved orbits that a march would leave, not points without a solution."""
    out = []
    for p in points:
        tmm = p["engines"].get("tmm") or {}
        if p["rpm"] is not None and tmm.get("orbit") not in (None, "stable"):
            out.append({"rpm": p["rpm"], "mu_max": tmm["floquet_max"], "kind": tmm["orbit"],
                        "meaning": ORBIT_KINDS.get(tmm["orbit"], "")})
    return sorted(out, key=lambda o: o["rpm"])


def _save(folder: Path, summary: dict, points: list, rows: list) -> None:
    """The finished points into ``summary.json`` and ``sweep.csv`` (sorted by speed)."""
    summary["points"] = sorted(points, key=lambda p: p["rpm"])
    write_json(folder / "summary.json", summary)
    if rows:
        write_csv(folder / "sweep.csv", sorted(rows, key=lambda r: (r["rpm"], r["engine"], r["gauge"])))


def _record(path: Path, name: str, points: list, fmap=None, rpm_range=None, record_peaks=()) -> None:
    """Peaks, Floquet multipliers and natural frequencies against speed as 2D charts in rerun
    (:func:`cosim.recording.summaries.sweep_recording`)."""
    from .recording.summaries import sweep_recording
    sweep_recording(path, name, points, fmap, rpm_range, record_peaks)
