"""``cosim compare``: the table of a run, sweep or uncertainty folder.

Owns: reading a results folder's summary for the console. Boundaries: the tables are
:mod:`cosim.report`'s.
"""
from __future__ import annotations

from pathlib import Path

from ..report import load_summary, report


def main(args) -> int:
    """``cosim compare``: the folder's own table; a summary that cannot be read or shown is one
    ``error:`` line and exit 2, never a traceback."""
    folder = args.run_dir
    summary = load_summary(folder)          # ValueError / FileNotFoundError name the file
    try:
        text = report(summary)
    except Exception as exc:                # a summary.json edited by hand or from another version
        raise ValueError(f"{Path(folder)}/summary.json: cannot be shown ({type(exc).__name__}: {exc}); it may be "
                         "from another version of the bench or edited by hand") from None
    print(text)
    return 0
