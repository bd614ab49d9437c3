"""Command line of the bench: ``cosim``.

    cosim list                                   scenarios and their one-line descriptions
    cosim run <name|path> [options]              run a scenario through the engines, write logs/
    cosim sweep <name|path> --rpm 100:400:25     peak strain against speed, points in parallel
    cosim uncertainty <name|path>                band of predicted strains over uncertain parameters
    cosim compare <run-dir>                      the comparison table of a finished run

Bad input (unknown scenario or engine, malformed range, bad scenario file) ends with a one-line
``error: ...`` on stderr and exit status 2; a run in which an engine failed exits with 1.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from . import __version__

SCENARIO_DIR = Path(__file__).resolve().parent.parent / "scenarios"


def list_scenarios() -> list[tuple[str, str]]:
    """(name, one-line description) of every scenario file."""
    from .scenario import load, scenario_names
    out = []
    for name in scenario_names():
        try:
            out.append((name, load(name).description))
        except Exception as exc:           # a broken file is listed with its error, not hidden
            out.append((name, f"(cannot be loaded: {exc})"))
    return out


def _engines(text: str) -> tuple:
    from .engines import ENGINES
    names = tuple(x.strip() for x in text.split(",") if x.strip())
    for n in names:
        if n not in ENGINES:
            raise ValueError(f"unknown engine {n!r}; choose from {', '.join(ENGINES)}")
    if not names:
        raise ValueError("give at least one engine")
    return names


def _executor_arguments(parser, jobs: str) -> None:
    """The options of :func:`cosim.parallel.executor`: local processes or a Dask cluster."""
    parser.add_argument("--workers", type=int, help="local worker processes (default: the number of cores)")
    parser.add_argument("--scheduler", help=f"Dask scheduler address (e.g. tcp://10.0.0.5:8786): run the {jobs} there")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="cosim",
        description="Flexible-linkage co-simulation bench: a transfer-matrix model (after Shin 1986) with exudyn "
                    "and MuJoCo references, motor-driven or at prescribed speed, compared with measurements.",
        epilog="Examples: cosim list; cosim run crank_rocker_373rpm; cosim run crank_rocker_373rpm --engines tmm "
               "--revolutions 2 --spawn; cosim sweep crank_rocker_373rpm --rpm 100:400:25; cosim compare "
               "logs/crank_rocker_373rpm-<timestamp>")
    p.add_argument("--version", action="version", version=f"cosim {__version__}")
    sub = p.add_subparsers(dest="command", metavar="{list,run,sweep,uncertainty,compare}")

    sub.add_parser("list", help="show the scenarios and their one-line descriptions",
                   description="Show the scenario files under scenarios/ with their one-line descriptions.")

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
    r.add_argument("--out", type=Path, help="output folder (default: logs/<scenario>-<timestamp>)")
    view = r.add_mutually_exclusive_group()
    view.add_argument("--save", dest="viewer", action="store_const", const="save",
                      help="write run.rrd only, no viewer (default; headless)")
    view.add_argument("--spawn", dest="viewer", action="store_const", const="spawn",
                      help="also spawn a rerun viewer and stream to it")
    view.add_argument("--connect", dest="connect", nargs="?", const="rerun+http://127.0.0.1:9876/proxy",
                      metavar="URL", help="also stream to a running rerun viewer (default URL "
                                          "rerun+http://127.0.0.1:9876/proxy)")
    view.add_argument("--no-record", dest="viewer", action="store_const", const="none",
                      help="no rerun recording at all")
    r.add_argument("--exaggeration", type=float, default=20.0,
                   help="factor on the elastic displacements in the linkage drawing (default 20)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")

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
    _executor_arguments(s, "points")
    s.add_argument("--out", type=Path, help="output folder (default: logs/<scenario>-sweep-<timestamp>)")
    s.add_argument("--quiet", action="store_true", help="no progress bar")

    u = sub.add_parser("uncertainty", help="band of predicted strains over the scenario's uncertain parameters",
                       description="Monte Carlo over the parameters in the scenario's [uncertainty] table (periodic "
                                   "TMM solves), a one-at-a-time sensitivity ranking, and whether the records' peaks "
                                   "fall inside the band. Samples run in parallel, or on a Dask cluster.")
    u.add_argument("scenario", help="scenario name or path (with an [uncertainty] table)")
    u.add_argument("--samples", type=int, help="Monte Carlo samples (default: the scenario's)")
    u.add_argument("--seed", type=int, help="random seed (default: the scenario's)")
    _executor_arguments(u, "samples")
    u.add_argument("--out", type=Path, help="output folder (default: logs/<scenario>-uncertainty-<timestamp>)")

    c = sub.add_parser("compare", help="print the comparison table of a finished run",
                       description="Print the last-revolution strain extremes per engine and gauge, records and "
                                   "scores, times and (motor runs) the speed fluctuation of a run folder.")
    c.add_argument("run_dir", type=Path, help="a run folder (logs/<scenario>-<timestamp>)")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    try:
        return _dispatch(parser, args)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError, OSError) as exc:
        print(f"error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:
        from tmm_core import TMMError

        from .engines import EngineError
        if isinstance(exc, (TMMError, EngineError)):
            print(f"error: {_one_line(exc)}", file=sys.stderr)
            return 2
        raise


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
    if args.command == "sweep":
        from .sweep import parse_rpm, run_sweep
        rpm = parse_rpm(args.rpm)
        folder, summary = run_sweep(args.scenario, rpm, _engines(args.engines), args.revolutions, args.workers,
                                    args.scheduler, args.out, progress=not args.quiet, method=args.method)
        print(f"sweep {summary['status']}: {len(summary['points'])} points in {summary['wall_time_s']:.1f} s; "
              f"written to {folder}")
        return 0 if summary["status"] == "completed" else 1
    if args.command == "uncertainty":
        from .uncertainty import run_uncertainty
        folder, summary = run_uncertainty(args.scenario, args.samples, args.seed, args.workers, args.scheduler, args.out)
        print(f"uncertainty {summary['status']}: {summary['samples']} samples in {summary.get('wall_time_s', 0):.1f} s")
        for g, b in (summary.get("band") or {}).items():
            print(f"  {g}: +peak {b['peak_max_range_ue'][0]:.1f}..{b['peak_max_range_ue'][1]:.1f} ue, -peak "
                  f"{b['peak_min_range_ue'][0]:.1f}..{b['peak_min_range_ue'][1]:.1f} ue; most influential: "
                  f"{summary.get('most_influential', {}).get(g)}")
        for r in summary.get("records") or []:
            print(f"  record {r['record']} {r['gauge']} {r['peak']}peak {r['recorded_ue']:.1f} ue: "
                  f"{'inside' if r['inside'] else 'outside'} the band")
        print(f"written to {folder}")
        return 0 if summary["status"].startswith("completed") else 1
    if args.command == "compare":
        from .report import comparison_table, load_summary
        print(comparison_table(load_summary(args.run_dir)))
        return 0
    parser.print_help()
    return 0


def run_main(scenario: str, args=None) -> int:
    """``cosim run``; also what each scenario script calls (``python scenarios/<name>.py``)."""
    if args is None:      # a scenario script: its own command line with the same options
        args = _parser().parse_args(["run", scenario] + sys.argv[1:])
    from .report import comparison_table
    from .run import RunOptions, run_scenario
    viewer = "connect" if getattr(args, "connect", None) else (args.viewer or "save")
    from .scenario import load
    sc = load(scenario)
    if getattr(sc, "kind", None) == "structure":       # a structure at one position: static analysis
        from .structure_scenario import run_static, summary_table
        folder, summary = run_static(sc, args.out)
        print(summary_table(summary))
        print(f"\nwritten to {folder}")
        return 0
    engines = _engines(args.engines) if args.engines else sc.output.engines
    options = RunOptions(engines=engines, mode=args.drive, revolutions=args.revolutions, out=args.out,
                         viewer=viewer, connect_url=getattr(args, "connect", None), exaggeration=args.exaggeration,
                         progress=not args.quiet)
    result = run_scenario(sc, options)
    print(comparison_table(result.summary))
    print(f"\nwritten to {result.folder}")
    return {"completed": 0, "interrupted": 130}.get(result.summary["status"], 1)


if __name__ == "__main__":
    sys.exit(main())
