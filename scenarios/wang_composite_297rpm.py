"""Wang's +/-45 deg graphite-epoxy four-bar (12/2.5/9/9 in, viscoelastic links) at 297 rpm.

Runs the scenario through every engine, like `cosim run wang_composite_297rpm` (same options; --help lists them).
"""
import sys

from cosim.commands.run import run_main

if __name__ == "__main__":
    sys.exit(run_main("wang_composite_297rpm"))
