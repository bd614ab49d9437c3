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
dispatch, logging set-up. Boundaries: no numerics and no file formats: each subcommand is a
module of :mod:`cosim.commands` (:data:`COMMANDS`), imported when the command runs, so ``cosim
--help`` and ``cosim list`` load none of the numerics.
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
import importlib  # noqa: E402
import logging  # noqa: E402
import os  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from . import __version__  # noqa: E402
from .defaults import MAX_HOURS, SYNTHESIS_LIKE  # noqa: E402
from .fmi.command import add_parser as add_fmu_parser  # noqa: E402
from .interrupts import LostInterrupts, exit_status, interrupt_on_sigterm  # noqa: E402
from .recording.options import add_viewer_arguments  # noqa: E402
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


def _verbosity_arguments(parser, top: bool = False) -> None:
    """``-v``/``-q`` on ``cosim`` itself and on each subcommand (either place works)."""
    suffix = "_top" if top else ""
    parser.add_argument("-v", "--verbose", dest=f"verbose{suffix}", action="count", default=0,
                        help="more detail on stderr (debug messages)")
    parser.add_argument("-q", "--quiet", dest=f"quiet{suffix}", action="store_true",
                        help="no progress bars; only warnings and errors on stderr")


def quiet(args) -> bool:
    """``-q`` given on ``cosim`` itself or on the subcommand."""
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
    """``cosim synthesize`` (run by :mod:`cosim.commands.synthesize`)."""
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
    _verbosity_arguments(add_fmu_parser(sub))


def _identify_parser(sub) -> None:
    """``cosim identify`` (run by :mod:`cosim.commands.identify`)."""
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
    with LostInterrupts() as lost:
        status = _main(argv)
        if lost.pending() and status == 0:
            # A Ctrl-C Python could not raise, in a command without its own Interrupts: it ends
            # the command as a Ctrl-C would have.
            logging.getLogger("cosim.cli").warning("interrupted")
            return exit_status()
        return status


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:          # Ctrl-C while the subcommands' modules load: no traceback
        return exit_status()
    setup_logging(getattr(args, "verbose", 0) + getattr(args, "verbose_top", 0), quiet(args))
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


#: The module and function that run each subcommand (``main(args) -> exit status``), imported
#: when the command runs: the one place cosim loads its own modules on demand, so that ``cosim
#: --help`` and ``cosim list`` import none of the numerics.
COMMANDS = {
    "run": ("cosim.commands.run", "main"),
    "sweep": ("cosim.commands.sweep", "main"),
    "uncertainty": ("cosim.commands.uncertainty", "main"),
    "identify": ("cosim.commands.identify", "main"),
    "compare": ("cosim.commands.compare", "main"),
    "new": ("cosim.commands.new", "main"),
    "synthesize": ("cosim.commands.synthesize", "main"),
    "export-fmu": ("cosim.fmi.command", "run_command"),
}


def _dispatch(parser, args) -> int:
    if args.command == "list":
        rows = list_scenarios()
        width = max((len(n) for n, _ in rows), default=0)
        for name, desc in rows:
            print(f"{name:<{width}}  {desc}")
        return 0
    if args.command not in COMMANDS:
        parser.print_help()
        return 0
    module, function = COMMANDS[args.command]
    return getattr(importlib.import_module(module), function)(args)


if __name__ == "__main__":
    sys.exit(main())
