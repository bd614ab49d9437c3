"""``cosim run``: a scenario through its engines, or a structure's static analysis; also what
each scenario script calls (``python scenarios/<name>.py`` runs :func:`run_main`).

Owns: the run command's use of its options. Boundaries: the run itself is :mod:`cosim.runs`.
"""
from __future__ import annotations

import logging
import sys

from ..cli import build_parser, quiet, setup_logging
from ..recording.sinks import copy_to_stdout
from ..report import comparison_table, status_notice
from ..runs import RunOptions, run_scenario
from ..scenario import load
from ..structure_scenario import run_static, summary_table
from . import options

log = logging.getLogger("cosim.cli")


def main(args) -> int:
    """``cosim run`` with its parsed options."""
    return run_main(args.scenario, args)


def run_main(scenario: str, args=None) -> int:
    """``cosim run``; a scenario script calls it with ``args=None`` and gets the command line's
    options read from its own ``sys.argv``."""
    if args is None:      # a scenario script: its own command line with the same options
        args = build_parser().parse_args(["run", scenario] + sys.argv[1:])
        setup_logging(args.verbose, args.quiet)
    viewer, save = options.viewer(args)
    sc = load(scenario)
    if getattr(sc, "kind", None) == "structure":       # a structure at one position: static analysis
        return _static(sc, args, viewer, save)
    out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
    shown = []       # the status the table was printed with

    def answer(summary: dict) -> None:
        """The table as soon as the engines' results are in, before the run's slower files."""
        print(comparison_table(summary), file=out, flush=True)
        shown.append(summary["status"])

    result = run_scenario(sc, _run_options(args, sc, viewer, save, answer))
    if not shown:
        answer(result.summary)
    elif result.summary["status"] != shown[0]:     # an output written after the table failed
        print(f"\n{status_notice(result.summary) or 'status ' + result.summary['status']}", file=out)
    print(f"\nwritten to {result.folder}", file=out)
    recording = result.summary["files"].get("recording")
    if viewer is not None and viewer.stdout and recording:
        copy_to_stdout(result.folder / recording)          # an absolute --save path stays absolute
    if result.recorder is not None and getattr(result.recorder, "serving", None):
        log.info("serving the recording until Ctrl-C")
        result.recorder.serve_until_interrupted()
    return options.exit_code(result.summary["status"])


def _run_options(args, sc, viewer, save, answer) -> RunOptions:
    """The run's options from the command line's (checked here, before anything runs)."""
    engines = options.engines(args.engines) if args.engines is not None else sc.output.engines
    options.positive(args, ("--revolutions", "--linkage-fps", "--viewer-timeout"))
    return RunOptions(engines=engines, mode=args.drive, revolutions=args.revolutions, out=args.out,
                      viewer="none" if viewer is None else viewer.viewer,
                      connect_url=None if viewer is None else viewer.url, save_path=save,
                      viewer_timeout_s=5.0 if viewer is None else viewer.timeout_s,
                      serve_address="127.0.0.1" if viewer is None else viewer.bind, exaggeration=args.exaggeration,
                      linkage_fps=args.linkage_fps, animation=args.animation, progress=not quiet(args),
                      records=args.records, max_hours=options.max_hours(args), on_results=answer)


def _static(sc, args, viewer, save) -> int:
    """A structure held at one position: its static analysis, table and folder."""
    if getattr(args, "records", None) is not None:
        log.warning("--records: a static structure has no records to score; ignored")
    if viewer is not None and (viewer.viewer != "save" or viewer.stdout or save):
        log.warning("a static structure writes no recording; the viewer flags are ignored")
    folder, summary = run_static(sc, args.out)
    print(summary_table(summary))
    print(f"\nwritten to {folder}")
    return 0
