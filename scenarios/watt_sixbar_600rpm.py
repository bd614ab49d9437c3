"""Illustrative Watt II six-bar (aluminium strips, rigid 3 in crank) at 600 rpm, gauged coupler, rocker, link E-F and output.

Runs the scenario through every engine, like `cosim run watt_sixbar_600rpm` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("watt_sixbar_600rpm"))
