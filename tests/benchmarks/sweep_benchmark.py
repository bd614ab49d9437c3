"""Benchmark (not a test): an 81-point periodic-solver sweep of the FE crank-rocker rig, 100-500 rpm.

Goal (issue 9): under 2 s on this machine. Writes logs/benchmarks/sweep-<timestamp>.json.
Run: python -m tests.benchmarks.sweep_benchmark [--workers 2] [--segments 8]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

from cosim.runlog import LOG_ROOT
from cosim.scenario import SCENARIO_DIR


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--segments", type=int, default=8)
    args = ap.parse_args(argv)
    from cosim.sweep import run_sweep
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "rig.toml"
        path.write_text(f'extends = "{SCENARIO_DIR / "crank_rocker_373rpm"}.toml"\n\n[solver.tmm]\n'
                        f'segments = {args.segments}\n', encoding="utf-8")
        tic = time.perf_counter()
        folder, summary = run_sweep(str(path), "100:500:5", ("tmm",), workers=args.workers, out=Path(tmp) / "out",
                                    progress=False, record=False, resonance=False)
        wall = time.perf_counter() - tic
    per_point = [p["wall_time_s"] for p in summary["points"] if "wall_time_s" in p]
    result = {"benchmark": "periodic sweep, FE crank-rocker, 81 points 100-500 rpm", "wall_time_s": wall,
              "goal_s": 2.0, "met": wall < 2.0, "workers": args.workers, "segments_per_link": args.segments,
              "median_point_s": sorted(per_point)[len(per_point) // 2] if per_point else None,
              "points_without_solution": summary.get("points_without_solution"),
              "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform()}}
    out = LOG_ROOT / "benchmarks"
    out.mkdir(parents=True, exist_ok=True)
    target = out / f"sweep-{time.strftime('%Y%m%d-%H%M%S')}.json"
    target.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
