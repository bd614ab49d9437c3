"""Alexander-Lawrence aluminium four-bar (4/11/10.5/10 in) at 400 rpm, Shin's example.

Runs the scenario through every engine, like `cosim run alexander_lawrence_400rpm` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("alexander_lawrence_400rpm"))
