"""Co-simulation master: every engine driven by its own simulated motor, or by a prescribed crank.

Time runs on a fixed macro step H: the end of macro step k is ``t0 + (k + 1) H``, computed from
the integer step count, never accumulated. H must be a whole multiple of every engine's internal
step. Each engine is one *channel* with its own drive (:func:`cosim.drives.make_drive`: a
:class:`cosim.motor.Motor`, or an FMU with ``[drive] type = "fmu"``, which the channel treats alike):

* torque-driven engines (exudyn, MuJoCo) carry the motor's rotor and flywheel inertia on their
  crank; the motor receives the engine's crank motion and returns the drive torque;
* kinematic engines (the transfer-matrix model, crank clamped) report the load torque the
  linkage takes; the motor integrates the crank against it and returns the crank motion.

Coupling schemes (``[coupling] scheme``):

``jacobi``
    engine and motor advance side by side from the interface values at the start of the step,
    each extrapolating the other's output (``extrapolation``: ``constant`` holds the last value,
    ``linear`` extrapolates the last two macro-step ends). Explicit; global error O(H) with
    constant and O(H^2) with linear extrapolation.
``gauss_seidel``
    one side goes first with extrapolated inputs, the other follows with the first side's actual
    trajectory over the step: torque-driven engines go first (the motor then sees the real crank
    speed), kinematic engines go second (they follow the motor's crank exactly). Same orders as
    Jacobi with smaller constants.
``iterated``
    the macro step is repeated (engine state saved and restored) until the interface signal
    changes by less than ``tolerance`` relative to its magnitude (fixed-point iteration, at most
    ``max_iterations``); the coupling error then vanishes up to the interpolation of the
    engine's samples.

``interface_jacobian`` (kinematic engines): the linkage's load torque contains J_r(q) q'', with
the rigid linkage's reflected inertia J_r (closed form). Left in the extrapolated load, it is an
explicit "added inertia" that makes the coupling unstable once J_r exceeds the drive's own
inertia (the FE crank-rocker's linkage reaches 1.6 times its motor-plus-flywheel inertia near
q = 0). With the Jacobian the motor integrates ``(J + J_r) q'' = T_drive - (T_load - J_r q'')``
and only the remainder is extrapolated.

``prescribed`` mode drives every engine at the scenario's constant crank speed (no motor), for a
like-for-like comparison of strains. Start-up is ``steady`` (at the set-point speed, current and
integrator in equilibrium) or ``rest``.

After every macro step ``callback(MacroStep)`` is called; returning True stops the run early. An
engine that fails stops only its own channel; every result up to the failure is kept. A
KeyboardInterrupt during the run ends it with status ``interrupted`` and the results so far.

Owns: ``CoSimulation``: macro steps, coupling schemes, motors per engine, the steady-state stop;
``run_prescribed`` (one engine through it).
Boundaries: no engine internals (protocol only) and no files (cosim.runs).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from tmm_core import InputError, TMMError

from .engines import make_engine
from .engines.base import DriveInput, EngineError, EngineRun, concatenate, constant_speed_profile
from .interface_signals import (ReflectedInertia, crank_extrapolation, crank_interpolation, extrapolate,
                                linear_interpolation)
from tmm_core.revolution import revolutions_completed

from .metrics import SteadyWatch, energy_balance, speed_fluctuation
from .drives import make_drive
from .motor import MotorState, MotorTrace
from .scenario import CouplingSettings, Scenario

MODES = ("prescribed", "motor")


# In prescribed mode the engines exchange nothing, so the macro step only sets how often the
# master collects outputs, checks the steady state, reports progress and can be interrupted: about
# 10 deg of crank angle keeps those fine-grained while the per-call costs of the engines and the
# master (~0.1-0.3 ms per macro step) are paid once for many engine steps.
PRESCRIBED_MACRO_DEG = 10.0


class CouplingError(EngineError):
    """An iterated macro step did not converge, or the coupling set-up is inconsistent."""


# -- results -------------------------------------------------------------------------------------
@dataclass
class ChannelResult:
    """One engine's run: its outputs, its motor's trace (None in prescribed mode), the number of
    coupling passes per macro step, and how it ended."""

    engine: str
    run: EngineRun
    motor: MotorTrace | None
    passes: np.ndarray
    status: str = "completed"           # completed | stopped | interrupted | failed
    error: str | None = None
    t0: float = 0.0
    angle0: float = 0.0
    motor_parameters: object = None     # cosim.motor.MotorParameters in motor mode
    #: The motor's current [A] and voltage [V] extremes over the whole run ({name: (min, max)}),
    #: kept even when the run holds only its last revolutions (``keep_revolutions``).
    motor_extrema: dict | None = None
    #: Macro steps the engine completed, the simulated time they make [s] (the integer count times
    #: the macro step) and the crank revolutions it travelled: the whole run's, also when the run
    #: holds only its last revolutions.
    macro_steps: int = 0
    sim_time_s: float = 0.0
    revolutions_run: float = 0.0

    def speed_fluctuation(self) -> dict:
        """Per-revolution crank speed statistics of the engine's crank (:func:`cosim.metrics.speed_fluctuation`),
        over the complete revolutions the run holds."""
        r = self.run
        return speed_fluctuation(r.t, r.crank_angle, r.crank_speed, self.angle0, self.t0)

    def energy_balance(self, t_start: float | None = None, t_end: float | None = None) -> dict:
        """Energy flows over a time window (:func:`cosim.metrics.energy_balance`)."""
        return energy_balance(self, t_start, t_end)


@dataclass
class CoSimResult:
    scenario: Scenario
    mode: str
    coupling: CouplingSettings
    macro_step_s: float
    t_end_s: float                      # t0 + sim_time_s
    channels: dict
    status: str                         # completed | stopped | interrupted | failed
    stop: str = "end"                   # why it ended: "end" (its length), "steady", or the status
    sim_time_s: float = 0.0             # macro steps run x macro step [s]

    def __getitem__(self, engine: str) -> ChannelResult:
        return self.channels[engine]


@dataclass
class MacroStep:
    """What a callback sees after macro step ``step`` (1-based) ending at ``t`` [s]."""

    step: int
    n_steps: int
    t: float
    outputs: dict                       # {engine: (EngineOutput, MotorTrace | None)}
    failed: dict = field(default_factory=dict)   # {engine: error message}, newly failed this step
    #: In a run until steady: {running engine: its last two revolutions' change} (relative, after
    #: two revolutions; cosim.metrics.SteadyWatch) and the tolerance that ends the run. None otherwise.
    change: dict | None = None
    steady_tolerance: float | None = None


# -- channels ------------------------------------------------------------------------------------
class _Channel:
    """One engine and (in motor mode) its motor, advanced macro step by macro step."""

    def __init__(self, name, engine, scenario: Scenario, mode: str, coupling: CouplingSettings,
                 keep_rad: float | None = None):
        self.name, self.engine, self.scenario, self.mode, self.c = name, engine, scenario, mode, coupling
        self.order = 1 if coupling.extrapolation == "linear" else 0
        self.outputs, self.traces, self.passes = [], [], []
        self.keep_rad = keep_rad            # crank angle of the outputs held (None: all of them)
        self.motor_extrema = {}
        self.motor = make_drive(scenario, integrates_crank=engine.kinematic,
                                repeatable=coupling.scheme == "iterated") if mode == "motor" else None
        self.J_r = None     # interface Jacobian, set at start
        self.t0, self.angle0, self.t_end = 0.0, 0.0, None
        self.steps, self.angle_end = 0, None   # macro steps done, the crank angle at the last one's end [rad]

    # -- start -----------------------------------------------------------------------------------
    def start(self, t0: float, angle: float, speed: float, t_end: float | None = None) -> None:
        """Reset the engine at ``t0`` [s]; ``t_end`` [s]: the run's last time, if known."""
        self.t0, self.angle0, self.t_end = t0, angle, t_end
        extra = {}
        if self.motor is not None and not self.engine.kinematic:
            extra["drive_inertia_kg_m2"] = self.motor.crank_side_inertia_kg_m2
        self.engine.reset(self.scenario, t0, angle, speed, **extra)
        if self.engine.kinematic and self.c.interface_jacobian and self.mode == "motor":
            # The engine's own rigid mass model if it has one, else the exact rigid linkage.
            source = getattr(self.engine, "reflected_inertia", None) or \
                (lambda q: self.scenario.mechanism.crank_inertia(q)[0])
            self.J_r = ReflectedInertia(source)
        if self.motor is None:
            self.profile = constant_speed_profile(self.scenario.drive.speed_rad_s, angle, t0)
            return
        self.state: MotorState = self.motor.start(t0, angle, speed)
        first = self.engine.initial_output()
        load = float(first.drive_torque[0]) if self.engine.kinematic else float("nan")
        # Interface values at the macro-step ends: crank (t, angle, speed, accel), the motor's drive
        # torque, and for kinematic engines the load torque the linkage takes.
        self.crank_hist = [(t0, angle, speed, 0.0)]
        self.drive_hist = [(t0, self._drive_torque_now())]
        self.load_hist = [(t0, load)]

    def _drive_torque_now(self) -> float:
        """The drive's torque in its current state [N m] (the motor's n (Kt i - T_f(omega_m)),
        an FMU drive's torque output)."""
        return self.motor.drive_torque_now(self.state)

    # -- one macro step ---------------------------------------------------------------------------
    def step(self, t_a: float, t_b: float):
        if self.motor is None:
            out = self.engine.advance(t_b, DriveInput(prescribed=self.profile, ahead=True, until=self.t_end))
            self.outputs.append(out)
            self.passes.append(1)
            self._done(out)
            self._release()
            return out, None
        h = self.engine.internal_step_s
        n = int(round((t_b - t_a) / h))
        samples = t_a + (t_b - t_a) * np.arange(1, n + 1) / n     # engine sample times, the last exactly t_b
        if self.engine.kinematic:
            out, trace, passes = self._kinematic_step(t_a, t_b, samples)
        else:
            out, trace, passes = self._torque_step(t_a, t_b, samples)
        self.outputs.append(out)
        self.traces.append(trace)
        self.passes.append(passes)
        for name in ("current_A", "voltage_V"):
            x = getattr(trace, name)
            if not np.all(np.isfinite(x)):
                continue            # an FMU drive does not give them (NaN)
            lo, hi = self.motor_extrema.get(name, (math.inf, -math.inf))
            self.motor_extrema[name] = (min(lo, float(np.min(x))), max(hi, float(np.max(x))))
        for hist in (self.crank_hist, self.drive_hist, self.load_hist):
            del hist[:-2]
        self._done(out)
        self._release()
        return out, trace

    def _done(self, out) -> None:
        """Count a completed macro step (the whole run's length, whatever the outputs held)."""
        self.steps += 1
        if len(out.crank_angle):
            self.angle_end = float(out.crank_angle[-1])

    def _release(self) -> None:
        """Drop the macro steps older than ``keep_rad`` of crank angle (they are in traces.csv
        already): the memory of a run stays bounded in its length."""
        if self.keep_rad is None:
            return
        newest = float(self.outputs[-1].crank_angle[-1])
        drop = 0
        while drop < len(self.outputs) - 1 and abs(newest - float(self.outputs[drop].crank_angle[-1])) > self.keep_rad:
            drop += 1
        if drop:
            del self.outputs[:drop]
            if self.traces:
                del self.traces[:drop]

    def _check(self, passes, t_b, new, old, hint):
        """True when the iterated interface signal has converged; raises after max_iterations.
        The change is measured against the largest signal seen so far in the run: near a zero
        crossing the instantaneous value is no scale, and an engine that iterates internally
        (the second-order TMM step) reproduces its torque only to its own tolerance."""
        change = float(np.max(np.abs(new - old)))
        self._scale = max(getattr(self, "_scale", 0.0), float(np.max(np.abs(new))))
        if change <= self.c.tolerance * max(self._scale, 1e-12):
            return True
        if passes >= self.c.max_iterations:
            raise CouplingError(f"{self.name}: iterated coupling did not converge in {self.c.max_iterations} passes "
                                f"before t = {t_b:.6g} s (last change {change:.3g} N m); {hint}")
        return False

    # torque-driven engine: the engine takes the motor torque, the motor takes the engine's crank.
    def _torque_step(self, t_a, t_b, samples):
        c = self.c
        torque_guess = lambda t: extrapolate(self.drive_hist, t, self.order)       # noqa: E731
        t_h, q_h, w_h, _ = self.crank_hist[-1]
        slope = 0.0
        if len(self.crank_hist) > 1 and self.order:
            slope = (w_h - self.crank_hist[-2][2]) / (t_h - self.crank_hist[-2][0])
        extrapolated = crank_extrapolation(t_h, q_h, w_h, slope)
        saved = self.engine.save() if c.scheme == "iterated" else None
        passes = 0
        while True:
            passes += 1
            if c.scheme == "jacobi":
                new_state, trace = self.motor.advance(self.state, t_b, crank=lambda t: extrapolated(t)[:2],
                                                      samples=samples)
                out = self.engine.advance(t_b, DriveInput(torque=torque_guess))
                break
            out = self.engine.advance(t_b, DriveInput(torque=torque_guess))
            crank = crank_interpolation(np.r_[t_a, out.t], np.r_[q_h, out.crank_angle], np.r_[w_h, out.crank_speed])
            new_state, trace = self.motor.advance(self.state, t_b, crank=lambda t: crank(t)[:2], samples=samples)
            if c.scheme == "gauss_seidel":
                break
            tt = np.r_[t_a, samples]
            T_new = np.r_[self.drive_hist[-1][1], trace.drive_torque_Nm]
            if self._check(passes, t_b, T_new, torque_guess(tt), "reduce coupling.macro_step"):
                break
            torque_guess = linear_interpolation(tt, T_new)
            self.engine.restore(saved)
        self.state = new_state
        self.crank_hist.append((t_b, float(out.crank_angle[-1]), float(out.crank_speed[-1]), 0.0))
        self.drive_hist.append((t_b, float(trace.drive_torque_Nm[-1])))
        return out, trace, passes

    # kinematic engine: the motor integrates the crank against the linkage's load torque.
    def _kinematic_step(self, t_a, t_b, samples):
        c = self.c
        t_h, q_h, w_h, a_h = self.crank_hist[-1]
        T_guess = lambda t: extrapolate(self.load_hist, t, self.order)     # noqa: E731
        accel_hist = [(t, a) for t, _, _, a in self.crank_hist]
        a_guess = lambda t: extrapolate(accel_hist, t, self.order)         # noqa: E731
        saved = self.engine.save() if c.scheme == "iterated" else None
        passes = 0
        while True:
            passes += 1
            load, inertia = self._load_functions(T_guess, a_guess, q_h, w_h, t_a)
            new_state, trace = self.motor.advance(self.state, t_b, load_torque=load, load_inertia=inertia,
                                                  samples=samples, load_inertia_max=self.J_r.max if self.J_r else 0.0)
            if c.scheme == "jacobi":
                profile = crank_extrapolation(t_a, q_h, w_h, a_h if self.order else 0.0)
            else:
                profile = crank_interpolation(np.r_[t_a, samples], np.r_[q_h, trace.crank_angle_rad],
                                               np.r_[w_h, trace.crank_speed_rad_s],
                                               np.r_[a_h, trace.crank_acceleration_rad_s2])
            out = self.engine.advance(t_b, DriveInput(prescribed=profile))
            if c.scheme != "iterated":
                break
            tt = np.r_[t_a, out.t]
            T_new = np.r_[self.load_hist[-1][1], out.drive_torque]
            if self._check(passes, t_b, T_new, T_guess(tt),
                           "reduce coupling.macro_step or set coupling.interface_jacobian = true"):
                break
            T_guess = linear_interpolation(tt, T_new)
            a_guess = linear_interpolation(np.r_[t_a, samples], np.r_[a_h, trace.crank_acceleration_rad_s2])
            self.engine.restore(saved)
        self.state = new_state
        self.crank_hist.append((t_b, new_state.crank_angle_rad, new_state.crank_speed_rad_s,
                                float(trace.crank_acceleration_rad_s2[-1])))
        self.drive_hist.append((t_b, float(trace.drive_torque_Nm[-1])))
        self.load_hist.append((t_b, float(out.drive_torque[-1])))
        return out, trace, passes

    def _load_functions(self, T_guess, a_guess, q_a, w_a, t_a):
        """The load torque (vectorised over time) and interface inertia the motor integrates against."""
        if self.J_r is None:
            return T_guess, None
        J_r = self.J_r

        def load(t):
            # The inertial part J_r(q) q'' of the guess moves to the motor's left-hand side; the
            # guess's angle is extrapolated (its error enters at second order only).
            t = np.asarray(t, dtype=float)
            return T_guess(t) - J_r(q_a + w_a * (t - t_a)) * a_guess(t)
        return load, J_r

    # -- results ---------------------------------------------------------------------------------
    def result(self, wall_time_s: float, status: str, error: str | None, macro_step_s: float) -> ChannelResult:
        """The channel's result; ``macro_step_s`` [s] turns its step count into simulated time."""
        run = concatenate(self.name, self.outputs, wall_time_s)
        motor = MotorTrace.concatenate(self.traces) if self.motor is not None else None
        revolutions = 0.0 if self.angle_end is None else revolutions_completed([self.angle0, self.angle_end])
        return ChannelResult(self.name, run, motor, np.array(self.passes, dtype=int), status, error,
                             self.t0, self.angle0, None if self.motor is None else self.motor.p,
                             dict(self.motor_extrema) if self.motor is not None else None,
                             self.steps, self.steps * macro_step_s, revolutions)


# -- the master ----------------------------------------------------------------------------------
def _settled(watch: SteadyWatch, outputs: dict, running: list) -> bool:
    """Feed a macro step's outputs to the watch; True when every running engine is steady."""
    for name, (out, _) in outputs.items():
        watch.add(name, out)
    verdicts = [watch.steady(n) for n in running]     # every engine's change, for the progress shown
    return all(verdicts)


def macro_step_for(scenario: Scenario, engines, coupling: CouplingSettings | None = None,
                   mode: str | None = None) -> float:
    """The macro step [s]: the scenario's, or the largest engine step if the others divide it.
    In ``mode`` 'prescribed' the engines exchange nothing: the scenario's macro step is the grid
    if every engine step divides it, else the largest engine step, and the master advances the
    engines by as many of those as make about PRESCRIBED_MACRO_DEG of crank angle (a whole
    fraction of a revolution where the revolution is a whole number of them). Raises
    :class:`CouplingError` naming the engine whose step does not divide it."""
    coupling = coupling or scenario.coupling
    steps = {e: scenario.engine_step_s(e) for e in engines}

    def misfit(H):
        """The first engine whose step does not divide ``H``, with the ratio, or None."""
        for e, h in steps.items():
            n = H / h
            if round(n) < 1 or abs(n - round(n)) > 1e-6 * max(1.0, n):
                return e, h, n
        return None
    H = coupling.macro_step_s if coupling.macro_step_s is not None else max(steps.values())
    if mode == "prescribed" and coupling.macro_step_s is not None and misfit(H) and not misfit(max(steps.values())):
        # Nothing is exchanged in prescribed mode: the coupling's macro step (a motor-mode setting)
        # need not fit the engines' steps there; the largest engine step is the grid instead.
        H = max(steps.values())
    bad = misfit(H)
    if bad:
        e, h, n = bad
        raise CouplingError(f"the macro step {H:.9g} s is not a whole multiple of the {e} step {h:.9g} s "
                            f"({n:.6g} times it); set coupling.macro_step or solver.{e}.step")
    if mode == "prescribed" and scenario.drive.speed_rad_s:
        per_rev = 2 * math.pi / (abs(scenario.drive.speed_rad_s) * H)       # macro steps of H per revolution
        most = max(1, int(per_rev * PRESCRIBED_MACRO_DEG / 360.0))
        if abs(per_rev - round(per_rev)) < 1e-6 * per_rev:
            most = max(d for d in range(1, most + 1) if round(per_rev) % d == 0)
        H *= most
    return H


class CoSimulation:
    """Run a scenario through several engines, each coupled to its own motor (or prescribed).

    ``engines``: names ('tmm', 'exudyn', 'mujoco') or ``{name: engine}`` (engines already built).
    ``mode``: 'prescribed' or 'motor' (default: the scenario's drive mode).
    """

    def __init__(self, scenario: Scenario, engines=("tmm",), mode: str | None = None,
                 coupling: CouplingSettings | None = None):
        self.scenario = scenario
        self.mode = mode or scenario.drive.mode
        if self.mode not in MODES:
            raise InputError(f"drive mode must be one of {MODES}, got {self.mode!r}")
        fmu_drive = scenario.drive.type == "fmu"
        if self.mode == "motor" and scenario.motor is None and not fmu_drive:
            raise InputError(f"scenario '{scenario.name}' has no [motor] table; run it in 'prescribed' mode or add one")
        if self.mode == "motor" and not fmu_drive:
            scenario.motor.check_setpoint()
        if not scenario.drive.speed_rad_s:
            raise InputError(f"scenario '{scenario.name}': drive.speed (the crank speed or set-point) must not be zero")
        self.coupling = coupling or scenario.coupling
        if isinstance(engines, dict):
            self.engines = dict(engines)
        else:
            if not engines:
                raise InputError("give at least one engine")
            self.engines = {name: make_engine(name) for name in engines}
        self.macro_step_s = macro_step_for(scenario, list(self.engines), self.coupling, self.mode)

    def duration_for(self, revolutions: float) -> float:
        """Simulated time [s] of ``revolutions`` at the set-point (or prescribed) crank speed."""
        return revolutions * self.scenario.revolution_period_s

    def run(self, duration_s: float | None = None, *, revolutions: float | None = None, callback=None,
            t0: float = 0.0, until_steady: bool | None = None, keep_revolutions: float | None = None) -> CoSimResult:
        """Advance every engine to ``duration_s`` (or ``revolutions`` at the set-point speed;
        default: the scenario's output revolutions), rounded up to whole macro steps.
        ``until_steady`` (default: when neither a length nor the scenario's output.revolutions is
        given): end as soon as every running engine is steady (:class:`cosim.metrics.SteadyWatch`,
        the scenario's ``output.steady_tolerance``), at the latest after ``output.max_revolutions``.
        ``keep_revolutions``: hold only the last that many crank revolutions of each engine's
        outputs (a caller that streams every macro step elsewhere, as ``cosim run`` does to
        traces.csv, keeps its memory bounded in run length); default: the whole run."""
        sc, H = self.scenario, self.macro_step_s
        if until_steady is None:
            until_steady = duration_s is None and revolutions is None and sc.output.revolutions is None
        if duration_s is None:
            if revolutions is None:
                revolutions = sc.output.max_revolutions if sc.output.revolutions is None else sc.output.revolutions
            duration_s = self.duration_for(revolutions)
        if not duration_s > 0:
            raise InputError(f"duration must be positive, got {duration_s!r} s")
        n_steps = int(math.ceil(duration_s / H - 1e-9))
        start_speed = sc.drive.speed_rad_s
        if self.mode == "motor":
            # An FMU drive starts at the drive speed (its own set-point is inside the FMU).
            setpoint = sc.drive.speed_rad_s if sc.drive.type == "fmu" else float(sc.motor.setpoint(t0))
            start_speed = 0.0 if self.coupling.start == "rest" else setpoint
        angle0 = sc.drive.start_angle_rad

        channels, clocks, status, errors = {}, {}, {}, {}
        for name, engine in self.engines.items():
            ch = channels[name] = _Channel(name, engine, sc, self.mode, self.coupling,
                                           None if keep_revolutions is None else 2 * math.pi * keep_revolutions)
            tic = time.perf_counter()
            try:
                ch.start(t0, angle0, start_speed, t_end=t0 + n_steps * H)
                status[name] = "running"
            except (EngineError, TMMError) as exc:
                status[name], errors[name] = "failed", str(exc)
            clocks[name] = time.perf_counter() - tic      # wall time includes the set-up
        stopped, reason = None, "end"
        watch = SteadyWatch(sc.output.steady_tolerance) if until_steady else None
        try:
            for k in range(n_steps):
                t_a, t_b = t0 + k * H, t0 + (k + 1) * H
                outputs, failed = {}, {}
                for name, ch in channels.items():
                    if status[name] != "running":
                        continue
                    tic = time.perf_counter()
                    try:
                        outputs[name] = ch.step(t_a, t_b)
                    except (EngineError, TMMError) as exc:
                        status[name], errors[name] = "failed", str(exc)
                        failed[name] = str(exc)
                    clocks[name] += time.perf_counter() - tic
                running = [n for n, s in status.items() if s == "running"]
                settled = bool(running) and watch is not None and _settled(watch, outputs, running)
                change = None if watch is None else {n: watch.change[n] for n in running if n in watch.change}
                if callback is not None and callback(MacroStep(k + 1, n_steps, t_b, outputs, failed, change,
                                                               None if watch is None else watch.tolerance)):
                    stopped = reason = "stopped"
                    break
                if not running:
                    break
                if settled:
                    reason = "steady"
                    break
        except KeyboardInterrupt:
            # Ctrl-C (or SIGTERM turned into it by the caller): keep every completed macro step.
            stopped = reason = "interrupted"
        results = {}
        for name, ch in channels.items():
            st = status[name]
            if st == "running":
                st = stopped or "completed"
            results[name] = ch.result(clocks[name], st, errors.get(name), H)
        sts = {r.status for r in results.values()}
        overall = next((s for s in ("failed", "interrupted", "stopped") if s in sts), "completed")
        sim_time = max(r.sim_time_s for r in results.values())
        return CoSimResult(sc, self.mode, self.coupling, H, t0 + sim_time, results, overall, reason, sim_time)


def run_prescribed(engine, scenario: Scenario, revolutions: float | None = None) -> EngineRun:
    """Drive one engine at the scenario's constant crank speed for ``revolutions`` (default: the
    scenario's output setting; without one, until the engine is steady or the scenario's
    ``output.max_revolutions``). It is the co-simulation master's prescribed mode with a single
    engine (one run loop, the scenario's macro step); an engine failure raises its error."""
    result = CoSimulation(scenario, {engine.name: engine}, mode="prescribed").run(revolutions=revolutions)
    channel = result[engine.name]
    if channel.status == "failed":
        raise EngineError(channel.error)
    if channel.status == "interrupted":
        raise KeyboardInterrupt
    return channel.run
