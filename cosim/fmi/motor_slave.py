"""The FMU of a scenario's DC motor with its controller and drive train (FMI 2.0 co-simulation).

The motor as a torque source for a crank another model integrates (:class:`cosim.motor.Motor`
with ``integrates_crank=False``): inputs ``crank_angle`` [rad] and ``crank_speed`` [rad/s], held
over a communication step (the angle advancing at that speed); outputs ``drive_torque`` [N.m]
(delivered to the crank, CCW positive), ``current`` [A], ``voltage`` [V], ``motor_speed``
[rad/s] at the step's end. The inputs' values at the end of the initialisation start the motor in
steady running at that crank speed (at rest for 0), as the bench's master starts it. Read-only:
``crank_side_inertia`` [kg.m2], the rotor and flywheel inertia the crank's model must carry (the
FMU integrates only the electrical side and the controller), and ``gear_ratio`` [1].

fmi2GetFMUstate/fmi2SetFMUstate keep the motor state (a frozen dataclass, in memory).

Owns: ``MotorSlave``. Boundaries: the motor's physics is cosim.motor.
"""
from __future__ import annotations

from ..interface_signals import crank_extrapolation
from ..motor import Motor
from .slave import BenchSlave, finite


class MotorSlave(BenchSlave):
    """The ``[motor]`` of the scenario in the FMU's resources."""

    description = "PM DC motor, PI speed control and drive train of the flexlink bench"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        sc = self.scenario
        self.motor = Motor(sc.motor, integrates_crank=False)
        self.state = None
        self.add("crank_angle", "rad", "input", sc.drive.start_angle_rad, "crank angle")
        self.add("crank_speed", "rad/s", "input", sc.drive.speed_rad_s, "crank speed")
        self.add("drive_torque", "N.m", "output", 0.0, "torque delivered to the crank, CCW positive")
        self.add("current", "A", "output", 0.0, "armature current")
        self.add("voltage", "V", "output", 0.0, "armature voltage")
        self.add("motor_speed", "rad/s", "output", 0.0, "motor shaft speed")
        self.add("crank_side_inertia", "kg.m2", "calculatedParameter", self.motor.crank_side_inertia_kg_m2,
                 "rotor and flywheel inertia turning with the crank, for the crank's model to carry")
        self.add("gear_ratio", "1", "calculatedParameter", sc.motor.gear_ratio, "motor turns per crank turn")

    def exit_initialization_mode(self):
        v = self.values
        self.state = self.motor.start(self.t0, v["crank_angle"], v["crank_speed"])
        v["drive_torque"] = self.motor.drive_torque_now(self.state)
        v["current"], v["motor_speed"] = self.state.current_A, self.motor.p.gear_ratio * v["crank_speed"]

    def do_step(self, current_time: float, step_size: float) -> bool:
        v = self.values
        motion = crank_extrapolation(current_time, finite(v["crank_angle"], "crank_angle"),
                                     finite(v["crank_speed"], "crank_speed"), 0.0)
        self.state, trace = self.motor.advance(self.state, current_time + step_size, crank=lambda t: motion(t)[:2])
        v["drive_torque"] = float(trace.drive_torque_Nm[-1])
        v["current"], v["voltage"] = float(trace.current_A[-1]), float(trace.voltage_V[-1])
        v["motor_speed"] = float(trace.motor_speed_rad_s[-1])
        return True

    def model_state(self):
        return self.state

    def set_model_state(self, token) -> None:
        self.state = token
