"""Permanent-magnet DC motor with a PI speed controller, belt/gear reduction and flywheel.

Equations (SI; crank-side quantities without index m, motor-side with m; n = motor turns per
crank turn, so omega_m = n omega on a rigid shaft)::

    L di/dt      = V - R i - Ke omega_m                              armature
    T_em         = Kt i                                              electromagnetic torque
    T_f          = b omega_m + Tc tanh(omega_m / omega_c)            viscous + (regularised) Coulomb friction
    V            = clip(Kp e + x_I, 0 .. V_max) (or -V_max .. V_max) PI on the crank-speed error e
    dx_I/dt      = Ki e, frozen while V is saturated                 anti-windup (conditional integration)

or, with an inner current loop (cascade control, as in PWM and most SCR drives; optional)::

    i_ref        = clip(Kp_w e + x_w, -i_max .. i_max)               speed PI -> current reference
    V            = clip(Kp_i (i_ref - i) + x_i, 0 .. V_max)          current PI -> armature voltage
    dx_w/dt, dx_i/dt frozen while their outputs are saturated and the error drives further

Mechanics on a rigid shaft: the drive delivers ``T_drive = n (T_em - T_f)`` to the crank, and the
crank-side inertia ``J_eq = J_flywheel + n^2 J_rotor`` turns with the crank. Two couplings:

* torque-driven engines (exudyn, MuJoCo) carry ``J_eq`` on their crank; the motor integrates only
  (i, x_I) from the crank speed the engine returns, and hands back ``T_drive``;
* kinematically driven engines (TMM) report the load torque the linkage needs; the motor also
  integrates the crank: ``J_eq alpha = T_drive - T_load``, and hands back the crank motion.

An optional torsional shaft (stiffness, damping) between the rotor and the crank replaces the
rigid shaft: the motor then integrates the rotor (theta_m, omega_m) and hands the shaft torque to
the crank side. A macro step is integrated with classical Runge-Kutta on fixed substeps sized
from the fastest rate of the linearised equations (pure Python floats: the state has at most ten
entries, and fixed substeps put samples exactly on the engines' step grid).

Owns: the motor's physics: one right-hand side, its integration and traces. Boundaries: no
scenario parsing (cosim.motor_design).
"""
from __future__ import annotations

import math
import dataclasses
from dataclasses import dataclass, replace
import numpy as np

from tmm_core import ConvergenceError, InputError

from .scenario_types import to_rpm


@dataclass(frozen=True)
class SetPoint:
    """Crank speed set-point [rad/s]: 'constant' (value), 'ramp' (from start to value over
    duration_s, from t0_s), 'step' (start until t0_s, then value)."""

    profile: str = "constant"
    value: float = 0.0
    start: float = 0.0
    t0_s: float = 0.0
    duration_s: float = 0.0

    def __post_init__(self):
        if self.profile not in ("constant", "ramp", "step"):
            raise InputError(f"motor setpoint profile must be 'constant', 'ramp' or 'step', got {self.profile!r}")
        if self.profile == "ramp" and not self.duration_s > 0:
            raise InputError(f"motor setpoint ramp duration_s must be positive, got {self.duration_s!r}")

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        if self.profile == "constant":
            return np.full(t.shape, self.value)
        if self.profile == "step":
            return np.where(t < self.t0_s, self.start, self.value)
        x = np.clip((t - self.t0_s) / self.duration_s, 0.0, 1.0)
        return self.start + (self.value - self.start) * x

    @property
    def peak(self) -> float:
        return max(abs(self.value), abs(self.start))


@dataclass(frozen=True)
class MotorParameters:
    """Motor, drive train and controller (SI). ``assumptions`` keeps the rationale of each value
    the sources do not give."""

    resistance_ohm: float
    inductance_H: float
    torque_constant_Nm_A: float
    back_emf_V_s_rad: float
    rotor_inertia_kg_m2: float
    supply_voltage_V: float
    gear_ratio: float = 1.0
    flywheel_inertia_kg_m2: float = 0.0
    viscous_friction_Nm_s_rad: float = 0.0
    coulomb_friction_Nm: float = 0.0
    kp_V_s_rad: float = 0.0
    ki_V_rad: float = 0.0
    current_kp_V_A: float = 0.0           # > 0: inner current loop on (speed gains below then apply)
    current_ki_V_A_s: float = 0.0
    speed_kp_A_s_rad: float = 0.0
    speed_ki_A_rad: float = 0.0
    current_limit_A: float = math.inf
    setpoint: SetPoint = SetPoint()
    shaft_stiffness_Nm_rad: float | None = None
    shaft_damping_Nm_s_rad: float = 0.0
    reversible: bool = False
    assumptions: tuple = ()

    def __post_init__(self):
        positive = ("resistance_ohm", "inductance_H", "torque_constant_Nm_A", "back_emf_V_s_rad", "supply_voltage_V",
                    "gear_ratio")
        nonneg = ("rotor_inertia_kg_m2", "flywheel_inertia_kg_m2", "viscous_friction_Nm_s_rad", "coulomb_friction_Nm",
                  "kp_V_s_rad", "ki_V_rad", "shaft_damping_Nm_s_rad", "current_kp_V_A", "current_ki_V_A_s",
                  "speed_kp_A_s_rad", "speed_ki_A_rad")
        for name in positive:
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"motor {name} must be positive, got {v!r}")
        for name in nonneg:
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"motor {name} must not be negative, got {v!r}")
        if not self.current_limit_A > 0:
            raise InputError(f"motor current_limit_A must be positive, got {self.current_limit_A!r}")
        if self.shaft_stiffness_Nm_rad is not None and not self.shaft_stiffness_Nm_rad > 0:
            raise InputError(f"motor shaft_stiffness_Nm_rad must be positive, got {self.shaft_stiffness_Nm_rad!r}")
        if self.rotor_inertia_kg_m2 + self.flywheel_inertia_kg_m2 <= 0:
            raise InputError("motor rotor_inertia_kg_m2 and flywheel_inertia_kg_m2 cannot both be zero")

    def check_setpoint(self) -> None:
        """Refuse a set-point the supply cannot reach. Checked when the motor drives a run (a
        scenario run at a prescribed speed keeps its [motor] table for later without it)."""
        top = self.no_load_crank_speed()
        if self.setpoint.peak > top:
            raise InputError(f"motor setpoint {self.setpoint.peak:.6g} rad/s ({to_rpm(self.setpoint.peak):.5g} "
                             f"rpm at the crank) is above the {top:.6g} rad/s ({to_rpm(top):.5g} rpm) the "
                             f"{self.supply_voltage_V:.4g} V supply allows (no load, Ke = {self.back_emf_V_s_rad:.4g} V s/rad, "
                             f"gear ratio {self.gear_ratio:.4g})")

    @property
    def voltage_range(self) -> tuple:
        """Armature voltages the drive can apply [V]: both polarities if reversible, otherwise the
        polarity of the set-point's direction of rotation (a one-quadrant drive)."""
        V = self.supply_voltage_V
        if self.reversible:
            return -V, V
        backwards = (self.setpoint.value or self.setpoint.start) < 0
        return (-V, 0.0) if backwards else (0.0, V)

    @property
    def crank_inertia_kg_m2(self) -> float:
        """Rotor and flywheel inertia seen at the crank on a rigid shaft [kg m^2]."""
        return self.flywheel_inertia_kg_m2 + self.gear_ratio**2 * self.rotor_inertia_kg_m2

    def no_load_crank_speed(self) -> float:
        """Highest steady crank speed at full voltage with only the motor's own friction [rad/s]."""
        # V = R i + Ke w_m, Kt i = b w_m + Tc  ->  w_m = (V - R Tc/Kt) / (Ke + R b / Kt)
        w_m = (self.supply_voltage_V - self.resistance_ohm * self.coulomb_friction_Nm / self.torque_constant_Nm_A) / \
              (self.back_emf_V_s_rad + self.resistance_ohm * self.viscous_friction_Nm_s_rad / self.torque_constant_Nm_A)
        return max(w_m, 0.0) / self.gear_ratio

    @property
    def current_loop(self) -> bool:
        return self.current_kp_V_A > 0

    def with_gains_for(self, bandwidth_Hz: float, load_inertia_kg_m2: float = 0.0,
                       current_bandwidth_Hz: float | None = None) -> "MotorParameters":
        """Controller gains for a speed loop of the given bandwidth, with J the crank-side inertia
        plus the linkage's mean reflected inertia ``load_inertia_kg_m2``.

        Without a current loop: a PI from speed error to voltage that cancels the mechanical pole
        of the plant K / (tau s + 1), K = 1 / (n Ke), tau = R J / (n^2 Kt Ke), giving a
        first-order loop (the armature inductance is neglected in the design, so a bandwidth
        near or above R / (2 pi L) rings).
        With ``current_bandwidth_Hz``: the current PI cancels the electrical pole (Kp_i = w_i L,
        Ki_i = w_i R; back-EMF acts as a slow disturbance) and the speed PI acts on the plant
        n Kt / (J s): Kp_w = w_c J / (n Kt), with its zero at w_c / 4 (phase margin about 76 deg)."""
        J = self.crank_inertia_kg_m2 + load_inertia_kg_m2
        n = self.gear_ratio
        wc = 2 * math.pi * bandwidth_Hz
        if current_bandwidth_Hz is None:
            K = 1.0 / (n * self.back_emf_V_s_rad)
            tau = self.resistance_ohm * J / (n**2 * self.torque_constant_Nm_A * self.back_emf_V_s_rad)
            kp = wc * tau / K
            return replace(self, kp_V_s_rad=kp, ki_V_rad=kp / tau, current_kp_V_A=0.0, current_ki_V_A_s=0.0)
        wi = 2 * math.pi * current_bandwidth_Hz
        kpw = wc * J / (n * self.torque_constant_Nm_A)
        return replace(self, current_kp_V_A=wi * self.inductance_H, current_ki_V_A_s=wi * self.resistance_ohm,
                       speed_kp_A_s_rad=kpw, speed_ki_A_rad=kpw * wc / 4.0, kp_V_s_rad=0.0, ki_V_rad=0.0)


@dataclass(frozen=True)
class MotorState:
    """Motor state at time ``t`` [s]; energies are cumulative from the start [J]."""

    t: float
    current_A: float
    integrator_V: float               # speed-loop integrator [V, or A with a current loop]
    crank_angle_rad: float = 0.0
    crank_speed_rad_s: float = 0.0
    rotor_angle_rad: float = 0.0      # compliant shaft only: rotor angle and speed in crank units (theta_m / n)
    rotor_speed_rad_s: float = 0.0
    energy_in_J: float = 0.0          # integral of V i
    copper_loss_J: float = 0.0        # integral of R i^2
    friction_loss_J: float = 0.0      # integral of T_f omega_m
    drive_work_J: float = 0.0         # integral of T_drive omega_crank (work delivered at the crank)
    current_integrator_V: float = 0.0 # current-loop integrator (cascade control only)

    @property
    def energies(self) -> np.ndarray:
        return np.array([self.energy_in_J, self.copper_loss_J, self.friction_loss_J, self.drive_work_J])


@dataclass
class MotorTrace:
    """Samples of the motor (one macro step or a whole run). Motor-side speed and torque are at
    the motor shaft; ``drive_torque_Nm`` is the torque the drive train delivers to the crank
    shaft (n (T_em - T_f), or the shaft torque with a compliant shaft), CCW positive."""

    t: np.ndarray
    current_A: np.ndarray
    voltage_V: np.ndarray
    torque_em_Nm: np.ndarray
    motor_speed_rad_s: np.ndarray
    drive_torque_Nm: np.ndarray
    crank_angle_rad: np.ndarray
    crank_speed_rad_s: np.ndarray
    crank_acceleration_rad_s2: np.ndarray
    setpoint_rad_s: np.ndarray
    electrical_power_W: np.ndarray
    copper_loss_W: np.ndarray
    friction_loss_W: np.ndarray
    energy_in_J: np.ndarray
    copper_loss_J: np.ndarray
    friction_loss_J: np.ndarray
    drive_work_J: np.ndarray

    UNITS = {"current_A": "A", "voltage_V": "V", "torque_em_Nm": "N m", "motor_speed_rad_s": "rad/s",
             "drive_torque_Nm": "N m", "crank_angle_rad": "rad", "crank_speed_rad_s": "rad/s",
             "crank_acceleration_rad_s2": "rad/s^2", "setpoint_rad_s": "rad/s", "electrical_power_W": "W",
             "copper_loss_W": "W", "friction_loss_W": "W", "energy_in_J": "J", "copper_loss_J": "J",
             "friction_loss_J": "J", "drive_work_J": "J"}

    @staticmethod
    def concatenate(traces: list) -> "MotorTrace":
        names = [f.name for f in dataclasses.fields(MotorTrace)]
        if not traces:
            return MotorTrace(*[np.zeros(0) for _ in names])
        return MotorTrace(*[np.concatenate([getattr(tr, n) for tr in traces]) for n in names])


class Motor:
    """One motor instance, coupled to one engine.

    ``integrates_crank``: True for kinematically driven engines (the motor integrates the crank
    with ``crank_inertia_kg_m2`` against a load torque); False for torque-driven engines (the crank
    speed comes from the engine, which carries the inertia).
    """

    def __init__(self, params: MotorParameters, integrates_crank: bool):
        self.p = params
        self.integrates_crank = integrates_crank
        self.compliant = params.shaft_stiffness_Nm_rad is not None
        self._ix = self.layout()

    @property
    def crank_side_inertia_kg_m2(self) -> float:
        """The inertia that turns with the crank: flywheel plus reflected rotor on a rigid shaft,
        the flywheel alone with a compliant shaft [kg m^2]."""
        p = self.p
        return p.flywheel_inertia_kg_m2 if self.compliant else p.crank_inertia_kg_m2

    # -- initial state ----------------------------------------------------------------------------
    def start(self, t0: float, crank_angle: float, crank_speed: float, load_torque: float = 0.0) -> MotorState:
        """Steady running at ``crank_speed`` [rad/s] (from rest: 0): current and integrator hold the
        speed against friction and the mean ``load_torque`` [N m at the crank]."""
        p = self.p
        wm = p.gear_ratio * crank_speed
        if crank_speed == 0:
            return MotorState(t0, 0.0, 0.0, crank_angle, 0.0, crank_angle, 0.0)
        i = (self.friction(wm) + load_torque / p.gear_ratio) / p.torque_constant_Nm_A
        v = p.resistance_ohm * i + p.back_emf_V_s_rad * wm
        # The shaft is twisted by the torque it carries.
        twist = 0.0 if not self.compliant else (p.gear_ratio * (p.torque_constant_Nm_A * i - self.friction(wm))
                                                / p.shaft_stiffness_Nm_rad)
        if p.current_loop:     # speed integrator holds the current, current integrator the voltage
            return MotorState(t0, i, i, crank_angle, crank_speed, crank_angle + twist, crank_speed,
                              current_integrator_V=v)
        return MotorState(t0, i, v, crank_angle, crank_speed, crank_angle + twist, crank_speed)

    def drive_torque_now(self, state: MotorState) -> float:
        """The drive torque in ``state``, n (Kt i - T_f(omega_m)) [N m] at the crank (with a
        compliant shaft in its steady start the shaft carries the same torque)."""
        p = self.p
        wm = p.gear_ratio * state.rotor_speed_rad_s
        return p.gear_ratio * (p.torque_constant_Nm_A * state.current_A - self.friction(wm))

    # -- the physics: one right-hand side -----------------------------------------------------------
    def friction(self, wm: float) -> float:
        """Motor friction torque [N m] at motor speed ``wm``: viscous plus Coulomb, the sign
        function regularised over 0.01 rad/s so the ODE stays smooth through standstill."""
        p = self.p
        return p.viscous_friction_Nm_s_rad * wm + p.coulomb_friction_Nm * math.tanh(wm / 0.01)

    def layout(self) -> dict:
        """Index of each integrated quantity in the state vector (which ones exist depends on
        the coupling and the drive train): current, speed-loop integrator, the four energies,
        the crank (kinematic engines), the rotor (compliant shaft), the current-loop integrator."""
        names = ["current", "integrator", "energy_in", "copper_loss", "friction_loss", "drive_work"]
        if self.integrates_crank:
            names += ["crank_angle", "crank_speed"]
        if self.compliant:
            names += ["rotor_angle", "rotor_speed"]
        if self.p.current_loop:
            names.append("current_integrator")
        return {name: k for k, name in enumerate(names)}

    def evaluate(self, y, setpoint: float, external: float, external_angle: float | None, load_inertia=None):
        """Right-hand side at one instant: ``(rates, values)`` for the state vector ``y``
        (:meth:`layout`), the speed set-point [rad/s] and the external signal (the load torque
        [N m] for a kinematic engine, else the engine's crank speed [rad/s] and angle [rad]).
        ``values`` holds the voltage, friction, electromagnetic, drive torque and crank
        acceleration (NaN for a torque-driven engine) at that instant."""
        p, ix = self.p, self._ix
        n = p.gear_ratio
        i, xI = y[ix["current"]], y[ix["integrator"]]
        th_c, w_c = (y[ix["crank_angle"]], y[ix["crank_speed"]]) if self.integrates_crank else (external_angle, external)
        th_m, w_m = (y[ix["rotor_angle"]], y[ix["rotor_speed"]]) if self.compliant else (th_c, w_c)
        lo, hi = p.voltage_range
        e = setpoint - w_c
        dxIi = None
        # Saturation with conditional integration: an integrator stops while its output is
        # saturated and the error drives it further.
        if p.current_loop:
            i_ref, dxI = _saturated(p.speed_kp_A_s_rad * e + xI, p.speed_ki_A_rad * e, e, -p.current_limit_A,
                                    p.current_limit_A)
            ei = i_ref - i
            v, dxIi = _saturated(p.current_kp_V_A * ei + y[ix["current_integrator"]], p.current_ki_V_A_s * ei, ei,
                                 lo, hi)
        else:
            v, dxI = _saturated(p.kp_V_s_rad * e + xI, p.ki_V_rad * e, e, lo, hi)
        wm = n * w_m
        Tf = self.friction(wm)
        T_em = p.torque_constant_Nm_A * i
        T_motor = n * (T_em - Tf)
        T_drive = (p.shaft_stiffness_Nm_rad * (th_m - th_c) + p.shaft_damping_Nm_s_rad * (w_m - w_c)
                   if self.compliant else T_motor)
        rates = [(v - p.resistance_ohm * i - p.back_emf_V_s_rad * wm) / p.inductance_H, dxI, v * i,
                 p.resistance_ohm * i * i, Tf * wm, T_drive * w_c]
        acc = float("nan")
        if self.integrates_crank:
            J = self.crank_side_inertia_kg_m2 + (float(load_inertia(th_c)) if load_inertia is not None else 0.0)
            acc = (T_drive - external) / J
            rates += [w_c, acc]
        if self.compliant:
            rates += [w_m, (T_motor - T_drive) / (n**2 * p.rotor_inertia_kg_m2)]
        if p.current_loop:
            rates.append(dxIi)
        return rates, {"voltage": v, "friction": Tf, "torque_em": T_em, "drive_torque": T_drive, "motor_speed": wm,
                       "crank_angle": th_c, "crank_speed": w_c, "crank_acceleration": acc}

    # -- integration over a macro step -------------------------------------------------------------
    def fastest_rate(self, load_inertia_max: float = 0.0) -> float:
        """Largest eigenvalue modulus [1/s] of the motor's linearised equations (electrical pole,
        speed loop, shaft torsion), which sets the Runge-Kutta substep."""
        p = self.p
        n = p.gear_ratio
        J = self.crank_side_inertia_kg_m2 + (load_inertia_max if self.integrates_crank else 0.0)
        rates = [p.resistance_ohm / p.inductance_H,
                 (p.resistance_ohm + p.current_kp_V_A) / p.inductance_H,
                 n * p.torque_constant_Nm_A * p.speed_kp_A_s_rad / max(J, 1e-12),
                 n**2 * p.torque_constant_Nm_A * p.back_emf_V_s_rad / (p.resistance_ohm * max(J, 1e-12)),
                 p.kp_V_s_rad * n * p.torque_constant_Nm_A / (p.resistance_ohm * max(J, 1e-12)),
                 # the regularised Coulomb friction is a steep viscous law near standstill
                 n**2 * p.coulomb_friction_Nm / 0.01 / max(J + n**2 * p.rotor_inertia_kg_m2, 1e-12)]
        if self.compliant:
            Jm = n**2 * p.rotor_inertia_kg_m2
            k = p.shaft_stiffness_Nm_rad
            rates.append(math.sqrt(k / Jm + k / max(J, 1e-12)))
            rates.append(p.shaft_damping_Nm_s_rad * (1 / Jm + 1 / max(J, 1e-12)))
        return max(rates)

    def advance(self, state: MotorState, t_next: float, *, crank=None, load_torque=None, load_inertia=None,
                samples=None, load_inertia_max: float = 0.0) -> tuple:
        """Integrate from ``state.t`` to ``t_next`` [s] with classical Runge-Kutta (fixed substeps,
        |lambda| h <= 0.1 for the fastest rate of :meth:`fastest_rate`: local error ~1e-7 relative).

        Torque-driven engine: ``crank(t) -> (angle, speed)`` (vectorised over t) is the crank
        motion over the step (the engine's, held, extrapolated or interpolated by the master).
        Kinematic engine: ``load_torque(t)`` [N m] (vectorised) is the torque the linkage takes at
        the crank; ``load_inertia(angle)`` [kg m^2] (optional, vectorised, at most
        ``load_inertia_max``) is an interface Jacobian, the part of the load proportional to the
        crank acceleration: the crank then obeys ``(J + load_inertia) alpha = T_drive -
        load_torque`` (the master moves that part out of ``load_torque``).
        ``samples``: increasing times in (state.t, t_next] at which to return the trace, the last
        ``t_next`` (default: ``t_next`` only). Returns ``(new_state, MotorTrace)``.
        """
        p = self.p
        if self.integrates_crank and load_torque is None:
            raise ValueError("a motor that integrates the crank needs load_torque")
        if not self.integrates_crank and crank is None:
            raise ValueError("a motor on a torque-driven engine needs the crank motion")
        ts = np.atleast_1d(np.asarray([t_next] if samples is None else samples, dtype=float))
        if abs(ts[-1] - t_next) > 1e-12 * max(1.0, abs(t_next)) or np.any(np.diff(np.r_[state.t, ts]) <= 0):
            raise ValueError("motor samples must increase from the state's time and end at t_next")
        # Substeps: every sample interval is cut into m equal steps; stage times on a half-step grid.
        edges = np.r_[state.t, ts]
        m = max(1, int(math.ceil(np.max(np.diff(edges)) * self.fastest_rate(load_inertia_max) / 0.1)))
        half = np.concatenate([a + (b - a) * np.arange(2 * m) / (2 * m) for a, b in zip(edges[:-1], edges[1:])] +
                              [edges[-1:]])
        # External signals at every stage time, vectorised.
        sp = p.setpoint(half)
        if self.integrates_crank:
            ext = np.asarray(load_torque(half), dtype=float) * np.ones_like(half)
        else:
            ang, spd = crank(half)
            ext = np.asarray(spd, dtype=float) * np.ones_like(half)
            ext_angle = np.asarray(ang, dtype=float) * np.ones_like(half)
        kinematic = self.integrates_crank
        angles = None if kinematic else ext_angle

        def rates(j, y):
            """Time derivatives at stage index j (on the half-step grid) of the state list y."""
            return self.evaluate(y, sp[j], ext[j], None if kinematic else angles[j], load_inertia)[0]

        ix = self._ix
        y = [0.0] * len(ix)
        y[ix["current"]], y[ix["integrator"]] = state.current_A, state.integrator_V
        for k, name in enumerate(("energy_in", "copper_loss", "friction_loss", "drive_work")):
            y[ix[name]] = float(state.energies[k])
        if kinematic:
            y[ix["crank_angle"]], y[ix["crank_speed"]] = state.crank_angle_rad, state.crank_speed_rad_s
        if self.compliant:
            y[ix["rotor_angle"]], y[ix["rotor_speed"]] = state.rotor_angle_rad, state.rotor_speed_rad_s
        if p.current_loop:
            y[ix["current_integrator"]] = state.current_integrator_V
        nY = len(y)
        Y = np.empty((len(ts), nY))
        dts = np.diff(edges) / m
        j = 0
        for s_idx, h in enumerate(dts):
            for _ in range(m):
                k1 = rates(j, y)
                y2 = [a + 0.5 * h * d for a, d in zip(y, k1)]
                k2 = rates(j + 1, y2)
                y3 = [a + 0.5 * h * d for a, d in zip(y, k2)]
                k3 = rates(j + 1, y3)
                y4 = [a + h * d for a, d in zip(y, k3)]
                k4 = rates(j + 2, y4)
                y = [a + h / 6.0 * (d1 + 2 * d2 + 2 * d3 + d4) for a, d1, d2, d3, d4 in zip(y, k1, k2, k3, k4)]
                j += 2
            Y[s_idx] = y
        if not np.all(np.isfinite(Y)):
            raise ConvergenceError(f"motor integration produced non-finite values before t = {t_next:.6g} s")
        return self._trace(state, t_next, ts, Y, half[2 * m::2 * m], sp[2 * m::2 * m], ext[2 * m::2 * m],
                           None if kinematic else ext_angle[2 * m::2 * m], load_inertia)

    def _trace(self, state, t_next, ts, Y, t_check, sp, ext, ext_angle, load_inertia):
        """Motor trace at the sample times from the integrated states ``Y`` (samples x states),
        through the same right-hand side as the integration (:meth:`evaluate`)."""
        p, ix = self.p, self._ix
        values = [self.evaluate(Y[k], sp[k], ext[k], None if ext_angle is None else ext_angle[k], load_inertia)[1]
                  for k in range(len(ts))]
        col = {key: np.array([v[key] for v in values], dtype=float) for key in values[0]}
        i, v = Y[:, ix["current"]], col["voltage"]
        w_m = Y[:, ix["rotor_speed"]] if self.compliant else col["crank_speed"]
        th_m = Y[:, ix["rotor_angle"]] if self.compliant else col["crank_angle"]
        energies = [Y[:, ix[name]] for name in ("energy_in", "copper_loss", "friction_loss", "drive_work")]
        new = MotorState(float(t_next), float(i[-1]), float(Y[-1, ix["integrator"]]), float(col["crank_angle"][-1]),
                         float(col["crank_speed"][-1]), float(th_m[-1]), float(w_m[-1]), *(float(e[-1]) for e in energies),
                         float(Y[-1, ix["current_integrator"]]) if p.current_loop else 0.0)
        trace = MotorTrace(ts, i, v, col["torque_em"], col["motor_speed"], col["drive_torque"], col["crank_angle"],
                           col["crank_speed"], col["crank_acceleration"], sp, v * i, p.resistance_ohm * i**2,
                           col["friction"] * col["motor_speed"], *energies)
        return new, trace


def _saturated(value, rate, error, lo, hi):
    """A controller output clipped to [lo, hi] and its integrator's rate, held at zero while the
    output is saturated and the error drives it further (conditional-integration anti-windup)."""
    if value > hi:
        return hi, (0.0 if error > 0 else rate)
    if value < lo:
        return lo, (0.0 if error < 0 else rate)
    return value, rate
