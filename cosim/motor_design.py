"""The ``[motor]`` table of a scenario: the drive train written from its rating (the constants the
sources do not give are derived by :func:`derive_pm_dc_motor` and listed as
assumptions), flywheels, shaft, controller and set-point, as :class:`cosim.motor.MotorParameters`.

Owns: the motor design from a scenario file. The motor's physics is :mod:`cosim.motor`.
"""
from __future__ import annotations

import math

import numpy as np

from tmm_core import InputError

from .motor import MotorParameters, SetPoint
from .scenario_reader import MAX_MAGNITUDE, Reader
from .scenario_types import Assumption, DriveSpec, to_rpm


MOTOR_CONSTANTS = {"resistance": ("resistance_ohm", "ohm"), "inductance": ("inductance_H", "H"),
                   "torque_constant": ("torque_constant_Nm_A", "N*m/A"),
                   "back_emf": ("back_emf_V_s_rad", "V*s/rad"), "rotor_inertia": ("rotor_inertia_kg_m2", "kg*m**2"),
                   "viscous_friction": ("viscous_friction_Nm_s_rad", "N*m*s/rad"),
                   "coulomb_friction": ("coulomb_friction_Nm", "N*m")}


#: Ranges of a drive for a linkage bench, beyond which a value is a unit slip, not a motor:
#: rated power 1 W-1 MW, voltages 1 V-10 kV, a speed loop's bandwidth up to 1 kHz (PI speed
#: loops of brushed DC drives run at 1-100 Hz) and a current loop's up to 20 kHz (the PWM rate).
RATED_POWER_W = (1.0, 1e6)
VOLTAGE_V = (1.0, 1e4)
SPEED_BANDWIDTH_HZ = (1e-3, 1e3)
CURRENT_BANDWIDTH_HZ = (1e-3, 2e4)


def in_range(r, d: dict, key: str, unit: str, bounds: tuple, table: str = "motor") -> float:
    """``d[key]`` in ``unit``, refused naming ``table.key`` outside ``bounds`` (SI)."""
    x = r.quantity(d[key], f"{table}.{key}", unit, positive=True)
    if not bounds[0] <= x <= bounds[1]:
        raise r.fail(f"{table}.{key}", f"is {x:.3g} {unit}, outside the {bounds[0]:g}-{bounds[1]:g} {unit} of a "
                                       f"linkage bench's drive (check the number and its unit)", d[key])
    return x


def derive_pm_dc_motor(rated_power_W: float, rated_speed_rad_s: float, rated_voltage_V: float,
                       efficiency: float = 0.8, copper_loss_share: float = 0.5, coulomb_share: float = 0.4,
                       electrical_time_constant_s: float = 0.01, rotor_inertia_per_W: float = 2.5e-6):
    """Defensible PM DC motor constants from the nameplate (rated output power, speed, voltage).

    At the rated point the input power is P / efficiency; ``copper_loss_share`` of the losses is
    R i^2, the rest friction (``coulomb_share`` of it Coulomb, the remainder viscous). Then
    i = P_in / V, R = copper loss / i^2, Ke = Kt = (V - R i) / omega, L = R * electrical time
    constant, J_rotor = rotor_inertia_per_W * P (catalogue fractional-horsepower PM DC motors:
    roughly 1e-3 kg m^2 for 0.5 hp). Returns a dict of values and a dict of rationales.
    """
    P, w, V = rated_power_W, rated_speed_rad_s, rated_voltage_V
    if not (P > 0 and w > 0 and V > 0 and 0 < efficiency < 1):
        raise InputError(f"motor rating must be positive with 0 < efficiency < 1, got P={P!r}, w={w!r}, V={V!r}, "
                         f"efficiency={efficiency!r}")
    P_in = P / efficiency
    losses = P_in - P
    i = P_in / V
    R = copper_loss_share * losses / i**2
    K = (V - R * i) / w
    friction = (1 - copper_loss_share) * losses / w            # torque at rated speed
    values = {"resistance_ohm": R, "inductance_H": R * electrical_time_constant_s, "torque_constant_Nm_A": K,
              "back_emf_V_s_rad": K, "rotor_inertia_kg_m2": rotor_inertia_per_W * P,
              "coulomb_friction_Nm": coulomb_share * friction,
              "viscous_friction_Nm_s_rad": (1 - coulomb_share) * friction / w}
    why = (f"derived from the rating ({P:.4g} W at {to_rpm(w):.5g} rpm, {V:.4g} V): efficiency {efficiency:.0%}, "
           f"{copper_loss_share:.0%} of the losses in the armature resistance, friction {coulomb_share:.0%} Coulomb; "
           f"Ke = Kt = (V - R i)/omega; L/R = {electrical_time_constant_s * 1e3:.3g} ms; rotor inertia "
           f"{rotor_inertia_per_W:.2g} kg m^2 per W (catalogue fractional-hp PM DC motors)")
    return values, why


#: The rating's design knobs of :func:`derive_pm_dc_motor`: key of the ``[motor]`` table ->
#: (argument, unit).
RATING_KNOBS = {"efficiency": ("efficiency", ""), "copper_loss_share": ("copper_loss_share", ""),
                "coulomb_share": ("coulomb_share", ""),
                "electrical_time_constant": ("electrical_time_constant_s", "s"),
                "rotor_inertia_per_power": ("rotor_inertia_per_W", "kg*m**2/W")}
#: Every key of the ``[motor]`` table.
MOTOR_KEYS = set(MOTOR_CONSTANTS) | set(RATING_KNOBS) | {
    "rated_power", "rated_speed", "rated_voltage", "supply_voltage", "gear_ratio", "flywheel_inertia", "flywheels",
    "shaft_stiffness", "shaft_damping", "controller", "setpoint", "reversible"}


def _derived_constants(r: Reader, d: dict, missing: list) -> dict:
    """The motor constants ``missing`` from the table, derived from its rating (recorded as
    assumptions): ``{MotorParameters field: SI value}``."""
    rating = [k for k in ("rated_power", "rated_speed", "rated_voltage") if k in d]
    if len(rating) < 3:
        need = sorted({"rated_power", "rated_speed", "rated_voltage"} - set(rating))
        raise r.fail(f"motor.{need[0]}", f"is required to derive the motor constants not given "
                                         f"({', '.join(missing)})")
    P = in_range(r, d, "rated_power", "W", RATED_POWER_W)
    w = r.quantity(d["rated_speed"], "motor.rated_speed", "rad/s", positive=True)
    V = in_range(r, d, "rated_voltage", "V", VOLTAGE_V)
    kw = {name: r.quantity(d[k], f"motor.{k}", unit, positive=True)
          for k, (name, unit) in RATING_KNOBS.items() if k in d}
    for k in ("efficiency", "copper_loss_share", "coulomb_share"):       # fractions, named by their own key
        if k in d and not (kw[RATING_KNOBS[k][0]] < 1 if k == "efficiency" else kw[RATING_KNOBS[k][0]] <= 1):
            raise r.fail(f"motor.{k}", "must be a fraction " + ("below 1 (100 %)" if k == "efficiency"
                                                                else "of at most 1 (100 %)"), d[k])
    try:
        derived, why = derive_pm_dc_motor(P, w, V, **kw)
    except InputError as exc:
        raise r.fail("motor.rated_power", str(exc)) from None
    values = {}
    for key in missing:
        name, unit = MOTOR_CONSTANTS[key]
        values[name] = derived[name]
        r.assumptions.append(Assumption(f"motor.{key}", f"{derived[name]:.6g} {unit.replace('**', '^')}", why))
    return values


def _constants(r: Reader, d: dict) -> dict:
    """The motor's electrical and friction constants (SI): those the table gives, the others
    derived from its rating; then the supply voltage [V]."""
    values = {}
    for key, (name, unit) in MOTOR_CONSTANTS.items():
        if key in d:
            strict = key in ("resistance", "inductance", "torque_constant", "back_emf")
            values[name] = r.quantity(d[key], f"motor.{key}", unit, positive=strict, nonnegative=not strict)
    missing = [k for k in MOTOR_CONSTANTS if MOTOR_CONSTANTS[k][0] not in values]
    if missing:
        values |= _derived_constants(r, d, missing)
    if "supply_voltage" in d:
        values["supply_voltage_V"] = in_range(r, d, "supply_voltage", "V", VOLTAGE_V)
    elif "rated_voltage" in d:
        values["supply_voltage_V"] = in_range(r, d, "rated_voltage", "V", VOLTAGE_V)
    else:
        raise r.fail("motor.supply_voltage", "is required (or give rated_voltage)")
    return values


def _flywheel_inertia(r: Reader, d: dict) -> float:
    """The flywheels' inertia [kg m^2]: ``flywheel_inertia``, or the sum of the ``flywheels``
    (solid disks from diameter, thickness, density and count)."""
    if "flywheel_inertia" in d and "flywheels" in d:
        raise r.fail("motor.flywheels", "give either flywheel_inertia or flywheels, not both")
    J_fw = r.quantity(d.get("flywheel_inertia", "0 kg*m^2"), "motor.flywheel_inertia", "kg*m**2", nonnegative=True)
    fws = d.get("flywheels", [])
    if not isinstance(fws, list):
        raise r.fail("motor.flywheels", "must be a list of tables", fws)
    for i, fw in enumerate(fws):
        fk = f"motor.flywheels[{i}]"
        f = r.table(fw, fk, {"diameter", "thickness", "density", "count"}, {"diameter", "thickness", "density"})
        radius = 0.5 * r.quantity(f["diameter"], f"{fk}.diameter", "m", positive=True)
        mass = (r.quantity(f["density"], f"{fk}.density", "kg/m**3", positive=True) * math.pi * radius**2 *
                r.quantity(f["thickness"], f"{fk}.thickness", "m", positive=True))
        J_fw += r.number(f.get("count", 1), f"{fk}.count", int, positive=True) * 0.5 * mass * radius**2   # solid disk
        if not J_fw <= MAX_MAGNITUDE:
            raise r.fail(fk, f"has an inertia of {J_fw:.3g} kg m^2: no rig is that size (check its numbers and units)")
    return J_fw


def _drive_train(r: Reader, d: dict) -> dict:
    """Gear ratio, flywheel inertia [kg m^2], shaft stiffness [N m/rad] and damping [N m s/rad],
    and whether the drive may reverse."""
    values = {"gear_ratio": r.number(d.get("gear_ratio", 1.0), "motor.gear_ratio", positive=True),
              "flywheel_inertia_kg_m2": _flywheel_inertia(r, d)}
    if "shaft_stiffness" in d:
        values["shaft_stiffness_Nm_rad"] = r.quantity(d["shaft_stiffness"], "motor.shaft_stiffness", "N*m/rad",
                                                      positive=True)
    values["shaft_damping_Nm_s_rad"] = r.quantity(d.get("shaft_damping", "0 N*m*s/rad"), "motor.shaft_damping",
                                                  "N*m*s/rad", nonnegative=True)
    values["reversible"] = r.number(d.get("reversible", False), "motor.reversible", bool)
    return values


def _setpoint(r: Reader, d: dict, drive: DriveSpec) -> SetPoint:
    """The speed set-point: the drive's speed [rad/s], reached by a constant, ramp or step profile."""
    sp = r.table(d.get("setpoint", {}), "motor.setpoint", {"profile", "start", "t0", "duration"})
    speed = drive.speed_rad_s
    sign = -1.0 if speed < 0 else 1.0
    return SetPoint(r.number(sp.get("profile", "constant"), "motor.setpoint.profile",
                             choices=("constant", "ramp", "step")), speed,
                    sign * r.quantity(sp.get("start", "0 rpm"), "motor.setpoint.start", "rad/s", nonnegative=True),
                    r.quantity(sp.get("t0", "0 s"), "motor.setpoint.t0", "s", nonnegative=True),
                    r.quantity(sp.get("duration", "0 s"), "motor.setpoint.duration", "s", nonnegative=True))


def _controller(r: Reader, d: dict) -> tuple:
    """``(controller table, its values)``: the current limit [A] and, when given, the PI gains
    (kp [V s/rad], ki [V/rad]); a bandwidth instead of gains is designed by :func:`_parameters`."""
    ctrl = r.table(d.get("controller", {}), "motor.controller", {"bandwidth", "kp", "ki", "current_bandwidth",
                                                                 "current_limit"})
    values = {}
    if "current_limit" in ctrl:
        values["current_limit_A"] = r.quantity(ctrl["current_limit"], "motor.controller.current_limit", "A",
                                               positive=True)
    if "bandwidth" in ctrl and ("kp" in ctrl or "ki" in ctrl):
        raise r.fail("motor.controller", "give either bandwidth or kp and ki")
    if "kp" in ctrl or "ki" in ctrl:
        values["kp_V_s_rad"] = r.quantity(ctrl.get("kp", "0 V*s/rad"), "motor.controller.kp", "V*s/rad",
                                          nonnegative=True)
        values["ki_V_rad"] = r.quantity(ctrl.get("ki", "0 V/rad"), "motor.controller.ki", "V/rad", nonnegative=True)
    return ctrl, values


def _parameters(r: Reader, values: dict, ctrl: dict, mech) -> MotorParameters:
    """The motor's parameters; without PI gains, the gains designed for the speed-loop bandwidth
    [Hz] (default 2 Hz) on the linkage's mean reflected inertia over a revolution."""
    try:
        params = MotorParameters(**values)
        if "kp" not in ctrl and "ki" not in ctrl:
            bw = in_range(r, {"bandwidth": ctrl.get("bandwidth", "2 Hz")}, "bandwidth", "Hz", SPEED_BANDWIDTH_HZ,
                          "motor.controller")
            bwi = (in_range(r, ctrl, "current_bandwidth", "Hz", CURRENT_BANDWIDTH_HZ, "motor.controller")
                   if "current_bandwidth" in ctrl else None)
            params = params.with_gains_for(bw, float(np.mean(mech.crank_inertia(np.linspace(0, 2 * math.pi, 72,
                                                                                            endpoint=False))[0])), bwi)
        elif "current_bandwidth" in ctrl:
            raise r.fail("motor.controller.current_bandwidth", "needs bandwidth (the gains are designed from both)")
    except InputError as exc:
        raise r.fail("motor", str(exc)) from None
    return params


def motor(r: Reader, data, drive: DriveSpec, mech) -> MotorParameters:
    """The ``[motor]`` table of ``data`` read with ``r`` as :class:`cosim.motor.MotorParameters`
    (SI): constants given or derived from the rating, drive train, set-point (the drive's speed)
    and controller; a motor-driven ``drive`` has its set-point checked against the motor."""
    d = r.table(data, "motor", MOTOR_KEYS)
    values = _constants(r, d) | _drive_train(r, d)
    values["setpoint"] = _setpoint(r, d, drive)
    ctrl, controller = _controller(r, d)
    params = _parameters(r, values | controller, ctrl, mech)
    if drive.mode == "motor":
        try:
            params.check_setpoint()
        except InputError as exc:
            raise r.fail("drive.speed", str(exc)) from None
    return params
