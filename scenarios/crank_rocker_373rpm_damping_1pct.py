"""FE crank-rocker at 373 rpm with 1 % damping (light-damping variant, issue 34).

Runs the scenario through every engine, like `cosim run crank_rocker_373rpm_damping_1pct` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("crank_rocker_373rpm_damping_1pct"))
