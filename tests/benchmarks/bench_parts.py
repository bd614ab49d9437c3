"""The side-by-side benchmark's parts other than the engines (``tests.benchmarks.bench``).

* ``quasi_static``: one quasi-static revolution (360 positions, 8 segments per link,
  beam-column), compiled against numpy side by side, the factorization of a revolution of
  configurations (the time domain's set-up) and the kernels' first call in a fresh process
  (factorization_benchmark.side_by_side, FE rig 241 rpm); and the same revolution on the
  Alexander-Lawrence four-bar (ked_benchmark).
* ``floor``: the compiled march per step on the cached maps of a revolution against the 3-5 us
  per step the issue estimates as the floor (factorization_benchmark.per_step).
* ``sweep``: the 81-point periodic sweep, 100-500 rpm (sweep_benchmark), stopped at a time cap.
* ``overhead``: the co-simulation bench's own cost (master, traces, rerun streaming).
* ``scaling``: the TMM's cost over 4-512 segments per link and over revolutions.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


# -- quasi-static revolution and the per-step floor -------------------------------------------------
def quasi_static(segments: int, repeats: int) -> dict:
    """FE rig: numpy and compiled side by side (min/median [s], ratios, first compiled calls [s]);
    Alexander-Lawrence: the compiled beam-column revolution, median [s]."""
    from .factorization_benchmark import side_by_side
    from .ked_benchmark import median_time, quasi_static_revolution
    out = {"fe_crank_rocker_241rpm": side_by_side(segments, repeats)}
    out["alexander_lawrence_400rpm"] = {"segments_per_link": segments, "positions": 360,
                                        "quasi_static_beam_column_s": median_time(
                                            quasi_static_revolution(segments, beam_column=True), repeats)}
    return out


def floor(settings: list, repeats: int) -> list:
    """Compiled march per step [s] at each (segments per link, step [deg]) of the FE rig, with
    its set-up and the ratio to the 3-5 us floor."""
    from .factorization_benchmark import per_step
    return [per_step(n, d, repeats) for n, d in settings]


# -- the speed sweep, capped ----------------------------------------------------------------------
def sweep_capped(cap_s: float, workers: int, segments: int = 8, rpm: str = "100:500:5") -> dict:
    """The periodic sweep in a child process stopped after ``cap_s`` seconds: its result, or
    {"finished": False, "points_done": how many points it finished, "wall_time_s": cap}."""
    with tempfile.TemporaryDirectory() as tmp:
        out_dir, result = Path(tmp) / "run", Path(tmp) / "result.json"
        cmd = [sys.executable, "-m", "tests.benchmarks.sweep_benchmark", "--workers", str(workers), "--segments",
               str(segments), "--rpm", rpm, "--out-dir", str(out_dir), "--result", str(result)]
        tic = time.perf_counter()
        # Its own process group, so the sweep's worker processes stop with it at the cap.
        proc = subprocess.Popen(cmd, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        try:
            _, err = proc.communicate(timeout=cap_s)
            finished = True
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            _, err = proc.communicate()
            finished = False
        wall = time.perf_counter() - tic
        if finished and proc.returncode == 0 and result.exists():
            return {"finished": True, "cap_s": cap_s, **json.loads(result.read_text())}
        summary = out_dir / "sweep" / "summary.json"
        done = len(json.loads(summary.read_text()).get("points", [])) if summary.exists() else 0
        row = {"finished": False, "cap_s": cap_s, "wall_time_s": wall, "points_done": done, "rpm": rpm,
               "workers": workers, "segments_per_link": segments}
        if finished:
            lines = (err or "").strip().splitlines()
            row["error"] = lines[-1] if lines else f"exit status {proc.returncode}"
        else:
            row["note"] = f"not finished in {cap_s:.0f} s ({done} points done)"
        return row


# -- the bench's own cost -------------------------------------------------------------------------
OVERHEAD_PAIRS = 9         # alternating unrecorded / recorded whole runs per macro-step setting


def bench_overhead(rig, macro_multiples, revolutions, pairs: int = OVERHEAD_PAIRS):
    """Engine time and the master's, and whole runs without and with rerun streaming [s] and as
    fractions of the engine's time, at macro steps of ``macro_multiples`` TMM steps (1 deg)."""
    from cosim.engines import make_engine
    from cosim.master import CoSimulation
    from cosim.runs import RunOptions, run_scenario
    from cosim.scenario import load
    from .bench_accuracy import timed
    sc = load(rig)
    # A first short run pays the kernels' first call (cache load), which would fall on the first row.
    CoSimulation(sc.with_overrides({"solver.tmm.step": "1 deg"}), ("tmm",), mode="prescribed").run(revolutions=0.1)
    out = {}
    for m in macro_multiples:
        s = sc.with_overrides({"coupling.macro_step": f"{m} deg", "solver.tmm.step": "1 deg"})
        eng = make_engine("tmm")
        inner = [0.0]
        # The engine's time is its set-up (reset: configurations, quasi-static start) and its steps.
        eng.advance, eng.reset = timed(eng.advance, inner), timed(eng.reset, inner)
        tic = time.perf_counter()
        cs = CoSimulation(s, {"tmm": eng}, mode="prescribed")
        cs.run(revolutions=revolutions)
        total = time.perf_counter() - tic
        # In prescribed mode the master groups macro steps to ~10 deg: record what it ran.
        row = {"macro_engine_steps": m, "engine_steps_per_call": int(round(cs.macro_step_s / s.engine_step_s("tmm"))),
               "engine_s": inner[0], "master_s": total - inner[0],
               "master_fraction": (total - inner[0]) / inner[0]}
        # Whole runs without and with the rerun recording, alternating, the fastest of nine each
        # (a loaded machine adds noise of the order of the fixed costs). The run's loop (the
        # master's run: engines, traces, the recording's batching) is timed apart: the recording's
        # child writes beside the loop and beside the results written after it.
        paired = []             # per pair {key: (whole run, loop, engine) [s]}
        loop_time = [0.0]
        run_method = CoSimulation.run
        CoSimulation.run = timed(run_method, loop_time)
        try:
            for _ in range(pairs):
                pair = {}
                for viewer in ("none", "save"):
                    with tempfile.TemporaryDirectory() as tmp:
                        loop_time[0] = 0.0
                        tic = time.perf_counter()
                        res = run_scenario(s, RunOptions(engines=("tmm",), revolutions=revolutions,
                                                         out=Path(tmp) / "r", viewer=viewer, progress=False))
                        wall = time.perf_counter() - tic
                        key = "stream" if viewer == "save" else "traces_only"
                        pair[key] = (wall, loop_time[0], res.summary["engines"]["tmm"]["wall_time_s"])
                paired.append(pair)
        finally:
            CoSimulation.run = run_method
        # The fastest whole run of each kind (with its engine time) and the fastest loop.
        best = {key: min((p[key][0], p[key][2]) for p in paired) for key in ("traces_only", "stream")}
        loops = {key: min(p[key][1] for p in paired) for key in ("traces_only", "stream")}
        for key, (wall, eng_s) in best.items():
            row[f"run_{key}_s"] = wall
            row[f"overhead_{key}_fraction"] = (wall - eng_s) / eng_s
            row[f"loop_{key}_s"] = loops[key]
        # The streaming's own cost: what the recording adds to the same run, against the engine's
        # time, in the whole run and in the run's loop.
        row["streaming_s"] = best["stream"][0] - best["traces_only"][0]
        row["streaming_fraction"] = row["streaming_s"] / best["traces_only"][1]
        row["streaming_loop_s"] = loops["stream"] - loops["traces_only"]
        row["streaming_loop_fraction"] = row["streaming_loop_s"] / best["traces_only"][1]
        # The same from the pairs (each recorded run against the unrecorded one just before it):
        # the median difference and its spread (the fastest-of differences above swing by a few
        # hundredths of a second from one benchmark run to the next).
        engine = float(np.median([p["traces_only"][2] for p in paired]))
        for key, col in (("paired_whole", 0), ("paired_loop", 1)):
            d = np.array([p["stream"][col] - p["traces_only"][col] for p in paired])
            row[f"streaming_{key}_median_fraction"] = float(np.median(d)) / engine
            row[f"streaming_{key}_quartiles_fraction"] = [float(q) / engine for q in np.percentile(d, [25, 75])]
        row["pairs"] = paired
        out[str(m)] = row
    return out


# -- TMM scaling ------------------------------------------------------------------------------------
def tmm_scaling(rig, segments, revolutions_list, tiny):
    """Per segment count: a quasi-static revolution (360 positions, beam-column) and a time-domain
    revolution at 1 deg on the default path (dense maps up to FACTORS_ABOVE_DOF, then the stored
    factorizations), on the maps alone and on the numpy Riccati sweeps alone [s]; above 128
    segments per link the sweeps march a quarter revolution (scaled to one).
    Per revolution count: wall time [s], fitted as set-up + cost per revolution."""
    from cosim.scenario import load
    from tmm_core import CrankMotion, TimeDomain, batches, quasi_static as qs_solve
    from .bench_accuracy import scenario_for
    sc = load(rig)
    q = np.radians(np.arange(360.0))
    # A first call loads the compiled kernels (numba's disk cache) and starts the kernels' thread
    # pool (a batch this large runs in parallel), which would fall on the first row.
    qs_solve(sc.mechanism, q, sc.drive.speed_rad_s, beam_column=True, tol=1e-8)
    default_limit = batches.FACTORS_ABOVE_DOF
    for limit in (0, 10**9):                  # and the march's first call on each path
        batches.FACTORS_ABOVE_DOF = limit
        try:
            TimeDomain(sc.mechanism, integrator="generalized_alpha", gauges=sc.gauges).run(
                CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=1.0, revolutions=0.05), start="quasi_static")
        finally:
            batches.FACTORS_ABOVE_DOF = default_limit
    rows = []
    for n in segments:
        mech = scenario_for(rig, "tmm", {"segments": n}).mechanism
        tic = time.perf_counter()
        try:
            # 1e-8: with hundreds of segments the beam-column iteration stalls near 4e-10 (round-off).
            qs_solve(mech, q, sc.drive.speed_rad_s, beam_column=True, tol=1e-8)
        except Exception as exc:
            rows.append({"segments": n, "error": f"{type(exc).__name__}: {exc}"})
            continue
        row = {"segments": n, "quasi_static_revolution_s": time.perf_counter() - tic}
        # The default path (dense load maps up to FACTORS_ABOVE_DOF, then the compiled march on
        # stored factorizations), the maps as far as they go, and the numpy Riccati sweeps alone.
        for key, limit, budget, maps_to in (("time_domain_revolution_s", 16 if tiny else 512, None, None),
                                            ("time_domain_maps_revolution_s", 8 if tiny else 64, None, 10**9),
                                            ("time_domain_sweeps_revolution_s", 4 if tiny else 512, 0.0, None)):
            if n > limit:
                continue
            revs = 0.25 if n > 128 and budget is not None else 1.0
            td = TimeDomain(mech, integrator="generalized_alpha", gauges=sc.gauges,
                            **({} if budget is None else {"max_map_bytes": budget}))
            batches.FACTORS_ABOVE_DOF = default_limit if maps_to is None else maps_to
            try:
                tic = time.perf_counter()
                td.run(CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=1.0, revolutions=revs),
                       start="quasi_static", record_displacements=False)
            finally:
                batches.FACTORS_ABOVE_DOF = default_limit
            row[key] = (time.perf_counter() - tic) / revs
            row[key.replace("_revolution_s", "_revolutions_marched")] = revs
        rows.append(row)
    revs = []
    for r in revolutions_list:
        td = TimeDomain(sc.mechanism, integrator="generalized_alpha", gauges=sc.gauges)
        tic = time.perf_counter()
        td.run(CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=1.0, revolutions=r), start="quasi_static",
               record_displacements=False)
        revs.append({"revolutions": r, "wall_s": time.perf_counter() - tic})

    def exponent(key):
        ok = [r for r in rows if key in r]
        if len(ok) < 2:
            return float("nan")
        x, y = np.log([r["segments"] for r in ok]), np.log([r[key] for r in ok])
        return float(np.polyfit(x, y, 1)[0])
    return {"by_segments": rows, "quasi_static_exponent": exponent("quasi_static_revolution_s"),
            "time_domain_exponent": exponent("time_domain_revolution_s"),
            "time_domain_maps_exponent": exponent("time_domain_maps_revolution_s"),
            "time_domain_sweeps_exponent": exponent("time_domain_sweeps_revolution_s"),
            "by_revolutions": revs, **affine(revs)}


def affine(revs):
    """Wall time = set-up + per-revolution cost x revolutions (least squares), and the exponent of
    the marching part alone (wall - set-up) against revolutions."""
    r = np.array([x["revolutions"] for x in revs], float)
    w = np.array([x["wall_s"] for x in revs], float)
    if len(r) < 2:
        return {}
    per_rev, setup = np.polyfit(r, w, 1)
    march = w - setup
    ok = march > 0
    expo = float(np.polyfit(np.log(r[ok]), np.log(march[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")
    return {"setup_s": float(setup), "per_revolution_s": float(per_rev), "marching_exponent": expo}
