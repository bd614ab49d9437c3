"""How long would ``tests.benchmarks.bench`` take here? (``bench --estimate`` with the same options.)

Each rig and engine runs once at the scenario's default setting in a fresh process (a cold run,
a warm revolution, then a run until steady: ~2 min for the five rigs). Its first-call cost,
set-up, marching per revolution, revolutions to steady and the process start-up then price the
full run's accuracy grid (cost of a setting ~ count x 1/step relative to the default) and its
timing rounds (at the default setting, standing in for the chosen one). The TMM's periodic
solves and the sweep count at their measured cost (low estimate) or their caps (high estimate); the
other parts at their measured cost (PART_SECONDS; every result file records each part's
``elapsed_s``).
"""
from __future__ import annotations

import time

from .bench_accuracy import COUNT, default_setting, run_setting
from .bench_timing import fresh, timed_process

# Measured with `bench --parts <part>` on the 2-core machine, load average 2-3 (2026-11-26) [s];
# the floor with a second, finer TMM setting.
PART_SECONDS = {"quasi_static": 6.0, "floor": 10.0, "scaling": 185.0, "overhead": 60.0}
SWEEP_S = 95.0             # the 81-point sweep on 2 workers, the same day
PERIODIC_S = 5.0           # a TMM periodic solve at the chosen setting (FE rigs, six-bar: 2-4 s)


def probe(rig: str, engine: str, setting: dict, reference: dict, max_revolutions: float,
          cold_revolutions: float) -> dict:
    """Cold run, warm revolution (bench_timing.timed_process) and a run until steady at the default
    ``setting``, and a tenth of a revolution at the ``reference`` (is it still on the fast path?),
    timed [s]."""
    tic = time.perf_counter()
    t = timed_process(rig, engine, setting, 1.0, cold_revolutions)
    s = run_setting(rig, engine, setting, max_revolutions)
    r = run_setting(rig, engine, reference, 0.1)
    return {**t, "march_per_revolution_s": t["march_s"], "revolutions_to_steady": s["revolutions_to_steady"],
            "reference_setup_s": r["setup_s"], "reference_march_per_revolution_s": (r["wall_s"] - r["setup_s"])
            / r["revolutions"], "inner_s": time.perf_counter() - tic}


def _factor(setting: dict, default: dict) -> float:
    """Marching cost of ``setting`` relative to ``default``: count ratio x inverse step ratio."""
    f = float(default["step"].split()[0]) / float(setting["step"].split()[0])
    for key in COUNT.values():
        if key in setting and key in default:
            f *= setting[key] / default[key]
    return f


def estimate(args) -> dict:
    """Probe every rig and engine, print the estimate of the full run with ``args``' options."""
    from .bench import grids
    rows, engines_s, periodic_s, periodic_low = {}, 0.0, 0.0, 0.0
    for rig in (args.rig_list if "engines" in args.part_set else []):
        for engine in args.engine_list:
            d = default_setting(rig, engine)
            grid, reference = grids(args, rig, engine)
            if not reference["step"].endswith(d["step"].split()[1]):
                grid, reference = [d] * len(grid), d         # other units: priced as the default
            tic = time.perf_counter()
            try:
                p = fresh(probe, rig, engine, d, reference, args.max_revolutions, args.cold_revolutions)
            except Exception as exc:
                rows[f"{rig} {engine}"] = {"error": f"{type(exc).__name__}: {exc}"}
                continue
            spawn = max(time.perf_counter() - tic - p["inner_s"], 0.0)
            revs = min(p["revolutions_to_steady"] or args.max_revolutions, args.max_revolutions)
            # The grid is priced from the default's marching cost; the reference at its own, measured:
            # it alone can fall off the fast path (the TMM's load maps grow with 1/step x count^2
            # and are dropped above their memory budget).
            def cost(s):
                setup = p["setup_s"] * (_factor(s, d) if engine == "tmm" else 1.0)
                return min(setup + revs * p["march_per_revolution_s"] * _factor(s, d), args.run_cap)
            ref_cost = min(p["reference_setup_s"] + revs * p["reference_march_per_revolution_s"], args.run_cap)
            accuracy = spawn + p["first_call_s"] + sum(cost(s) for s in grid) + ref_cost
            timing = args.repeat_count * (spawn + p["first_call_s"] + 2 * p["setup_s"]
                                          + (args.cold_revolutions + args.revolutions) * p["march_per_revolution_s"])
            rows[f"{rig} {engine}"] = {"accuracy_s": accuracy, "timing_s": timing, "probe": p, "spawn_s": spawn,
                                       "revolutions_to_steady": revs}
            engines_s += accuracy + timing
            if engine == "tmm" and args.periodic_cap:
                periodic_s += args.periodic_cap
                periodic_low += min(PERIODIC_S, args.periodic_cap)
            print(f"{rig:28s} {engine:7s} accuracy grid {accuracy:6.0f} s  timing {timing:5.0f} s  (default: march "
                  f"{p['march_per_revolution_s']:.3g} s/rev, set-up {p['setup_s']:.3g} s, first call "
                  f"{p['first_call_s']:.2g} s, steady after {revs:g} rev; converged setting: march "
                  f"{p['reference_march_per_revolution_s']:.3g} s/rev)", flush=True)
    other = sum(v for k, v in PART_SECONDS.items() if k in args.part_set)
    sweep = args.sweep_cap if "sweep" in args.part_set else 0.0
    low = engines_s + other + periodic_low + min(SWEEP_S, sweep)
    high = engines_s + other + periodic_s + sweep
    if args.budget is not None:
        high = min(high, 60 * args.budget + 60)     # the budget bounds starts; the last part may overrun
    out = {"engines_s": engines_s, "periodic_solves_up_to_s": periodic_s, "other_parts_s": other,
           "sweep_up_to_s": sweep, "total_low_s": low, "total_high_s": high, "rows": rows}
    print(f"engines {engines_s / 60:.1f} min + TMM periodic solves up to {periodic_s / 60:.1f} min + other parts "
          f"{other / 60:.1f} min + sweep up to {sweep / 60:.1f} min: {low / 60:.0f}-{high / 60:.0f} min in all "
          f"(repeats {args.repeat_count}{', quick grid' if args.quick else ''})")
    return out
