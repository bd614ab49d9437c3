"""The FMU of one engine on one scenario (FMI 2.0 co-simulation, built by :mod:`cosim.fmi.export`).

Inputs, by the FMU's drive input (``bench_fmu.json``, chosen at export):

* ``prescribed``: ``crank_angle`` [rad], ``crank_speed`` [rad/s], ``crank_acceleration``
  [rad/s2] at the start of each communication step; over the step the crank moves with that
  constant acceleration (exact for a crank at constant speed). Output ``drive_torque`` [N.m].
* ``torque``: ``drive_torque`` [N.m], held over the step; the engine integrates the crank
  (torque-driven engines only: the transfer-matrix model clamps its crank). Outputs
  ``crank_angle`` [rad] and ``crank_speed`` [rad/s].

Every gauge ``g`` adds the outputs ``g.bending`` and ``g.axial`` [1] (strain, positive = tension
on the gauged face; :mod:`cosim.engines.base` for the sign conventions). Parameters
``start_angle`` [rad] and ``start_speed`` [rad/s] (fixed: set before the initialisation) start
the crank; ``drive_inertia`` [kg.m2] (torque input) is the drive's inertia carried on the crank.
Read-only (calculated parameters: changing them needs a new export): ``drive_speed`` [rad/s],
the scenario's crank speed, ``internal_step`` [s], the engine's step, of which every
communication step must be a whole multiple, ``<gauge>.position`` [m] and ``<link>.length`` [m]. Outputs are the engine's values at the step's end.

fmi2GetFMUstate/fmi2SetFMUstate save and restore the engine (``Engine.save``/``restore``, as the
master does for its iterated coupling); the state lives in memory (not serialisable).

Owns: ``LinkageSlave``. Boundaries: the engines behind their protocol; the packaging is
cosim.fmi.export.
"""
from __future__ import annotations

import re

from ..engines import make_engine
from ..engines.base import DriveInput
from ..interface_signals import crank_extrapolation
from .slave import BenchSlave, finite

INPUTS = ("prescribed", "torque")


class LinkageSlave(BenchSlave):
    """An engine (``config['engine']``) of the scenario in the FMU's resources."""

    description = "Flexible linkage of the flexlink bench (one engine, one scenario)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        sc, self.engine_name, self.drive_input = self.scenario, self.config["engine"], self.config["input"]
        self.engine = None
        self.add("start_angle", "rad", "parameter", sc.drive.start_angle_rad, "crank angle at the start")
        self.add("start_speed", "rad/s", "parameter", sc.drive.speed_rad_s, "crank speed at the start")
        self.add("drive_speed", "rad/s", "calculatedParameter", sc.drive.speed_rad_s, "the scenario's crank speed")
        self.add("internal_step", "s", "calculatedParameter", sc.engine_step_s(self.engine_name),
                 "the engine's step: a communication step is a whole multiple of it")
        if self.drive_input == "prescribed":
            self.add("crank_angle", "rad", "input", sc.drive.start_angle_rad, "crank angle (CCW from the ground line)")
            self.add("crank_speed", "rad/s", "input", sc.drive.speed_rad_s, "crank speed")
            self.add("crank_acceleration", "rad/s2", "input", 0.0, "crank acceleration")
            self.add("drive_torque", "N.m", "output", 0.0, "torque the linkage takes at the crank, CCW positive")
        else:
            self.add("drive_inertia", "kg.m2", "parameter", 0.0, "drive inertia turning with the crank")
            self.add("drive_torque", "N.m", "input", 0.0, "torque applied to the crank, CCW positive")
            self.add("crank_angle", "rad", "output", sc.drive.start_angle_rad, "crank angle")
            self.add("crank_speed", "rad/s", "output", sc.drive.speed_rad_s, "crank speed")
        for g in sc.gauges:
            self.add(f"{g.name}.bending", "1", "output", 0.0, f"bending strain at gauge {g.name}")
            self.add(f"{g.name}.axial", "1", "output", 0.0, f"axial strain at gauge {g.name}")
            self.add(f"{g.name}.position", "m", "calculatedParameter", g.position_m,
                     f"gauge {g.name}: distance along link {g.link} from its start")
        for link in sc.mechanism.links():
            # FMI's structured names allow [integer] subscripts only: "rocker[D-E]" -> "rocker_D_E".
            name = re.sub(r"\W+", "_", link.name).strip("_")
            self.add(f"{name}.length", "m", "calculatedParameter", link.length_m, f"length of link {link.name}")

    def exit_initialization_mode(self):
        v = self.values
        self.engine = make_engine(self.engine_name)
        extra = {} if self.drive_input == "prescribed" else {"drive_inertia_kg_m2": v["drive_inertia"]}
        self.engine.reset(self.scenario, self.t0, v["start_angle"], v["start_speed"], **extra)
        self._publish(self.engine.initial_output())

    def do_step(self, current_time: float, step_size: float) -> bool:
        v = self.values
        if self.drive_input == "prescribed":
            drive = DriveInput(prescribed=crank_extrapolation(current_time, v["crank_angle"], v["crank_speed"],
                                                              v["crank_acceleration"]))
        else:
            drive = DriveInput(torque=finite(v["drive_torque"], "drive_torque"))
        self._publish(self.engine.advance(current_time + step_size, drive))
        return True

    def _publish(self, out) -> None:
        """Outputs from the engine's last sample (the step's end)."""
        v = self.values
        if self.drive_input == "prescribed":
            v["drive_torque"] = float(out.drive_torque[-1])
        else:
            v["crank_angle"], v["crank_speed"] = float(out.crank_angle[-1]), float(out.crank_speed[-1])
        for name, (bending, axial) in out.gauges.items():
            v[f"{name}.bending"], v[f"{name}.axial"] = float(bending[-1]), float(axial[-1])

    def model_state(self):
        return self.engine.save()

    def set_model_state(self, token) -> None:
        self.engine.restore(token)
