"""FE crank-rocker at 373 rpm with an elastic crank 100x stiffer than the strip (variant: the crank's own modes).

Runs the scenario through every engine, like `cosim run crank_rocker_373rpm_flexible_crank` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("crank_rocker_373rpm_flexible_crank"))
