"""``cosim identify``: calibrate declared unknowns against records at some speeds, predict
held-out ones.

Owns: the identify command's use of its options (``--sigma``, ``--starts``, the scenario lists).
Boundaries: the identification itself is :mod:`cosim.identify`.
"""
from __future__ import annotations

from ..cli import quiet
from ..identify import identify
from ..report import identification_table
from . import options


def main(args) -> int:
    """``cosim identify``: its options read and checked, the identification run
    (:func:`cosim.identify.identify`), its table and where the results went printed."""
    validation = [s.strip() for s in args.validate.split(",") if s.strip()]
    names = [s.strip() for s in args.parameters.split(",") if s.strip()] if args.parameters else None
    if args.starts < 1:
        raise ValueError(f"--starts must be at least 1, got {args.starts}")
    max_hours = options.max_hours(args)
    rel, absolute = parse_sigma(args.sigma)
    folder, result = identify(args.scenarios, validation, names, args.records, args.out, starts=args.starts,
                              workers=args.workers, scheduler=args.scheduler, sigma_relative=rel,
                              sigma_absolute_ue=absolute, progress=not quiet(args), max_hours=max_hours)
    print(identification_table(result))
    print(f"\nwritten to {folder}")
    return 0 if result["status"] == "completed" else 1


def parse_sigma(text: str) -> tuple:
    """``--sigma REL%,ABS``: (relative part, absolute part [microstrain]), both >= 0, not both 0."""
    try:
        rel, absolute = (x.strip() for x in str(text).split(","))
        rel = float(rel.rstrip("%")) / (100.0 if rel.endswith("%") else 1.0)
        absolute = float(absolute)
        if rel < 0 or absolute < 0 or rel + absolute <= 0:
            raise ValueError
    except ValueError:
        raise ValueError(f"--sigma {text!r}: write the relative and absolute parts, e.g. 10%,5") from None
    return rel, absolute
