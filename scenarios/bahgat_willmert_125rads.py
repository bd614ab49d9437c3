"""Bahgat-Willmert steel four-bar (5/11/10.5/10 in, 0.25 x 1 in) at 125 rad/s, Shin's first comparison.

Runs the scenario through every engine, like `cosim run bahgat_willmert_125rads` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("bahgat_willmert_125rads"))
