"""Shin's §8.2 multiloop mechanism (7 steel links, plate, 2 springs, 2 sliders) in motion at 20 rad/s.

Runs the scenario through every engine, like `cosim run shin_multiloop_motion` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("shin_multiloop_motion"))
