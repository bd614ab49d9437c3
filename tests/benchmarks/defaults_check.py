"""Are the shipped scenarios' default engine settings within 1 % of each engine's converged answer?

For every shipped scenario that moves (structures are static) and every engine it runs by default,
the steady-state bending peaks at the scenario's own settings are compared with a run refined
once in every direction (transfer-matrix: twice the segments, half the step; exudyn: twice the
elements, half the step; MuJoCo: half the step). The difference, relative to the refined run's
peak-to-peak, estimates the default's discretisation error; a default run is then a matched-
accuracy comparison. Each engine runs until steady (``cosim.metrics``).

    python -m tests.benchmarks.defaults_check [--scenarios a,b] [--tol 0.01] [--out FILE]

Results go to ``logs/benchmarks/defaults-<timestamp>.json``; exit status 1 if a default misses.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from cosim.engines import make_engine
from cosim.master import run_prescribed
from cosim.metrics import run_change
from tmm_core.revolution import last_revolution
from cosim.runlog import write_json
from cosim.scenario import load, scenario_names


def _refined(sc, engine: str):
    """The scenario refined once for ``engine`` (key paths of its file, cosim.overrides)."""
    if engine == "tmm":
        over = {"solver.tmm.segments": 2 * sc.tmm.segments}
        for name, link in sc.raw.get("links", {}).items():
            if isinstance(link, dict) and "segments" in link:
                over[f"links.{name}.segments"] = 2 * int(link["segments"]["value"] if isinstance(link["segments"], dict)
                                                          else link["segments"])
        over["solver.tmm.step"] = f"{0.5 * sc.engine_step_s('tmm')!r} s"
    elif engine == "exudyn":
        over = {"solver.exudyn.elements": 2 * sc.exudyn.elements, "solver.exudyn.step": f"{0.5 * sc.exudyn.step_s!r} s"}
    else:
        over = {"solver.mujoco.step": f"{0.5 * sc.mujoco.step_s!r} s"}
    return sc.with_overrides(over)


def _peaks(run) -> dict:
    m = last_revolution(run.crank_angle)
    return {g: (float(b[m].max() * 1e6), float(b[m].min() * 1e6)) for g, (b, _) in run.gauges.items()}


def _run(sc, engine: str):
    """Until steady; the transfer-matrix model directly, with a map budget large enough for the
    refined mesh (4 GB: beyond the engine's 1 GB its steps fall back to the slow Riccati sweeps)."""
    if engine != "tmm":
        return run_prescribed(make_engine(engine), sc)
    from tmm_core import CrankMotion, TimeDomain
    s = sc.tmm
    td = TimeDomain(sc.mechanism, integrator=s.integrator, coupling=s.coupling, beam_column=s.beam_column,
                    gravity=sc.gravity, gauges=sc.gauges, axial_force=s.axial_force, max_map_bytes=4e9)
    crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"),
                                       revolutions=sc.output.max_revolutions, start_angle=sc.drive.start_angle_rad)
    # Three revolutions at least: the core may call a run steady after two (revolutions 1 and 2
    # agree), whose samples span one step less than two revolutions, too short for the bench's
    # revolution-to-revolution check (tmm_core.revolution.revolution_change) that the caller applies.
    r = td.run(crank, start=s.start, steady_tol=sc.output.steady_tolerance, record_displacements=False,
               min_revolutions=3)
    return type("Run", (), {"crank_angle": r.crank_angle, "gauges": r.gauges, "drive_torque": r.drive_torque,
                            "t": r.t})()


def check(name: str, engine: str) -> dict:
    """Default against refined for one scenario and engine; a default run that does not reach
    its steady state has no converged answer to compare (``steady`` False, ``error`` NaN)."""
    sc = load(name)
    tic = time.perf_counter()
    run = _run(sc, engine)
    wall = time.perf_counter() - tic
    if not run_change(run) < sc.output.steady_tolerance:
        return {"scenario": name, "engine": engine, "steady": False, "error": float("nan"), "wall_time_s": wall}
    default = _peaks(run)
    refined = _peaks(_run(_refined(sc, engine), engine))
    worst = 0.0
    for g, (hi, lo) in refined.items():
        span = max(hi - lo, 1e-12)
        worst = max(worst, abs(default[g][0] - hi) / span, abs(default[g][1] - lo) / span)
    return {"scenario": name, "engine": engine, "steady": True, "error": worst, "wall_time_s": wall,
            "default": default, "refined": refined}


def moving_scenarios() -> list:
    return [n for n in scenario_names() if load(n).raw.get("linkage", {}).get("type") != "structure"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", help="comma-separated names (default: every moving shipped scenario)")
    ap.add_argument("--tol", type=float, default=0.01, help="largest peak error relative to the peak-to-peak")
    ap.add_argument("--out", type=Path, help="output file")
    args = ap.parse_args(argv)
    names = args.scenarios.split(",") if args.scenarios else moving_scenarios()
    rows = []
    for name in names:
        for engine in load(name).output.engines:
            row = check(name, engine)
            rows.append(row)
            flag = "NOT STEADY (no converged answer)" if not row["steady"] else \
                "ok" if row["error"] < args.tol else "MISSES"
            print(f"{name:38s} {engine:7s} default vs refined {100 * row['error']:6.2f} % of p-p  "
                  f"({row['wall_time_s']:.1f} s)  {flag}", flush=True)
    out = args.out or Path("logs") / "benchmarks" / f"defaults-{time.strftime('%Y%m%d-%H%M%S')}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json(out, {"tol": args.tol, "rows": rows})
    print(f"written to {out}")
    return 0 if all(r["error"] < args.tol for r in rows if r["steady"]) else 1


if __name__ == "__main__":
    sys.exit(main())
