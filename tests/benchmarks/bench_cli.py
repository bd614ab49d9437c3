"""Time to an answer on the command line: whole ``cosim`` processes, warm, median of N.

    python -m tests.benchmarks.bench_cli [--repeat 5] [--skip-exudyn]

Each command runs N times in a fresh process (the wall time of the whole process, as a user
waits for it: interpreter start, imports, the run, the files); the first run of each command is
not counted, so numba's kernel cache, the page cache and ``__pycache__`` are warm. The goals of
issue 35 item 6: ``cosim --help`` and ``cosim list`` at most 0.5 s, the TMM-only run of the main
rig at most 1.2 s; the exudyn-only run of the same rig is timed beside it, in the same run, so the
ratio of the two is measured under the same load.

Not a test: the numbers depend on the machine and its load.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
RUN = ["run", "crank_rocker_373rpm", "--no-record", "-q"]
COMMANDS = {
    "cosim --help": ["--help"],
    "cosim list": ["list"],
    "cosim run crank_rocker_373rpm --engines tmm --no-record": RUN + ["--engines", "tmm"],
    "cosim run crank_rocker_373rpm --engines exudyn --no-record": RUN + ["--engines", "exudyn"],
}


def wall_time_s(args: list, out: Path) -> float:
    """Wall time [s] of one ``python -m cosim ARGS`` process (run folders under ``out``)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    extra = ["--out", str(out / f"run-{time.monotonic_ns()}")] if args[0] == "run" else []
    tic = time.perf_counter()
    subprocess.run([sys.executable, "-m", "cosim", *args, *extra], cwd=out, env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - tic


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=5, help="timed runs per command (median reported)")
    p.add_argument("--skip-exudyn", action="store_true", help="leave out the exudyn-only run")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        for label, command in COMMANDS.items():
            if args.skip_exudyn and "exudyn" in command:
                continue
            wall_time_s(command, Path(tmp))                   # warm-up, not counted
            times = [wall_time_s(command, Path(tmp)) for _ in range(args.repeat)]
            print(f"{statistics.median(times):6.2f} s  (min {min(times):.2f}, max {max(times):.2f})  {label}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
