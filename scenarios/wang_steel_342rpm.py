"""Wang's steel four-bar (16.12/2.25/12/12 in, 0.75 x 0.062 in steel) at 342 rpm.

Runs the scenario through every engine, like `cosim run wang_steel_342rpm` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("wang_steel_342rpm"))
