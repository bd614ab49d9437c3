"""The drive of a motor-driven run, by ``[drive] type``: the bench's DC motor (``"motor"``, the
``[motor]`` table, :class:`cosim.motor.Motor`) or an FMU (``"fmu"``, :class:`cosim.fmi.drive.FmuDrive`).

Both offer what the master's channel uses: ``start``, ``advance`` (a crank motion in, or a load
torque in and the crank integrated), ``drive_torque_now``, ``crank_side_inertia_kg_m2`` and ``p``
(the motor's parameters; None for an FMU, whose parameters are its own).

Owns: ``make_drive``. Boundaries: the drives' code (cosim.motor, cosim.fmi.drive), imported
lazily for the FMU (FMPy is loaded only by a run that uses it).
"""
from __future__ import annotations

from .motor import Motor


def make_drive(scenario, integrates_crank: bool, repeatable: bool = True):
    """The drive of ``scenario`` for one engine: ``integrates_crank`` for kinematic engines
    (the drive integrates the crank against the load torque), else it takes the crank's motion.
    ``repeatable``: the coupling repeats macro steps (the iterated scheme), so an FMU drive
    saves its state at each step's start."""
    if scenario.drive.type == "fmu":
        from .fmi.drive import FmuDrive
        return FmuDrive(scenario.drive.fmu, integrates_crank, repeatable=repeatable)
    return Motor(scenario.motor, integrates_crank=integrates_crank)
