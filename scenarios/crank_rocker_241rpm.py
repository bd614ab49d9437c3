"""FE crank-rocker rig (7/10/12/11 in aluminium) at 241 rpm, gauged coupler and rocker.

Runs the scenario through every engine, like `cosim run crank_rocker_241rpm` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("crank_rocker_241rpm"))
