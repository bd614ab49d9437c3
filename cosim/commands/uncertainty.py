"""``cosim uncertainty``: the band of predicted strains over the scenario's declared unknowns.

Owns: the uncertainty command's use of its options. Boundaries: the study itself is
:mod:`cosim.uncertainty`.
"""
from __future__ import annotations

import sys

from ..cli import quiet
from ..report import uncertainty_table
from ..uncertainty import run_uncertainty
from . import options


def main(args) -> int:
    """``cosim uncertainty`` with its parsed options."""
    options.positive(args, ("--samples", "--trajectories", "--workers"))
    options.refuse_structure(args.scenario, "uncertainty")
    viewer, save = options.viewer(args)
    folder, summary = run_uncertainty(args.scenario, args.samples, args.seed, args.workers, args.scheduler,
                                      args.out, record=viewer is not None, progress=not quiet(args),
                                      records_dir=args.records, trajectories=args.trajectories,
                                      max_hours=options.max_hours(args))
    out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
    print(uncertainty_table(summary), file=out)
    print(f"\nwritten to {folder}", file=out)
    options.show(folder / "uncertainty.rrd", viewer, save)
    return options.exit_code(summary["status"])
