"""Side-by-side benchmark (issues 10, 15): TMM vs exudyn vs MuJoCo at matched accuracy, the TMM's
quasi-static revolution, per-step floor, speed sweep and scaling, and the bench's own cost. A
script, not a test (timings are not asserted).

Rigs (prescribed crank): the Alexander-Lawrence four-bar at 400 rpm, the FE crank-rocker (rigid
crank) at 95, 241 and 373 rpm, and the illustrative Watt II six-bar at 600 rpm, a mechanism no
source tests (all three engines run it). Per rig and engine (bench_accuracy, bench_timing):

* the converged answer (steady peak-to-peak of every gauge's bending strain) and the cheapest
  setting of a grid around the scenario's default within ``--tol`` of it;
* each chosen setting's (and converged answer's) p-p difference from exudyn's converged answer;
* at the chosen settings, timed in turn in fresh processes (``--repeats`` rounds): first call
  (imports, numba cache load), set-up (model building; TMM: factorization of a revolution),
  marching per simulated second, time to the steady state, peak memory; their ratios to the
  TMM's; and the TMM's periodic steady-state solve (capped at ``--periodic-cap`` s).

Other parts (bench_parts): ``quasi_static`` (360 positions, 8 segments per link, beam-column,
compiled vs numpy), ``floor`` (compiled march per step vs the 3-5 us floor), ``scaling`` (4-512
segments per link), ``overhead`` (the co-simulation bench), ``sweep`` (81 points, 100-500 rpm,
stopped at ``--sweep-cap`` s). Results go to ``logs/benchmarks/bench-<timestamp>.json``, each
part written as soon as it is done; ``bench_table`` prints its tables (and writes docs/benchmarks.md's).

    python -m tests.benchmarks.bench [--rigs a,b] [--engines tmm,exudyn,mujoco] [--parts engines,...]
                                     [--quick] [--repeats 5] [--budget 55] [--estimate] [--tiny]
                                     [--run-cap 600] [--periodic-cap 60] [--sweep-cap 300]
                                     [--tmm-grid 4,8,16:1,0.5,0.25] [--tmm-reference 16:0.25]

Bounding the run: ``--quick`` (3 grid settings per engine, 3 timing rounds), ``--repeats``, the
caps (each accuracy run, each periodic solve, the sweep: a capped item is reported as "not finished
in X s"), and ``--budget`` (parts and rigs not started within it are recorded as not run).
``--estimate`` runs each rig and engine once at its default setting and its converged setting
(about 2 min) and prints how long the run with the same options would take here (bench_estimate).
"""
from __future__ import annotations

import argparse
import os
import platform
import time
from pathlib import Path

import numpy as np

from . import bench_timing
from .bench_accuracy import accuracy_runs, at_least_as_fine, cheapest_setting, choose, grid_for, vs_exudyn
from .bench_timing import fresh, ratios, time_chosen

__all__ = ["main", "cheapest_setting", "at_least_as_fine"]

RIGS = ("alexander_lawrence_400rpm", "crank_rocker_95rpm", "crank_rocker_241rpm", "crank_rocker_373rpm",
        "watt_sixbar_600rpm")
ENGINES = ("tmm", "exudyn", "mujoco")
PARTS = ("engines", "quasi_static", "floor", "scaling", "overhead", "sweep")
# The test suite's run: one cheap setting per engine, and a coarse converged answer.
TINY = {"tmm": [{"segments": 2, "step": "4 deg"}], "exudyn": [{"elements": 2, "step": "0.5 deg"}],
        "mujoco": [{"step": "1 deg"}]}
TINY_REFERENCE = {"tmm": {"segments": 4, "step": "2 deg"}, "exudyn": {"elements": 4, "step": "0.25 deg"},
                  "mujoco": {"step": "0.5 deg"}}


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", default=",".join(RIGS))
    ap.add_argument("--engines", default=",".join(ENGINES))
    ap.add_argument("--parts", default=",".join(PARTS), help=f"comma-separated, from {', '.join(PARTS)}")
    ap.add_argument("--repeats", type=int, help="timing rounds per rig (default 5; --quick: 3)")
    ap.add_argument("--quick", action="store_true", help="the default and its coarser neighbours only, 3 rounds")
    ap.add_argument("--revolutions", type=float, default=3.0, help="revolutions per timed run")
    ap.add_argument("--max-revolutions", type=float, default=12.0, help="longest accuracy run (until steady)")
    ap.add_argument("--tol", type=float, help="matched accuracy: relative p-p tolerance (default 0.01; --tiny: 1.0, "
                                               "only exercising the pipeline)")
    ap.add_argument("--tmm-grid", help="TMM grid as SEGMENTS:STEPS_DEG, e.g. '4,8,16:1,0.5,0.25'")
    ap.add_argument("--tmm-reference", help="TMM converged setting as SEGMENTS:STEP_DEG, e.g. '16:0.25'")
    ap.add_argument("--run-cap", type=float, default=600.0, help="cap on each accuracy run [s] (checked every "
                                                                  "revolution)")
    ap.add_argument("--periodic-cap", type=float, default=60.0, help="cap on each TMM periodic solve [s]; 0 skips")
    ap.add_argument("--sweep-cap", type=float, default=300.0, help="cap on the 81-point sweep [s]")
    ap.add_argument("--sweep-workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--budget", type=float, help="wall-time budget [min]: parts not started within it are skipped "
                                                 "(the sweep's cap shrinks to what is left)")
    ap.add_argument("--estimate", action="store_true", help="probe each rig and engine, print the full run's time")
    ap.add_argument("--tiny", action="store_true", help="one cheap setting per engine (the test suite's run)")
    ap.add_argument("--out", type=Path, help="output file (default logs/benchmarks/bench-<timestamp>.json)")
    args = ap.parse_args(argv)
    args.rig_list = [r for r in args.rigs.split(",") if r]
    args.engine_list = [e for e in args.engines.split(",") if e]
    from cosim.scenario import scenario_names
    known = set(scenario_names())
    for rig in args.rig_list:
        if rig not in known:
            ap.error(f"--rigs: unknown scenario {rig!r} (known: {', '.join(sorted(known))})")
    for engine in args.engine_list:
        if engine not in ENGINES:
            ap.error(f"--engines: unknown engine {engine!r} (known: {', '.join(ENGINES)})")
    if not args.rig_list or not args.engine_list:
        ap.error(f"--rigs and --engines need at least one name each, got {args.rigs!r} and {args.engines!r}")
    if args.tol is not None and not (np.isfinite(args.tol) and args.tol > 0):
        ap.error(f"--tol must be a positive number, got {args.tol!r}")
    args.part_set = set(p for p in args.parts.split(",") if p)
    if not args.part_set or not args.part_set <= set(PARTS):
        ap.error(f"--parts: choose from {', '.join(PARTS)}; got {args.parts!r}")
    if args.repeats is not None and args.repeats < 1:
        ap.error(f"--repeats must be at least 1, got {args.repeats!r}")
    for name in ("revolutions", "max_revolutions", "sweep_cap", "run_cap"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be positive, got {getattr(args, name)!r}")
    if args.budget is not None and not args.budget > 0:
        ap.error(f"--budget must be positive (minutes), got {args.budget!r}")

    def tmm_settings(text, option):
        try:
            segs, steps = text.split(":")
            out = [{"segments": int(n), "step": f"{float(d):g} deg"} for n in segs.split(",") for d in steps.split(",")]
        except ValueError:
            ap.error(f"{option}: expected SEGMENTS:STEPS_DEG like '4,8:0.5,0.25', got {text!r}")
        if any(o["segments"] < 1 or float(o["step"].split()[0]) <= 0 for o in out):
            ap.error(f"{option}: segments and steps must be positive, got {text!r}")
        return out
    args.tmm_grid_list = tmm_settings(args.tmm_grid, "--tmm-grid") if args.tmm_grid else None
    args.tmm_reference_setting = tmm_settings(args.tmm_reference, "--tmm-reference")[0] if args.tmm_reference else None
    if args.tiny:
        args.revolutions, args.max_revolutions, args.cold_revolutions = 0.3, 0.3, 0.1
    else:
        args.cold_revolutions = 0.5
    args.repeat_count = args.repeats or (1 if args.tiny else 3 if args.quick else 5)
    args.tolerance = args.tol if args.tol is not None else (1.0 if args.tiny else 0.01)
    return args


def grids(args, rig: str, engine: str) -> tuple:
    """(grid, reference) of ``engine`` on ``rig`` under the command-line options."""
    if args.tiny:
        return TINY[engine], TINY_REFERENCE[engine]
    grid, reference = grid_for(rig, engine, args.quick)
    if engine == "tmm":
        grid = args.tmm_grid_list or grid
        reference = args.tmm_reference_setting or reference
    return grid, reference


def rig_block(args, rig: str) -> dict:
    """Matched accuracy, timing, exudyn comparison and ratios of every engine on one rig."""
    from cosim.scenario import load
    sc = load(rig)
    block = {"speed_rpm": abs(sc.drive.speed_rad_s) * 30 / np.pi,
             "rigid_links": [l.name for l in sc.mechanism.links() if l.rigid]}
    for engine in args.engine_list:
        grid, reference = grids(args, rig, engine)
        try:
            runs = fresh(accuracy_runs, rig, engine, grid, reference, args.max_revolutions, args.run_cap)
            block[engine] = choose(runs, args.tolerance, args.tiny)
        except Exception as exc:
            block[engine] = {"error": f"{type(exc).__name__}: {exc}", "chosen": None}
    chosen = {e: block[e]["chosen"] for e in args.engine_list if block[e].get("chosen")}
    timing = time_chosen(rig, chosen, args.repeat_count, args.revolutions, args.cold_revolutions,
                         0 if args.tiny else args.periodic_cap)
    for engine, row in timing.items():
        block[engine]["chosen"].update(row)
    block["vs_exudyn"] = vs_exudyn(block)
    block["ratios_vs_tmm"] = ratios(timing)
    return block


def main(argv=None) -> dict:
    args = parse_args(argv)
    bench_timing.FRESH = not args.tiny
    if args.estimate:
        from .bench_estimate import estimate
        return estimate(args)
    start = time.perf_counter()
    result = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform(),
                          "load_average_at_start": list(os.getloadavg())},
              "tiny": args.tiny, "quick": args.quick, "revolutions": args.revolutions,
              "max_revolutions": args.max_revolutions, "repeats": args.repeat_count, "tol": args.tolerance,
              "status": "incomplete", "elapsed_s": {}, "rigs": {}}
    from cosim.runlog import LOG_ROOT, write_json
    target = args.out or (LOG_ROOT / "benchmarks" / f"bench-{time.strftime('%Y%m%d-%H%M%S')}.json")
    target.parent.mkdir(parents=True, exist_ok=True)

    def left_s():
        return float("inf") if args.budget is None else 60 * args.budget - (time.perf_counter() - start)

    def part(key, fn):
        # Every part is written as soon as it is done; a failing part is recorded, not fatal.
        if left_s() <= 0:
            return {"error": f"not run: the --budget of {args.budget:g} min was spent"}
        tic = time.perf_counter()
        try:
            return fn()
        except Exception as exc:
            return {"error": f"{type(exc).__name__}: {exc}"}
        finally:
            result["elapsed_s"][key] = time.perf_counter() - tic
            write_json(target, result)

    tiny = args.tiny
    for rig in (args.rig_list if "engines" in args.part_set else []):
        result["rigs"][rig] = part(f"engines:{rig}", lambda: rig_block(args, rig))
        write_json(target, result)
    from . import bench_parts as bp
    # The floor is measured on the FE rig at 241 rpm (factorization_benchmark): also at its chosen TMM setting.
    fe = result["rigs"].get("crank_rocker_241rpm") or {}
    fe_tmm = ((fe.get("tmm") or {}).get("chosen") or {}).get("setting")
    if "quasi_static" in args.part_set:
        result["quasi_static"] = part("quasi_static", lambda: fresh(bp.quasi_static, 4 if tiny else 8,
                                                                    1 if tiny else 7))
    if "floor" in args.part_set:
        settings = [(4, 4.0)] if tiny else [(8, 0.5)]
        if fe_tmm and fe_tmm["step"].endswith(" deg"):
            chosen = (fe_tmm["segments"], float(fe_tmm["step"].split()[0]))
            settings += [chosen] if chosen not in settings else []
        result["floor"] = part("floor", lambda: fresh(bp.floor, settings, 1 if tiny else 3))
    if "scaling" in args.part_set:
        result["tmm_scaling"] = part("scaling", lambda: fresh(bp.tmm_scaling, args.rig_list[-1] if tiny else
                                                              "crank_rocker_241rpm", (4, 8) if tiny else
                                                              (4, 8, 16, 32, 64, 128, 256, 512),
                                                              (1, 2) if tiny else (1, 2, 4, 8, 16), tiny))
    if "overhead" in args.part_set:
        result["bench_overhead"] = part("overhead", lambda: fresh(bp.bench_overhead, args.rig_list[-1] if tiny else
                                                                  "crank_rocker_241rpm", (1,) if tiny else (1, 4, 16),
                                                                  0.2 if tiny else 30.0, 2 if tiny else
                                                                  bp.OVERHEAD_PAIRS))
    if "sweep" in args.part_set:
        cap = min(8.0 if tiny else args.sweep_cap, max(left_s(), 1.0))
        result["sweep"] = part("sweep", lambda: bp.sweep_capped(cap, args.sweep_workers, 2 if tiny else 8,
                                                                "100:500:400" if tiny else "100:500:5"))
    result["elapsed_s"]["total"] = time.perf_counter() - start
    result["machine"]["load_average_at_end"] = list(os.getloadavg())
    result["status"] = "completed"
    write_json(target, result)
    print(f"written to {target}")
    return result


if __name__ == "__main__":
    main()
