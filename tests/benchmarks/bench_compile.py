"""The first run's compilation: the transfer-matrix kernels a default run needs, compiled from an
empty numba cache, whole and kernel by kernel.

    python -m tests.benchmarks.bench_compile [--scenario crank_rocker_373rpm] [--top 15]

Runs ``python -m cosim.kernel_warmup`` (what a first ``cosim run`` starts beside itself: a few
macro steps of a prescribed run with the compiled backend) in a fresh process whose
``NUMBA_CACHE_DIR`` is an empty folder, and reports its wall time and, from numba's compile
events, each kernel's own compile time (its compile time less that of the kernels compiled
while it compiled). The goal of issue 33 item 7: at most 20 s on the 2-core machine.

Not a test: the numbers depend on the machine and its load.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent

#: The child: numba's compile events around the warm-up, written as JSON to argv[2].
CHILD = r"""
import json, sys, time
from numba.core import event
own, stack = {}, []
class Listener(event.Listener):
    def on_start(self, ev):
        stack.append([ev.data["dispatcher"].py_func.__qualname__, time.perf_counter(), 0.0])
    def on_end(self, ev):
        name, t0, children = stack.pop()
        total = time.perf_counter() - t0
        own[name] = own.get(name, 0.0) + total - children
        if stack:
            stack[-1][2] += total
event.register("numba:compile", Listener())
from cosim.kernel_warmup import main
main([sys.argv[1]])
json.dump(own, open(sys.argv[2], "w"))
"""


def scenario_file(name: str, folder: Path) -> Path:
    """The resolved scenario file a first run would hand its warm-up (a one-line ``[input]``)."""
    path = folder / "scenario.toml"
    path.write_text((ROOT / "scenarios" / f"{name}.toml").read_text())
    return path


def compile_once(name: str) -> tuple[float, dict]:
    """``(wall [s], {kernel: own compile time [s]})`` of one warm-up on an empty cache."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "cache").mkdir()
        env = dict(os.environ, PYTHONPATH=str(ROOT), NUMBA_CACHE_DIR=str(folder / "cache"))
        events = folder / "events.json"
        tic = time.perf_counter()
        subprocess.run([sys.executable, "-c", CHILD, str(scenario_file(name, folder)), str(events)], env=env,
                       check=True, cwd=ROOT)
        return time.perf_counter() - tic, json.loads(events.read_text())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crank_rocker_373rpm", help="a shipped scenario's name")
    p.add_argument("--top", type=int, default=15, help="kernels listed, longest first")
    args = p.parse_args(argv)
    wall, own = compile_once(args.scenario)
    print(f"warm-up on an empty cache: {wall:.1f} s whole process, {sum(own.values()):.1f} s compiling "
          f"({len(own)} kernels)")
    for name, seconds in sorted(own.items(), key=lambda kv: -kv[1])[:args.top]:
        print(f"  {seconds:6.2f} s  {name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
