"""Benchmark (not a test): an 81-point periodic-solver sweep of the FE crank-rocker rig, 100-500 rpm.

Goal (issue 9): under 2 s on this machine. Writes logs/benchmarks/sweep-<timestamp>.json (or
``--result``). The sweep's own folder (``--out-dir``, default a temporary one) holds its
summary.json, rewritten after every point, so a run stopped at a time cap still tells how many
points it finished (``tests.benchmarks.bench_parts.sweep_capped``).
Run: python -m tests.benchmarks.sweep_benchmark [--workers 2] [--segments 8] [--rpm 100:500:5] [--model reduced]
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

RPM = "100:500:5"          # 81 points


def sweep(workers: int, segments: int, rpm: str, out_dir: Path, model: str = "full") -> dict:
    """Run the periodic sweep into ``out_dir`` (which must not hold a run) with the TMM ``model``
    ('full' or 'reduced'); wall time [s] and median time per point [s]."""
    from cosim.sweeps import run_sweep
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "rig.toml"
    path.write_text(f'extends = "{SCENARIO_DIR / "crank_rocker_373rpm"}.toml"\n\n[solver.tmm]\n'
                    f'segments = {segments}\n', encoding="utf-8")
    tic = time.perf_counter()
    folder, summary = run_sweep(str(path), rpm, ("tmm",), workers=workers, out=out_dir / "sweep",
                                progress=False, record=False, resonance=False, model=model)
    wall = time.perf_counter() - tic
    per_point = [p["wall_time_s"] for p in summary["points"] if "wall_time_s" in p]
    return {"benchmark": f"periodic sweep, FE crank-rocker, {len(summary['points'])} points {rpm} rpm",
            "model": model,
            "wall_time_s": wall, "goal_s": 2.0, "met": wall < 2.0, "workers": workers, "segments_per_link": segments,
            "rpm": rpm, "points": len(summary["points"]),
            "median_point_s": sorted(per_point)[len(per_point) // 2] if per_point else None,
            "points_without_solution": summary.get("points_without_solution"),
            "machine": {"python": platform.python_version(), "cpus": os.cpu_count(), "platform": platform.platform()}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--segments", type=int, default=8)
    ap.add_argument("--rpm", default=RPM, help="start:stop:step (default: the 81-point sweep)")
    ap.add_argument("--model", choices=("full", "reduced"), default="full", help="the TMM model of the periodic solves")
    ap.add_argument("--out-dir", type=Path, help="folder for the sweep's own results (default: a temporary one)")
    ap.add_argument("--result", type=Path, help="result file (default logs/benchmarks/sweep-<timestamp>.json)")
    args = ap.parse_args(argv)
    if args.out_dir is not None:
        result = sweep(args.workers, args.segments, args.rpm, args.out_dir, args.model)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            result = sweep(args.workers, args.segments, args.rpm, Path(tmp), args.model)
    target = args.result or LOG_ROOT / "benchmarks" / f"sweep-{time.strftime('%Y%m%d-%H%M%S')}.json"
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(json.dumps(result, indent=2))
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
