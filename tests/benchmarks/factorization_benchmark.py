"""Benchmark (not a test): the compiled factorization (tmm_core.compiled.structure) against the numpy
reference, side by side in one process, and the compiled march's cost per step (issue 15).

On the FE crank-rocker at 241 rpm (rigid crank, rotating-frame terms):

* one quasi-static revolution: 360 positions, beam-column (``quasi_static``);
* the time domain's per-configuration factorization with its load-to-response maps
  (``TimeDomain.configurations``, 360 configurations);
* the compiled march per step on the cached maps of one revolution (``March.step_many``), at
  8 segments per link and 0.25 deg, and 16 segments per link and 0.0625 deg (the FE rig's matched
  accuracy), against the floor the issue estimates (3-5 us per step).

The numpy and compiled calls alternate and each figure is the minimum (and median) of the
repeats, so the ratios hold on a shared, loaded machine. The first compiled call of a fresh
process loads the kernels from numba's disk cache (or compiles them) and is reported apart.
Writes ``logs/benchmarks/factorization-<timestamp>.json``.

Run: ``python -m tests.benchmarks.factorization_benchmark [--segments 8] [--repeats 7]``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def side_by_side(segments: int, repeats: int) -> dict:
    from cosim.scenario import load
    from tmm_core import TimeDomain, quasi_static
    sc = load("crank_rocker_241rpm").with_overrides({"solver.tmm.segments": segments})
    s = sc.tmm
    mech = sc.mechanism
    th = np.radians(np.arange(360.0))
    w = sc.drive.speed_rad_s
    tds = {c: TimeDomain(mech, integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                         axial_force=s.axial_force, backend="compiled" if c else "numpy") for c in (False, True)}
    dt = np.radians(1.0) / abs(w)

    def qs(compiled):
        return lambda: quasi_static(mech, th, w, beam_column=True, coupling=s.coupling, gravity=sc.gravity,
                                    gauges=sc.gauges, backend="compiled" if compiled else "numpy")

    def cfg(compiled):
        return lambda: tds[compiled].configurations(th, np.full(360, w), np.zeros(360), dt)

    first = _timed(lambda: (qs(True)(), cfg(True)()))
    runs = {"quasi_static_numpy": qs(False), "quasi_static_compiled": qs(True),
            "configurations_numpy": cfg(False), "configurations_compiled": cfg(True)}
    times = {k: [] for k in runs}
    for _ in range(repeats):
        for k, fn in runs.items():
            times[k].append(_timed(fn))
    out = {"segments_per_link": segments, "positions": 360, "first_compiled_calls_s": first}
    for k, v in times.items():
        out[k] = {"min_s": min(v), "median_s": statistics.median(v)}
    for what in ("quasi_static", "configurations"):
        out[f"{what}_ratio"] = {"min": min(times[f"{what}_numpy"]) / min(times[f"{what}_compiled"]),
                                "median": statistics.median(times[f"{what}_numpy"])
                                / statistics.median(times[f"{what}_compiled"])}
    iterations = qs(True)().solution.iterations
    out["quasi_static_solves"] = iterations
    return out


def per_step(segments: int, step_deg: float, repeats: int) -> dict:
    """Compiled march per step over one revolution of cached maps (set-up excluded)."""
    from cosim.scenario import load
    from tmm_core import TimeDomain
    sc = load("crank_rocker_241rpm").with_overrides({"solver.tmm.segments": segments})
    s = sc.tmm
    td = TimeDomain(sc.mechanism, integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                    axial_force=s.axial_force)
    w = sc.drive.speed_rad_s
    N = int(round(360.0 / step_deg))
    th = np.radians(np.arange(N) * step_deg)
    dt = np.radians(step_deg) / abs(w)
    t = time.perf_counter()
    cfg = td.configurations(th, np.full(N, w), np.zeros(N), dt)
    setup = time.perf_counter() - t
    best = np.inf
    for _ in range(repeats):
        march = td.begin(dt, th[0], w, 0.0, start="quasi_static")
        idx = np.arange(1, 2 * N + 1) % N
        best = min(best, _timed(lambda: march.step_many(cfg, idx, record_z=False)) / len(idx))
    return {"segments_per_link": segments, "step_deg": step_deg, "n_dof": td.n_dof, "configurations": N,
            "setup_s": setup, "setup_per_configuration_s": setup / N, "per_step_s": best,
            "floor_per_step_s": [3e-6, 5e-6], "ratio_to_floor": [best / 5e-6, best / 3e-6]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--no-steps", action="store_true", help="skip the per-step march measurement")
    args = ap.parse_args(argv)
    result = {"benchmark": "compiled factorization vs numpy, FE crank-rocker 241 rpm",
              "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform(),
                          "load_average": os.getloadavg()},
              "side_by_side": side_by_side(args.segments, args.repeats)}
    sb = result["side_by_side"]
    print(f"FE rig 241 rpm, {args.segments} segments per link, 360 positions (first compiled calls "
          f"{sb['first_compiled_calls_s']:.2f} s)")
    for what in ("quasi_static", "configurations"):
        a, b = sb[f"{what}_numpy"], sb[f"{what}_compiled"]
        print(f"  {what:15s} numpy {a['min_s'] * 1e3:8.1f} ms (median {a['median_s'] * 1e3:8.1f})   compiled "
              f"{b['min_s'] * 1e3:8.1f} ms (median {b['median_s'] * 1e3:8.1f})   ratio {sb[what + '_ratio']['min']:.1f} "
              f"(median {sb[what + '_ratio']['median']:.1f})")
    if not args.no_steps:
        result["per_step"] = [per_step(8, 0.25, max(2, args.repeats // 2)), per_step(16, 0.0625, 2)]
        for p in result["per_step"]:
            print(f"  march {p['segments_per_link']:2d} segments/link, {p['step_deg']} deg: {p['per_step_s'] * 1e6:6.1f} us per "
                  f"step ({p['ratio_to_floor'][0]:.1f}-{p['ratio_to_floor'][1]:.1f}x the 3-5 us floor); set-up "
                  f"{p['setup_s']:.2f} s for {p['configurations']} configurations "
                  f"({p['setup_per_configuration_s'] * 1e6:.0f} us each)")
    from cosim.runlog import LOG_ROOT
    out = LOG_ROOT / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    target = out / f"factorization-{time.strftime('%Y%m%d-%H%M%S')}.json"
    target.write_text(json.dumps(result, indent=2))
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
