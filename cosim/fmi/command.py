"""``cosim export-fmu SCENARIO --engine tmm -o linkage.fmu``: the command line of the FMU export.

Light on purpose (argparse only): the CLI builds its parser at every start, and PythonFMU is
imported only when the command runs (:mod:`cosim.fmi.export`).

Owns: ``add_parser``, ``run_command``. Boundaries: the export itself is cosim.fmi.export.
"""
from __future__ import annotations

import argparse
from pathlib import Path

ENGINE_CHOICES = ("tmm", "exudyn", "mujoco", "motor")


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``export-fmu`` on the ``cosim`` sub-command parsers; returns its parser."""
    e = subparsers.add_parser(
        "export-fmu", help="write an FMI 2.0 co-simulation FMU of one engine (or the motor) on a scenario",
        description="Write an FMI 2.0 co-simulation FMU (PythonFMU) of one engine on one scenario: inputs the crank "
                    "angle, speed and acceleration (--input prescribed) or the drive torque (--input torque, "
                    "torque-driven engines); outputs the drive torque or the crank motion and every gauge's bending "
                    "and axial strain. '--engine motor' exports the scenario's DC motor (crank speed in, drive "
                    "torque out) for a master to couple to a crank. docs/fmi.md. Example: cosim export-fmu "
                    "crank_rocker_373rpm --engine tmm -o linkage.fmu")
    e.add_argument("scenario", help="scenario name or path")
    e.add_argument("--engine", default="tmm", choices=ENGINE_CHOICES, help="the model in the FMU (default tmm)")
    e.add_argument("--input", default="prescribed", choices=("prescribed", "torque"),
                   help="the drive input: the crank motion (default) or the drive torque")
    e.add_argument("-o", "--output", required=True, type=Path, metavar="FILE.fmu", help="the FMU to write")
    return e


def run_command(args) -> int:
    """Export; an existing file is not overwritten. Returns the exit status."""
    from .export import export_fmu
    if args.output.exists():
        raise FileExistsError(f"export-fmu: {args.output} exists; remove it or choose another -o")
    path = export_fmu(args.scenario, args.output, engine=args.engine, drive_input=args.input)
    print(f"written to {path}")
    return 0
