"""Command line of the bench: ``cosim``.

    cosim list                                   scenarios and their one-line descriptions
    cosim run <name|path> [options]              run a scenario through the engines, write logs/
    cosim sweep <name|path> --rpm 100:400:25     peak strain against speed, points in parallel
    cosim uncertainty <name|path>                band of predicted strains over uncertain parameters
    cosim identify <name> ... --validate <name>  calibrate declared unknowns, predict held-out speeds
    cosim compare <folder>                       the table of a run, sweep or uncertainty folder
    cosim new <name> [--like SCENARIO]           a commented scenario file to start from
    cosim synthesize --case I|II ...             link lengths of a rigid crank-rocker (tmm_core.synthesis)
    cosim export-fmu <name|path> -o X.fmu        an FMI 2.0 FMU of one engine or the motor (cosim.fmi)

Bad input (unknown scenario or engine, malformed range, bad scenario file) ends with a one-line
``error: ...`` on stderr and exit status 2; a run in which an engine failed, or that ran out of
memory, exits with 1; a run that completed with some of its files missing (``completed with
missing outputs``: the recording's writer died, the parquet copy or the figure failed) with 3; a sweep
in which a point did not run too; a sweep whose points all ran but some have no solution
(``completed with unsolved points``, a finding) exits with 0, as ``completed`` does. A
stdout closed by its reader (``cosim compare ... | head``) ends quietly with exit status 141
(128 + SIGPIPE, what ``git log | head`` or ``yes | head`` give, so ``set -o pipefail`` sees the
same as with any other command whose output was cut short).
``python -m cosim`` is the same command.

Output: the tables (and where the results were written) go to stdout (with ``--stdout`` the
recording goes there, and the tables to stderr); progress bars and messages
go to stderr through :mod:`logging` (``-v`` adds detail, ``-q`` leaves only warnings and errors
and switches the bars off; bars are off anyway when stderr is not a terminal). The ``--serve``
viewer's address is printed on stderr even with ``-q`` (:func:`cosim.recording.sinks.announce_serving`). Results are
written under ``./logs/`` of the current directory unless ``--out`` says otherwise.

Owns: the ``cosim`` command: arguments (every subcommand's, synthesize and identify too),
dispatch, exit codes, logging set-up. Boundaries: no numerics and no file formats: it calls run,
sweep, uncertainty, identify, report. Each subcommand imports the modules that run it when it
runs (the one place cosim imports its own modules inside functions), so ``cosim --help`` and
``cosim list`` load none of the numerics.
"""
from __future__ import annotations

import signal


def _exit_quietly(signum, frame):
    """Ctrl-C while this module's imports load (the console script imports it before ``main``
    can catch anything): end with 128 + the signal, no traceback."""
    raise SystemExit(128 + signum)


# Installed before the other imports and put back after them, only over Python's own handler on
# the main thread (a SIGINT ignored by the shell stays ignored; a library import keeps its own).
_IMPORTING = signal.getsignal(signal.SIGINT) is signal.default_int_handler
if _IMPORTING:
    try:
        signal.signal(signal.SIGINT, _exit_quietly)
    except ValueError:                 # not the main thread
        _IMPORTING = False

import argparse  # noqa: E402  (after the handler, on purpose)
import json  # noqa: E402
import logging  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from . import __version__  # noqa: E402
from .defaults import MAX_HOURS, SYNTHESIS_LIKE  # noqa: E402
from .interrupts import exit_status, interrupt_on_sigterm  # noqa: E402
from .recording.options import add_viewer_arguments, viewer_from_args  # noqa: E402
from .recording.sinks import copy_to_stdout, show_file  # noqa: E402
from .run_outcome import MISSING_OUTPUTS  # noqa: E402
from .runlog import out_folder  # noqa: E402
from .scenario_files import SCENARIO_DIR, ScenarioFileError, read_with_bases, scenario_names  # noqa: E402

if _IMPORTING:
    signal.signal(signal.SIGINT, signal.default_int_handler)



def list_scenarios() -> list[tuple[str, str]]:
    """(name, one-line description) of every scenario file, read from the file and the bases it
    extends without building it (``cosim list`` answers at once; ``cosim run`` checks the rest)."""
    out = []
    for name in scenario_names():
        try:
            meta = read_with_bases(SCENARIO_DIR / f"{name}.toml").get("scenario", {})
            description = meta.get("description", "") if isinstance(meta, dict) else ""
            out.append((name, description if isinstance(description, str) else str(description)))
        except ScenarioFileError as exc:   # a broken file is listed with its error, not hidden
            out.append((name, f"(cannot be loaded: {exc})"))
    return out


def _engines(text: str) -> tuple:
    from .engines import ENGINES          # the engine registry, loaded by the commands that run engines
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    for n in names:
        if n not in ENGINES:
            raise ValueError(f"--engines: unknown engine {n!r}; choose from {', '.join(ENGINES)}")
    if not names:
        raise ValueError("--engines: give at least one engine")
    if len(set(names)) != len(names):
        raise ValueError(f"--engines: an engine is named twice ({text!r})")
    return names


#: The largest counts the command line takes (each sample or trajectory is a model run; more would
#: allocate their design, gigabytes, before anything could say so).
MAX_COUNT = {"--samples": 10_000, "--trajectories": 1_000, "--workers": 1_024}


def _positive(args, flags) -> None:
    """Each numeric flag given must be a positive finite number (counts at most MAX_COUNT); the
    error names the flag. Checked before anything runs."""
    for flag in flags:
        value = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{flag} must be a positive finite number, got {value!r}")
        if value is not None and value > MAX_COUNT.get(flag, math.inf):
            raise ValueError(f"{flag} must be at most {MAX_COUNT[flag]}, got {value!r}")


class _Prefix(logging.Formatter):
    """Messages as they are; warnings and errors prefixed (``error: ...`` is the CLI's contract)."""

    def format(self, record):
        text = record.getMessage()
        return text if record.levelno < logging.WARNING else f"{record.levelname.lower()}: {text}"


class _Stderr(logging.StreamHandler):
    """Writes to the *current* ``sys.stderr`` (pytest's capture and notebooks replace it)."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):
        pass


_HANDLER = None


def setup_logging(verbose: int = 0, quiet: bool = False) -> None:
    """The ``cosim`` logger to stderr at INFO (``-v``: DEBUG, ``-q``: WARNING). Idempotent: a
    second call (tests, scripts) replaces the handler instead of doubling every line."""
    global _HANDLER
    logger = logging.getLogger("cosim")
    if _HANDLER is not None:
        logger.removeHandler(_HANDLER)
    _HANDLER = _Stderr()
    _HANDLER.setFormatter(_Prefix())
    logger.addHandler(_HANDLER)
    logger.setLevel(logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO)
    logger.propagate = False         # no second copy through a root handler


#: The help of ``--max-hours`` (cosim run, sweep, uncertainty, identify).
MAX_HOURS_HELP = (f"refuse work whose estimated wall time exceeds H hours (default {MAX_HOURS:g}; the estimate is "
                  "steps x mesh size per engine and solve, made before anything runs)")


def _max_hours_argument(parser) -> None:
    parser.add_argument("--max-hours", type=float, metavar="H", help=MAX_HOURS_HELP)


def _max_hours(args) -> float:
    """``--max-hours``, checked positive and finite (default :data:`cosim.defaults.MAX_HOURS`)."""
    _positive(args, ("--max-hours",))
    return MAX_HOURS if getattr(args, "max_hours", None) is None else args.max_hours


def _verbosity_arguments(parser, top: bool = False) -> None:
    """``-v``/``-q`` on ``cosim`` itself and on each subcommand (either place works)."""
    suffix = "_top" if top else ""
    parser.add_argument("-v", "--verbose", dest=f"verbose{suffix}", action="count", default=0,
                        help="more detail on stderr (debug messages)")
    parser.add_argument("-q", "--quiet", dest=f"quiet{suffix}", action="store_true",
                        help="no progress bars; only warnings and errors on stderr")


def _quiet(args) -> bool:
    return bool(getattr(args, "quiet", False) or getattr(args, "quiet_top", False))


def _executor_arguments(parser, jobs: str) -> None:
    """The options of :func:`cosim.parallel.executor`: local processes or a Dask cluster."""
    parser.add_argument("--workers", type=int, help="local worker processes (default: the number of cores)")
    parser.add_argument("--scheduler", help=f"Dask scheduler address (e.g. tcp://10.0.0.5:8786): run the {jobs} there")


def build_parser() -> argparse.ArgumentParser:
    """The ``cosim`` parser: every subcommand's options, built without importing the modules that
    run them (``cosim --help`` answers at once)."""
    p = argparse.ArgumentParser(
        prog="cosim",
        description="Flexible-linkage co-simulation bench: a transfer-matrix model (after Shin 1986) with exudyn "
                    "and MuJoCo references, motor-driven or at prescribed speed, compared with measurements.",
        epilog="Examples: cosim list; cosim run crank_rocker_373rpm; cosim run crank_rocker_373rpm --engines tmm "
               "--revolutions 2 --spawn; cosim sweep crank_rocker_373rpm --rpm 100:400:25; cosim compare "
               "logs/crank_rocker_373rpm-<timestamp>")
    p.add_argument("--version", action="version", version=f"cosim {__version__}")
    _verbosity_arguments(p, top=True)
    sub = p.add_subparsers(dest="command", metavar="{list,run,sweep,uncertainty,identify,compare,new,synthesize,export-fmu}")

    for add in (_list_parser, _run_parser, _sweep_parser, _uncertainty_parser, _compare_parser, _new_parser,
                _synthesize_parser, _identify_parser, _export_fmu_parser):
        add(sub)
    return p


def _list_parser(sub) -> None:
    """``cosim list``."""
    sub.add_parser("list", help="show the scenarios and their one-line descriptions",
                   description="Show the scenario files under scenarios/ with their one-line descriptions.")


def _run_parser(sub) -> None:
    """``cosim run``."""
    r = sub.add_parser("run", help="run a scenario through the engines and write logs/<scenario>-<timestamp>/",
                       description="Run a scenario through the engines. Writes traces.csv, scenario.resolved.toml, "
                                   "run.rrd (rerun recording) and summary.json to the run folder.")
    r.add_argument("scenario", help="scenario name (see `cosim list`) or path to a .toml file")
    r.add_argument("--engines", help="comma-separated engines to run (default: the scenario's output.engines, "
                                     "normally tmm,exudyn,mujoco)")
    r.add_argument("--drive", choices=("prescribed", "motor"),
                   help="prescribed constant crank speed, or the scenario's simulated motor (default: the scenario's "
                        "drive.mode)")
    r.add_argument("--revolutions", type=float, help="crank revolutions to simulate (default: the scenario's "
                                                      "output.revolutions)")
    r.add_argument("--out", type=out_folder, help="output folder (default: ./logs/<scenario>-<timestamp> in the current "
                                            "directory)")
    r.add_argument("--records", type=Path, metavar="DIR",
                   help="score against the records in DIR (<name>.csv + <name>.toml each, format in "
                        "cosim/records.py) instead of the shipped scenarios/records")
    _max_hours_argument(r)
    add_viewer_arguments(r, "run.rrd", run=True)
    _verbosity_arguments(r)


def _sweep_parser(sub) -> None:
    """``cosim sweep``."""
    s = sub.add_parser("sweep", help="peak strain against crank speed; points run in parallel",
                       description="Run prescribed-speed points of a scenario and record the last revolution's peak "
                                   "strains per engine and gauge. Points run in parallel on the local cores, or on a "
                                   "Dask cluster given --scheduler.")
    s.add_argument("scenario", help="scenario name or path")
    s.add_argument("--rpm", required=True, help="start:stop:step (e.g. 100:400:25) or a list 95,241,373")
    s.add_argument("--engines", default="tmm", help="comma-separated engines (default: tmm)")
    s.add_argument("--revolutions", type=float, help="revolutions per point (default: the scenario's)")
    s.add_argument("--method", choices=("periodic", "march"), default="periodic",
                   help="TMM: periodic steady state in one solve with Floquet multipliers (default), or time marching; "
                        "exudyn and MuJoCo always march")
    s.add_argument("--model", choices=("full", "reduced"),
                   help="TMM model of the periodic solves: the full transfer-matrix model, or the reduced one (link "
                        "modes plus a static correction, docs/theory.md 'Reduced model'); default: the scenario's "
                        "solver.tmm.model")
    _executor_arguments(s, "points")
    _max_hours_argument(s)
    s.add_argument("--out", type=out_folder, help="output folder (default: ./logs/<scenario>-sweep-<timestamp>)")
    s.add_argument("--no-campbell", dest="campbell", action="store_false",
                   help="skip the natural-frequency map and Campbell diagram (36 eigenvalue searches over a "
                        "revolution; four-bars only)")
    s.add_argument("--records", type=Path, metavar="DIR",
                   help="draw the recorded peaks from DIR instead of the shipped scenarios/records")
    add_viewer_arguments(s, "sweep.rrd")
    _verbosity_arguments(s)


def _uncertainty_parser(sub) -> None:
    """``cosim uncertainty``."""
    u = sub.add_parser("uncertainty", help="band of predicted strains over the scenario's uncertain parameters",
                       description="Band over the unknowns declared in the scenario's [uncertainty] table (Latin "
                                   "hypercube and Morris design; the TMM marched to its steady revolution), a Morris "
                                   "sensitivity ranking, and whether each recorded peak lies inside the band. Samples "
                                   "run in parallel, or on a Dask cluster.")
    u.add_argument("scenario", help="scenario name or path (with an [uncertainty] table)")
    u.add_argument("--samples", type=int, help="Monte Carlo samples (default: the scenario's)")
    u.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    u.add_argument("--trajectories", type=int, help="Morris trajectories (default: the scenario's "
                                                    "morris_trajectories, else 8)")
    _executor_arguments(u, "samples")
    _max_hours_argument(u)
    u.add_argument("--out", type=out_folder, help="output folder (default: ./logs/<scenario>-uncertainty-<timestamp>)")
    u.add_argument("--records", type=Path, metavar="DIR",
                   help="check the recorded peaks from DIR instead of the shipped scenarios/records")
    add_viewer_arguments(u, "uncertainty.rrd")
    _verbosity_arguments(u)


def _compare_parser(sub) -> None:
    """``cosim compare``."""
    c = sub.add_parser("compare", help="print the table of a run, sweep or uncertainty folder",
                       description="Print the table of a results folder: for a run the last-revolution strain "
                                   "extremes per engine and gauge, records and scores, times, and (motor runs) the "
                                   "speed fluctuation, motor current and energy balance; for a sweep the peaks per "
                                   "speed; for an uncertainty run the band. An unfinished folder is said to be so.")
    c.add_argument("run_dir", type=Path, help="a results folder (logs/<scenario>-<timestamp>, ...-sweep-..., "
                                              "...-uncertainty-...)")
    _verbosity_arguments(c)


def _new_parser(sub) -> None:
    """``cosim new``."""
    n = sub.add_parser("new", help="write a commented scenario file to start a rig of your own",
                       description="Write NAME.toml: a complete, commented four-bar scenario (every value to replace "
                                   "marked as an assumption), or with --like a copy of an existing scenario (and the "
                                   "base files it extends). The file is checked to load; an existing file is never "
                                   "overwritten.")
    n.add_argument("name", help="scenario name (letters, digits, _ and -): the file is NAME.toml")
    n.add_argument("--like", metavar="SCENARIO", help="copy this scenario (name or path) instead of the template")
    n.add_argument("--out", type=out_folder, metavar="DIR", help="folder to write to (default: the current directory)")
    _verbosity_arguments(n)


def _synthesize_parser(sub) -> None:
    """``cosim synthesize`` (run by :func:`synthesize_main`)."""
    s = sub.add_parser(
        "synthesize", help="link lengths of a rigid crank-rocker from its rocker swing and limit positions",
        description="Rigid crank-rocker synthesis (FE thesis Ch. III). Case I: from the rocker swing, the folded "
                    "rocker limit phi4 and the minimum transmission angle mu1; case II: from the rocker swing and the "
                    "crank's limit positions. Values carry units ('11 in', '81.07 deg'); lengths are printed in the "
                    "unit of --ground. Example: cosim synthesize --case I --ground '11 in' --oscillation '81.0748 deg' "
                    "--rocker-limit '14.1411 deg' --min-transmission '18.1949 deg'")
    s.add_argument("--case", required=True, choices=("I", "II"), help="I or II (see above)")
    s.add_argument("--ground", required=True, metavar="LENGTH", help="ground link length d, e.g. '11 in'")
    s.add_argument("--oscillation", required=True, metavar="ANGLE", help="rocker swing between its limits")
    s.add_argument("--rocker-limit", metavar="ANGLE", help="case I: phi4, angle crank pivot - rocker pivot - "
                                                           "rocker pin at the folded limit")
    s.add_argument("--min-transmission", metavar="ANGLE", help="case I: mu1, transmission angle with the crank "
                                                               "along the ground line (its minimum)")
    s.add_argument("--crank-limits", nargs=2, metavar=("THETA1", "THETA3"),
                   help="case II: crank angle at the extended limit, and crank angle at the folded limit minus "
                        "180 deg (the thesis's theta3), e.g. '44.6649 deg' '102.2467 deg'")
    s.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    s.add_argument("--scenario-out", type=Path, metavar="PATH", help="write a scenario TOML of the linkage to PATH")
    s.add_argument("--overwrite", action="store_true", help="with --scenario-out: replace an existing file at PATH "
                                                            "(by default it is refused)")
    s.add_argument("--like", metavar="SCENARIO", help="with --scenario-out: the scenario whose sections, materials, "
                                                      f"gauges, drive and solvers to keep (default {SYNTHESIS_LIKE})")
    _verbosity_arguments(s)


def _export_fmu_parser(sub) -> None:
    """``cosim export-fmu`` (its options beside its command, in :mod:`cosim.fmi.command`, a light
    module: the export itself is imported when the command runs)."""
    from .fmi.command import add_parser
    _verbosity_arguments(add_parser(sub))


def _identify_parser(sub) -> None:
    """``cosim identify`` (run by :func:`identify_main`)."""
    p = sub.add_parser("identify", help="calibrate declared unknowns at some speeds, predict held-out ones",
                       description="Calibrate chosen unknowns of the scenarios' [uncertainty] table against their "
                                   "records by bounded least squares within the declared ranges, then predict the "
                                   "held-out scenarios (--validate) without reading their records during the fit. "
                                   "Writes identification.json, identification.png/.svg and identification.rrd.",
                       epilog="Example: cosim identify crank_rocker_241rpm --validate "
                              "crank_rocker_95rpm,crank_rocker_373rpm")
    p.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="calibration scenarios (names or paths)")
    p.add_argument("--validate", default="", metavar="SCENARIO[,SCENARIO]",
                   help="held-out scenarios to predict (comma-separated)")
    p.add_argument("--parameters", metavar="NAME[,NAME]",
                   help="declared unknowns to calibrate (default: the scenario's [uncertainty] identify list); the "
                        "others keep the scenario's own values")
    p.add_argument("--starts", type=int, default=3, help="least-squares starts per choice of the discrete unknowns "
                                                         "(default 3: mid-range and random points)")
    p.add_argument("--sigma", default="10%,5", metavar="REL%,ABS",
                   help="record uncertainty: relative part and absolute part in microstrain (default 10%%,5)")
    p.add_argument("--records", type=Path, metavar="DIR",
                   help="read the records from DIR instead of the shipped scenarios/records")
    p.add_argument("--out", type=out_folder, help="output folder (default: ./logs/<scenarios>-identify-<timestamp>)")
    p.add_argument("--workers", type=int, help="local worker processes (default: the number of cores)")
    p.add_argument("--scheduler", help="Dask scheduler address: run the fits there")
    _max_hours_argument(p)
    _verbosity_arguments(p)


def main(argv: list[str] | None = None) -> int:
    interrupt_on_sigterm()
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:          # Ctrl-C while the subcommands' modules load: no traceback
        return exit_status()
    setup_logging(getattr(args, "verbose", 0) + getattr(args, "verbose_top", 0), _quiet(args))
    log = logging.getLogger("cosim.cli")
    log.debug("cosim %s, options %s", __version__, vars(args))
    try:
        status = _dispatch(parser, args)
        sys.stdout.flush()              # here, not at exit, where a closed pipe would print a traceback
        return status
    except KeyboardInterrupt:
        log.warning("interrupted")
        return exit_status()
    except BrokenPipeError:             # the reader of stdout has gone (`| head`): nothing to say
        _silence_stdout()
        return EXIT_BROKEN_PIPE
    except (ValueError, FileNotFoundError, OSError) as exc:
        log.error(_one_line(exc))
        return 2
    except Exception as exc:
        if _is_model_error(exc):
            log.error(_one_line(exc))
            return 2
        raise


def _is_model_error(exc: Exception) -> bool:
    """A transfer-matrix or engine error: bad input found by the model (exit 2, one line). Their
    modules are looked up, not imported: if one of them raised, it is loaded."""
    core, engines = sys.modules.get("tmm_core"), sys.modules.get("cosim.engines")
    return ((core is not None and isinstance(exc, core.TMMError))
            or (engines is not None and isinstance(exc, engines.EngineError)))


#: Exit status of a run whose engines completed but some of whose outputs (recording, parquet,
#: figure, model.xml, scores) are missing (cosim.run_outcome): its results are computed, yet a
#: script that goes on to read them must not take it for a whole run (0), nor for a failure (1).
EXIT_MISSING_OUTPUTS = 3
#: Exit status when stdout's reader closed the pipe: 128 + SIGPIPE (13), the shell's convention.
EXIT_BROKEN_PIPE = 141


def _silence_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's final flush of what is still
    buffered for the closed pipe neither fails nor prints (the recipe of Python's signal docs)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):     # a stdout without a file descriptor (captured)
        pass


def _one_line(exc) -> str:
    return " ".join(str(exc).split())


def _dispatch(parser, args) -> int:
    if args.command == "list":
        rows = list_scenarios()
        width = max((len(n) for n, _ in rows), default=0)
        for name, desc in rows:
            print(f"{name:<{width}}  {desc}")
        return 0
    if args.command == "run":
        return run_main(args.scenario, args)
    if args.command in ("sweep", "uncertainty"):
        _positive(args, ("--samples", "--trajectories", "--workers"))
        _refuse_structure(args.scenario, args.command)
    if args.command == "sweep":
        from .sweeps import parse_rpm, run_sweep
        rpm = parse_rpm(args.rpm)
        _positive(args, ("--revolutions", "--workers"))
        from .report import sweep_table, unsolved_count
        viewer, save = _viewer(args)
        folder, summary = run_sweep(args.scenario, rpm, _engines(args.engines), args.revolutions, args.workers,
                                    args.scheduler, args.out, record=viewer is not None, progress=not _quiet(args),
                                    method=args.method, resonance=args.campbell, records_dir=args.records,
                                    model=args.model, max_hours=_max_hours(args))
        out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
        print(sweep_table(summary), file=out)
        print(f"\nsweep {summary['status']}: {len(summary['points'])} points{unsolved_count(summary)} in "
              f"{summary['wall_time_s']:.1f} s; written to {folder}", file=out)
        _show(folder / "sweep.rrd", viewer, save)
        return _exit_code(summary["status"])
    if args.command == "uncertainty":
        from .report import uncertainty_table
        from .uncertainty import run_uncertainty
        viewer, save = _viewer(args)
        folder, summary = run_uncertainty(args.scenario, args.samples, args.seed, args.workers, args.scheduler,
                                          args.out, record=viewer is not None, progress=not _quiet(args),
                                          records_dir=args.records, trajectories=args.trajectories,
                                          max_hours=_max_hours(args))
        out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
        print(uncertainty_table(summary), file=out)
        print(f"\nwritten to {folder}", file=out)
        _show(folder / "uncertainty.rrd", viewer, save)
        return _exit_code(summary["status"])
    if args.command == "new":
        from .template import new_scenario
        path, bases = new_scenario(args.name, args.like, args.out)
        print(f"wrote {path}" + (f" and its base file(s) {', '.join(str(b) for b in bases)}" if bases else ""))
        print(f"run it with: cosim run {path}")
        return 0
    if args.command == "export-fmu":
        from .fmi.command import run_command as export_fmu_command
        return export_fmu_command(args)
    if args.command == "identify":
        return identify_main(args)
    if args.command == "synthesize":
        return synthesize_main(args)
    if args.command == "compare":
        return compare_main(args.run_dir)
    parser.print_help()
    return 0


def _parse_sigma(text: str) -> tuple:
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


def identify_main(args) -> int:
    """``cosim identify``: its options read and checked, the identification run
    (:func:`cosim.identify.identify`), its table and where the results went printed."""
    validation = [s.strip() for s in args.validate.split(",") if s.strip()]
    names = [s.strip() for s in args.parameters.split(",") if s.strip()] if args.parameters else None
    if args.starts < 1:
        raise ValueError(f"--starts must be at least 1, got {args.starts}")
    max_hours = _max_hours(args)
    rel, absolute = _parse_sigma(args.sigma)
    from .identify import identify
    from .report import identification_table
    folder, result = identify(args.scenarios, validation, names, args.records, args.out, starts=args.starts,
                              workers=args.workers, scheduler=args.scheduler, sigma_relative=rel,
                              sigma_absolute_ue=absolute, progress=not _quiet(args), max_hours=max_hours)
    print(identification_table(result))
    print(f"\nwritten to {folder}")
    return 0 if result["status"] == "completed" else 1


def _quantity(option: str, text: str, kind: str):
    """``text`` as a pint quantity of kind 'length' or 'angle'; a bare number is refused."""
    from .units import UREG, quantity     # pint on use: `cosim --help` stays quick
    example = {"length": "in", "angle": "deg"}[kind]
    try:
        q = quantity(text)
    except Exception:
        raise ValueError(f"option {option} = {text!r}: not a quantity with a unit, e.g. '11 {example}'") from None
    if not hasattr(q, "units") or q.units == UREG.dimensionless:      # "81 %" has a unit: refused below
        raise ValueError(f"option {option} = {text!r}: has no unit; write it with one, e.g. '{text} {example}'")
    target = UREG.meter if kind == "length" else UREG.radian     # pint counts angles as dimensionless
    if UREG.get_root_units(q.units)[1] != target or not math.isfinite(q.magnitude):
        raise ValueError(f"option {option} = {text!r}: is not a finite {kind}")
    return q


def _case_inputs(args) -> dict:
    """The case's angle options [rad]; an option of the other case is refused rather than ignored."""
    own = {"I": ("rocker_limit", "min_transmission"), "II": ("crank_limits",)}[args.case]
    for name in ("rocker_limit", "min_transmission", "crank_limits"):
        value, option = getattr(args, name), "--" + name.replace("_", "-")
        if (value is not None) != (name in own):
            raise ValueError(f"option {option} is required for case {args.case}" if value is None else
                             f"option {option} = {value!r}: is not used by case {args.case}")
    if args.like is not None and args.scenario_out is None:
        raise ValueError(f"option --like = {args.like!r}: is only used with --scenario-out")
    if args.overwrite and args.scenario_out is None:
        raise ValueError("option --overwrite: is only used with --scenario-out")
    out = args.scenario_out
    if out is not None and (out.exists() or out.is_symlink()) and not (args.overwrite and out.is_file()):
        raise ValueError(f"option --scenario-out = {str(out)!r}: already exists" +
                         ("; give another path, or --overwrite to replace it" if not out.is_dir() else
                          " and is a folder; give a file path"))
    given = ([(n, "--" + n.replace("_", "-"), getattr(args, n)) for n in own] if args.case == "I" else
             [(n, f"--crank-limits ({n.upper()})", t) for n, t in zip(("theta1", "theta3"), args.crank_limits)])
    return {name: float(_quantity(option, text, "angle").to("rad").magnitude) for name, option, text in given}


def synthesize_main(args) -> int:
    """``cosim synthesize``: its options read (values with units), the crank-rocker synthesized
    (:mod:`tmm_core.synthesis`), printed (table or one JSON object), optionally written as a scenario."""
    ground = _quantity("--ground", args.ground, "length")
    oscillation = float(_quantity("--oscillation", args.oscillation, "angle").to("rad").magnitude)
    inputs = _case_inputs(args)
    from tmm_core.synthesis import synthesize_case_one, synthesize_case_two
    from .report import synthesis_table
    from .synthesis import result_record, write_scenario
    result = (synthesize_case_one if args.case == "I" else synthesize_case_two)(
        float(ground.to("m").magnitude), oscillation, **inputs)
    written = (write_scenario(result, args.scenario_out, args.like or SYNTHESIS_LIKE, ground.units)
               if args.scenario_out is not None else None)
    record = result_record(result, ground.units, written)
    print(json.dumps(record) if args.json else synthesis_table(record))
    return 0


def _exit_code(status: str) -> int:
    """A command's exit status from its summary's status: 0 when it completed (with failed samples
    or unsolved points too: the band, and a speed without a periodic solution, are results),
    :data:`EXIT_MISSING_OUTPUTS` when a run completed but some of its files are missing, 128 + the
    signal when a signal interrupted it, 1 otherwise."""
    if status == MISSING_OUTPUTS:
        return EXIT_MISSING_OUTPUTS
    if status.startswith("completed"):
        return 0
    return exit_status() if status == "interrupted" else 1


def _refuse_structure(scenario: str, command: str) -> None:
    """A structure held at one position has no speed: ``sweep`` and ``uncertainty`` refuse it."""
    from .scenario import load
    sc = load(scenario)
    if getattr(sc, "kind", None) == "structure":
        raise ValueError(f"scenario '{scenario}' is a structure held at one position (linkage.type = 'structure'): "
                         f"it has no crank speed, so `cosim {command}` cannot run it; use `cosim run {scenario}`")


def compare_main(folder) -> int:
    """``cosim compare``: the folder's own table; a summary that cannot be read or shown is one
    ``error:`` line and exit 2, never a traceback."""
    from .report import load_summary, report
    summary = load_summary(folder)          # ValueError / FileNotFoundError name the file
    try:
        text = report(summary)
    except Exception as exc:                # a summary.json edited by hand or from another version
        raise ValueError(f"{Path(folder)}/summary.json: cannot be shown ({type(exc).__name__}: {exc}); it may be "
                         "from another version of the bench or edited by hand") from None
    print(text)
    return 0


def run_main(scenario: str, args=None) -> int:
    """``cosim run``; also what each scenario script calls (``python scenarios/<name>.py``)."""
    if args is None:      # a scenario script: its own command line with the same options
        args = build_parser().parse_args(["run", scenario] + sys.argv[1:])
        setup_logging(args.verbose, args.quiet)
    from .report import comparison_table, status_notice
    from .runs import RunOptions, run_scenario
    viewer, save = _viewer(args)
    from .scenario import load
    sc = load(scenario)
    if getattr(sc, "kind", None) == "structure":       # a structure at one position: static analysis
        from .structure_scenario import run_static, summary_table
        if getattr(args, "records", None) is not None:
            logging.getLogger("cosim.cli").warning("--records: a static structure has no records to score; ignored")
        if viewer is not None and (viewer.viewer != "save" or viewer.stdout or save):
            logging.getLogger("cosim.cli").warning("a static structure writes no recording; the viewer flags are "
                                                   "ignored")
        folder, summary = run_static(sc, args.out)
        print(summary_table(summary))
        print(f"\nwritten to {folder}")
        return 0
    out = sys.stderr if viewer is not None and viewer.stdout else sys.stdout     # --stdout: the .rrd
    shown = []       # the status the table was printed with

    def answer(summary: dict) -> None:
        """The table as soon as the engines' results are in, before the run's slower files."""
        print(comparison_table(summary), file=out, flush=True)
        shown.append(summary["status"])

    engines = _engines(args.engines) if args.engines is not None else sc.output.engines
    _positive(args, ("--revolutions", "--linkage-fps", "--viewer-timeout"))
    max_hours = _max_hours(args)
    options = RunOptions(engines=engines, mode=args.drive, revolutions=args.revolutions, out=args.out,
                         viewer="none" if viewer is None else viewer.viewer,
                         connect_url=None if viewer is None else viewer.url, save_path=save,
                         viewer_timeout_s=5.0 if viewer is None else viewer.timeout_s,
                         serve_address="127.0.0.1" if viewer is None else viewer.bind, exaggeration=args.exaggeration,
                         linkage_fps=args.linkage_fps, animation=args.animation, progress=not _quiet(args),
                         records=args.records, max_hours=max_hours, on_results=answer)
    result = run_scenario(sc, options)
    if not shown:
        answer(result.summary)
    elif result.summary["status"] != shown[0]:     # an output written after the table failed
        print(f"\n{status_notice(result.summary) or 'status ' + result.summary['status']}", file=out)
    print(f"\nwritten to {result.folder}", file=out)
    recording = result.summary["files"].get("recording")
    if viewer is not None and viewer.stdout and recording:
        copy_to_stdout(result.folder / recording)          # an absolute --save path stays absolute
    if result.recorder is not None and getattr(result.recorder, "serving", None):
        logging.getLogger("cosim.cli").info("serving the recording until Ctrl-C")
        result.recorder.serve_until_interrupted()
    return _exit_code(result.summary["status"])


def _viewer(args):
    """(ViewerOptions or None, --save path or None) of the recording flags (cosim.recording.options)."""
    return viewer_from_args(args)


def _show(path: Path, viewer, save) -> None:
    """A finished sweep/uncertainty recording in the viewer the flags ask for (and --save, --stdout)."""
    if viewer is None or not path.exists():
        return
    show_file(path, viewer, save)


if __name__ == "__main__":
    sys.exit(main())
