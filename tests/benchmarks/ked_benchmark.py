"""Benchmark of the transfer-matrix kineto-elastodynamics (run on purpose, not part of the tests).

Measures, on the Alexander-Lawrence four-bar at 400 rpm:
* one quasi-static revolution, 360 positions, 8 segments per link (linear and beam-column);
* a time-domain run to the steady state, 8 segments per link, 1 deg step (generalized-alpha,
  3 % damping, quasi-static start, steady tolerance 1e-3);
* how both scale with the segment count (4 to 512 per link): quasi-static time per position,
  and for the time domain the set-up cost per crank position plus the cost per step.
Medians of repeated runs after a warm-up. Writes ``logs/benchmarks/ked-<timestamp>.json``.

Run: ``python -m tests.benchmarks.ked_benchmark [--quick]``.
"""
from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time

import numpy as np

from cosim.runlog import LOG_ROOT, run_folder, write_json
from cosim.units import INCH, RPM
from scenarios.rigs import alexander_lawrence
from tmm_core import CrankMotion, Gauge, quasi_static
from tmm_core.transient import TimeDomain

W = -400 * RPM
GAUGES = [Gauge("rocker_mid", "rocker", 10.5 * INCH / 2), Gauge("coupler_mid", "coupler", 5.5 * INCH)]


def median_time(fn, repeats: int) -> float:
    fn()   # warm-up
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def quasi_static_revolution(n: int, positions: int = 360, beam_column: bool = False):
    mech = alexander_lawrence(n)
    th = np.radians(np.linspace(0.0, 360.0, positions, endpoint=False))
    return lambda: quasi_static(mech, th, W, beam_column=beam_column, gauges=GAUGES)


def steady_state_run(n: int, step_deg: float = 1.0):
    mech = alexander_lawrence(n, damping=0.03)
    crank = CrankMotion.constant_speed(W, step_deg=step_deg, revolutions=60)

    def run():
        r = TimeDomain(mech, integrator="generalized_alpha", gauges=GAUGES).run(crank, start="quasi_static",
                                                                              steady_tol=1e-3)
        return r
    return run


def time_domain_costs(n: int, positions: int = 36):
    """Set-up cost per crank position (factorizations and load-to-response maps) and marching
    cost per step, from runs of one and of three revolutions with ``positions`` steps each."""
    mech = alexander_lawrence(n, damping=0.03)
    td = TimeDomain(mech, integrator="generalized_alpha", gauges=GAUGES)
    times = []
    for revs in (1, 3):
        crank = CrankMotion.constant_speed(W, step_deg=360.0 / positions, revolutions=revs)
        t = time.perf_counter()
        r = td.run(crank, start="rest")
        times.append(time.perf_counter() - t)
    march = max(times[1] - times[0], 0.0) / (2 * positions)
    setup = max(times[0] - march * positions, 0.0) / positions
    return setup, march, bool(r.info["maps"])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats and segment counts (smoke run)")
    args = parser.parse_args(argv)
    repeats = 1 if args.quick else 5
    counts = (4, 8) if args.quick else (4, 8, 16, 32, 64, 128, 256, 512)
    result = {"machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine(),
                          "cpus": __import__("os").cpu_count()}}

    qs_lin = median_time(quasi_static_revolution(8), repeats)
    qs_bc = median_time(quasi_static_revolution(8, beam_column=True), repeats)
    run = steady_state_run(8)
    td_steady = median_time(run, max(1, repeats // 2))
    r = run()
    result["alexander_lawrence_8_segments"] = {
        "quasi_static_revolution_360_positions_s": qs_lin,
        "quasi_static_revolution_360_positions_beam_column_s": qs_bc,
        "time_domain_to_steady_state_1deg_s": td_steady,
        "time_domain_revolutions_to_steady": r.revolutions, "time_domain_cycle_change": r.cycle_change,
        "goals": {"quasi_static_revolution_s": 0.020, "time_domain_steady_s": 0.5}}
    print(f"quasi-static revolution (360 positions, 8 segments/link): {qs_lin * 1e3:.1f} ms linear, "
          f"{qs_bc * 1e3:.1f} ms beam-column   (goal 20 ms)")
    print(f"time domain to steady state (8 segments/link, 1 deg): {td_steady:.2f} s after {r.revolutions:.0f} "
          f"revolutions (goal 0.5 s)")

    scaling = []
    print(f"{'segments':>9s}{'QS per position [ms]':>22s}{'TD set-up per position [ms]':>29s}"
          f"{'TD per step [ms]':>18s}{'maps':>6s}")
    for n in counts:
        positions = 36 if n <= 64 else 8
        qs_pp = median_time(quasi_static_revolution(n, positions), 1 if n > 64 else repeats) / positions
        setup, march, maps = time_domain_costs(n, positions=positions)
        scaling.append({"segments_per_link": n, "quasi_static_per_position_s": qs_pp,
                        "time_domain_setup_per_position_s": setup, "time_domain_per_step_s": march,
                        "dense_maps": maps})
        print(f"{n:9d}{qs_pp * 1e3:22.3f}{setup * 1e3:29.3f}{march * 1e3:18.3f}{'yes' if maps else 'no':>6s}")
    ns = np.array([s["segments_per_link"] for s in scaling], dtype=float)
    for key in ("quasi_static_per_position_s", "time_domain_setup_per_position_s", "time_domain_per_step_s"):
        y = np.array([s[key] for s in scaling])
        big = ns >= 32 if np.sum(ns >= 32) >= 2 else ns > 0
        slope = float(np.polyfit(np.log(ns[big]), np.log(np.maximum(y[big], 1e-9)), 1)[0])
        result.setdefault("scaling_exponent", {})[key] = slope
        print(f"fitted exponent of {key} vs segments (n >= 32): {slope:.2f}")
    result["scaling"] = scaling
    folder = run_folder("benchmarks", LOG_ROOT / "benchmarks")
    path = folder / f"ked-{time.strftime('%Y%m%d-%H%M%S')}.json"
    write_json(path, result)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
