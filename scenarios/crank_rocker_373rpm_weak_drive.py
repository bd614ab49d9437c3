"""FE crank-rocker at 373 rpm driven by the thesis's motor and disks alone (variant: a 58 % speed fluctuation).

Runs the scenario through every engine, like `cosim run crank_rocker_373rpm_weak_drive` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("crank_rocker_373rpm_weak_drive"))
