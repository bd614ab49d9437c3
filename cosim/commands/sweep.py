"""``cosim sweep``: prescribed-speed points of a scenario, their peaks per engine and gauge.

Owns: the sweep command's use of its options. Boundaries: the sweep itself is :mod:`cosim.sweeps`.
"""
from __future__ import annotations

import sys

from ..cli import quiet
from ..report import sweep_table, unsolved_count
from ..sweeps import parse_rpm, run_sweep
from . import options


def main(args) -> int:
    """``cosim sweep`` with its parsed options."""
    options.positive(args, ("--samples", "--trajectories", "--workers"))
    options.refuse_structure(args.scenario, "sweep")
    rpm = parse_rpm(args.rpm)
    options.positive(args, ("--revolutions", "--workers"))
    viewer, save = options.viewer(args)
    folder, summary = run_sweep(args.scenario, rpm, options.engines(args.engines), args.revolutions, args.workers,
                                args.scheduler, args.out, record=viewer is not None, progress=not quiet(args),
                                method=args.method, resonance=args.campbell, records_dir=args.records,
                                model=args.model, max_hours=options.max_hours(args))
    out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
    print(sweep_table(summary), file=out)
    print(f"\nsweep {summary['status']}: {len(summary['points'])} points{unsolved_count(summary)} in "
          f"{summary['wall_time_s']:.1f} s; written to {folder}", file=out)
    options.show(folder / "sweep.rrd", viewer, save)
    return options.exit_code(summary["status"])
