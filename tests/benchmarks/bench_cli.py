"""Time to an answer on the command line: whole ``cosim`` processes, warm, median of N.

    python -m tests.benchmarks.bench_cli [--repeat 5] [--skip-exudyn]

Each command runs N times in a fresh process (the wall time of the whole process, as a user
waits for it: interpreter start, imports, the run, the files; for a run also the time until its
table is printed, the answer); the first run of each command is not counted, so numba's kernel cache, the page cache and ``__pycache__`` are warm. The goals of
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


def wall_time_s(args: list, out: Path) -> tuple:
    """``(whole process, answer)`` wall times [s] of one ``python -m cosim ARGS`` process (run
    folders under ``out``): the answer is the first line of a run's table on stdout (None for the
    other commands), printed before the run's parquet copy and figures."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    extra = ["--out", str(out / f"run-{time.monotonic_ns()}")] if args[0] == "run" else []
    answer = None
    tic = time.perf_counter()
    with subprocess.Popen([sys.executable, "-m", "cosim", *args, *extra], cwd=out, env=env, text=True,
                          stdout=subprocess.PIPE, stderr=subprocess.DEVNULL) as proc:
        for line in proc.stdout:
            if answer is None and args[0] == "run" and line.startswith("scenario "):
                answer = time.perf_counter() - tic
    if proc.returncode != 0:
        raise RuntimeError(f"cosim {' '.join(args)} exited with {proc.returncode}")
    return time.perf_counter() - tic, answer


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
            runs = [wall_time_s(command, Path(tmp)) for _ in range(args.repeat)]
            times = [whole for whole, _ in runs]
            answers = [a for _, a in runs if a is not None]
            answer = f"; answer (table printed) {statistics.median(answers):.2f} s" if answers else ""
            print(f"{statistics.median(times):6.2f} s  (min {min(times):.2f}, max {max(times):.2f}{answer})  {label}",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
