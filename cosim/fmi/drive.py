"""An FMU as the master's drive (``[drive] type = "fmu"``): the FMU takes the crank speed (and
angle) and returns the torque on the crank, like the bench's motor on a torque-driven engine.

The FMU is checked against the scenario's mapping before a run (:func:`checked_model_description`):
a file that is not an FMU archive, an FMI version other than 2.0, a model-exchange-only FMU, a
missing variable, a non-real one or one of the wrong causality (torque an output; speed and angle
inputs; inertia a parameter) is refused with a message naming the file and the variable.

Coupling. Torque-driven engines (exudyn, MuJoCo) carry the drive's inertia on their crank; the
FMU steps over each engine sample interval with the crank speed at its middle. Kinematic engines
(the transfer-matrix model) take the crank motion: here the master's drive integrates the crank,
``(J + J_r(q)) alpha = T_fmu - T_load``, with Heun's method on the engine's sample grid (the FMU
stepped once per interval at the predicted mean speed), the same equation the bench's motor
integrates with its own torque. The iterated coupling repeats a macro step: the FMU's state is
then saved at the step's start and restored (fmi2GetFMUstate/fmi2SetFMUstate; an FMU without
them is refused for that scheme only).

The FMU runs in a process of its own (:mod:`cosim.fmi.host`): a crashing or interpreter-bound
binary (PythonFMU's) cannot take the master down.

Owns: ``FmuDrive``, ``checked_model_description``, ``FmuRefused``. Boundaries: the FMU file is
read by FMPy (imported here, lazily by cosim.drives); the coupling schemes are cosim.master's.
"""
from __future__ import annotations

import math
import re
import zipfile

import numpy as np

from tmm_core import InputError, TMMError

from ..motor import MotorState, MotorTrace
from ..units import UnitError, factor
from .drive_spec import FmuDriveSpec

#: The causalities each mapped signal may have.
CAUSALITIES = {"torque": ("output",), "speed": ("input",), "angle": ("input",),
               "inertia": ("parameter", "calculatedParameter", "constant")}


class FmuStepError(TMMError):
    """The FMU failed during a run (a failed step, a non-finite output, a step it cannot repeat):
    the master ends the engine's channel with it, as with an engine's failure. (A TMMError, not
    cosim.engines' EngineError: the drive sits below the master, which the engines' module
    imports.)"""


class FmuRefused(InputError):
    """An FMU does not fit its mapping; the message names the file and the variable."""


def checked_model_description(spec: FmuDriveSpec):
    """The FMU's model description (FMPy), checked against the mapping of ``spec``."""
    path = spec.file
    if not zipfile.is_zipfile(path):
        raise FmuRefused(f"FMU '{path}': not an FMU (a zip archive with a modelDescription.xml)")
    md = _read(path, validate=False)
    if md.fmiVersion != "2.0":
        raise FmuRefused(f"FMU '{path}': FMI version {md.fmiVersion}; the bench imports FMI 2.0 FMUs")
    if md.coSimulation is None:
        raise FmuRefused(f"FMU '{path}': model exchange only; the bench drives co-simulation FMUs "
                         f"(no <CoSimulation> element)")
    md = _read(path, validate=True)
    variables = {v.name: v for v in md.modelVariables}
    for key in ("torque", "speed", "angle", "inertia"):
        var = getattr(spec, key)
        if var is not None:
            _check_variable(path, var, variables, CAUSALITIES[key])
    return md


def _read(path: str, validate: bool):
    import fmpy
    try:
        return fmpy.read_model_description(path, validate=validate)
    except Exception as exc:          # FMPy raises zip, XML and validation errors of its own kinds
        raise FmuRefused(f"FMU '{path}': cannot be read ({type(exc).__name__}: {exc})") from None


def _check_variable(path, var, variables: dict, causalities: tuple) -> None:
    v = variables.get(var.name)
    if v is None:
        raise FmuRefused(f"FMU '{path}': no variable '{var.name}' ({var.key}); its variables: "
                         f"{', '.join(sorted(variables)[:20])}")
    if v.type != "Real":
        raise FmuRefused(f"FMU '{path}': variable '{var.name}' ({var.key}) is {v.type}, not Real")
    causality = "constant" if v.variability == "constant" else v.causality
    if causality not in causalities:
        raise FmuRefused(f"FMU '{path}': variable '{var.name}' ({var.key}) has causality '{v.causality}'; "
                         f"the mapping needs {' or '.join(causalities)}")
    fmu_unit = pint_spelling(v.unit) if v.unit else None
    if fmu_unit is not None:
        try:
            factor(var.unit, fmu_unit)
        except UnitError:
            raise FmuRefused(f"FMU '{path}': variable '{var.name}' ({var.key}) is in {v.unit}, not of the kind "
                             f"of the unit the scenario declares for it, {var.unit}") from None


def pint_spelling(fmi_unit: str) -> str | None:
    """An FMI unit name in pint's spelling (``"N.m"`` -> ``"N*m"``, ``"rad/s2"`` -> ``"rad/s**2"``),
    or None if pint cannot read it (the scenario's unit then stands unchecked)."""
    spelling = re.sub(r"([A-Za-z])(-?\d+)", r"\1**\2", fmi_unit.replace(".", "*"))
    try:
        factor(spelling, spelling)
    except UnitError:
        return None
    return spelling


class FmuDrive:
    """The master's drive from an FMU (see the module's docstring); the methods the master's
    channel uses are those of :class:`cosim.motor.Motor`."""

    p = None                 # no bench motor parameters: the FMU keeps its own

    def __init__(self, spec: FmuDriveSpec, integrates_crank: bool, repeatable: bool = True):
        self.spec, self.integrates_crank, self.repeatable = spec, integrates_crank, repeatable
        self.model_description = checked_model_description(spec)
        self.vr = {v.name: v.valueReference for v in self.model_description.modelVariables}
        self.can_restore = bool(self.model_description.coSimulation.canGetAndSetFMUstate)
        self.fmu, self.saved = None, None
        self.t, self.torque = 0.0, 0.0
        self._inertia = spec.inertia_kg_m2

    # -- FMU values in SI --------------------------------------------------------------------------
    def _get(self, var) -> float:
        return self.fmu.getReal([self.vr[var.name]])[0] * var.to_si

    def _set(self, var, value: float) -> None:
        if var is not None:
            self.fmu.setReal([self.vr[var.name]], [value / var.to_si])

    def _open(self, t0: float, crank_angle: float, crank_speed: float) -> None:
        """The FMU's process, instantiated and initialised with the crank at ``crank_angle``
        [rad] and ``crank_speed`` [rad/s] (the FMU decides its own start from them)."""
        from .host import FmuProcess
        self.close()
        md = self.model_description
        self.fmu = FmuProcess(self.spec.file, md.guid, md.coSimulation.modelIdentifier)
        self.fmu.instantiate()
        self.fmu.setupExperiment(None, t0)          # (tolerance, start time)
        self.fmu.enterInitializationMode()
        self._set(self.spec.speed, crank_speed)
        self._set(self.spec.angle, crank_angle)
        self.fmu.exitInitializationMode()
        if self.spec.inertia is not None:
            self._inertia = self._get(self.spec.inertia)
        if not self._inertia > 0:
            name = self.spec.inertia.name if self.spec.inertia else "drive.fmu.inertia"
            raise FmuRefused(f"FMU '{self.spec.file}': the drive inertia ({name}) is {self._inertia!r} kg m^2; "
                             f"it must be positive")

    @property
    def crank_side_inertia_kg_m2(self) -> float:
        """The drive's inertia turning with the crank [kg m^2]: the scenario's value, or the FMU's
        variable (read from an instance initialised for the purpose when asked before ``start``,
        as a torque-driven engine's reset asks)."""
        if self._inertia is None:
            self._open(0.0, 0.0, 0.0)
            self.close()
        return self._inertia

    def start(self, t0: float, crank_angle: float, crank_speed: float, load_torque: float = 0.0) -> MotorState:
        """Start the FMU with the crank at ``crank_angle`` [rad] and ``crank_speed`` [rad/s]."""
        self._open(t0, crank_angle, crank_speed)
        self.t, self.torque = t0, self._get(self.spec.torque)
        return self._state(t0, crank_angle, crank_speed)

    @staticmethod
    def _state(t, angle, speed) -> MotorState:
        nan = float("nan")
        return MotorState(float(t), nan, nan, float(angle), float(speed), float(angle), float(speed))

    def drive_torque_now(self, state: MotorState) -> float:
        """The FMU's torque output [N m] at its current time."""
        return self.torque

    def close(self) -> None:
        """End the FMU's process."""
        if self.fmu is not None:
            self.fmu.close()
            self.fmu, self.saved = None, None

    def __del__(self):
        try:
            self.close()
        except Exception:             # the interpreter may be shutting down
            pass

    # -- a macro step ----------------------------------------------------------------------------
    def _rewind(self, t: float) -> None:
        """Bring the FMU to ``t`` [s]: save it there if it is there, else restore the state
        saved there (a repeated macro step)."""
        if abs(self.t - t) <= 1e-12 * max(1.0, abs(t)):
            if self.can_restore and self.repeatable:
                if self.saved is not None:
                    self.fmu.freeFMUState(self.saved[1])
                self.saved = (t, self.fmu.getFMUState(), self.torque)
            return
        if self.saved is None or abs(self.saved[0] - t) > 1e-12 * max(1.0, abs(t)):
            raise FmuStepError(f"FMU '{self.spec.file}': asked to repeat a step from t = {t:.9g} s, and it "
                              f"{'has no saved state there' if self.can_restore else 'cannot restore its state (canGetAndSetFMUstate is false): use coupling.scheme jacobi or gauss_seidel'}")
        self.fmu.setFMUState(self.saved[1])
        self.t, self.torque = t, self.saved[2]

    def _step(self, t: float, h: float, angle: float, speed: float) -> float:
        """One FMU step from ``t`` by ``h`` [s] with the crank inputs held; the torque at its end [N m]."""
        spec, vrs, values = self.spec, [self.vr[self.spec.speed.name]], [speed / self.spec.speed.to_si]
        if spec.angle is not None:
            vrs.append(self.vr[spec.angle.name])
            values.append(angle / spec.angle.to_si)
        torque = self.fmu.step(t, h, vrs, values, [self.vr[spec.torque.name]])[0]
        self.t, self.torque = t + h, torque * spec.torque.to_si
        if not math.isfinite(self.torque):
            raise FmuStepError(f"FMU '{self.spec.file}': {self.spec.torque.name} is not finite at t = {self.t:.9g} s")
        return self.torque

    def advance(self, state: MotorState, t_next: float, *, crank=None, load_torque=None, load_inertia=None,
                samples=None, load_inertia_max: float = 0.0) -> tuple:
        """As :meth:`cosim.motor.Motor.advance`: ``crank(t) -> (angle, speed)`` for a
        torque-driven engine, ``load_torque(t)`` [N m] (and ``load_inertia(angle)`` [kg m^2]) for
        a kinematic one. Returns ``(new_state, MotorTrace)`` at ``samples`` (default ``t_next``);
        the trace's motor quantities the FMU does not give are NaN."""
        self._rewind(state.t)
        ts = np.atleast_1d(np.asarray([t_next] if samples is None else samples, dtype=float))
        edges = np.r_[state.t, ts]
        if self.integrates_crank:
            if load_torque is None:
                raise ValueError("a drive that integrates the crank needs load_torque")
            q, w, a, T = self._integrate(edges, state, load_torque, load_inertia)
        else:
            if crank is None:
                raise ValueError("a drive on a torque-driven engine needs the crank motion")
            T = np.array([self._step(t0, t1 - t0, *np.ravel(crank(np.array([t0, 0.5 * (t0 + t1)])))[[0, 3]])
                          for t0, t1 in zip(edges[:-1], edges[1:])])
            angle, speed = crank(ts)
            q, w, a = np.asarray(angle, float), np.asarray(speed, float), np.full(len(ts), np.nan)
        return self._state(t_next, q[-1], w[-1]), _trace(ts, T, q, w, a)

    def _integrate(self, edges, state, load_torque, load_inertia):
        """Heun's method for the crank, ``(J + J_r(q)) alpha = T_fmu - T_load``, on ``edges``."""
        J0 = self.crank_side_inertia_kg_m2
        inertia = (lambda q: J0 + float(load_inertia(q))) if load_inertia is not None else (lambda q: J0)
        loads = np.asarray(load_torque(edges), dtype=float) * np.ones(len(edges))
        q, w = state.crank_angle_rad, state.crank_speed_rad_s
        a = (self.torque - loads[0]) / inertia(q)
        out = np.empty((len(edges) - 1, 4))
        for k in range(len(edges) - 1):
            h = edges[k + 1] - edges[k]
            w_pred = w + h * a
            T1 = self._step(edges[k], h, q, 0.5 * (w + w_pred))
            a1 = (T1 - loads[k + 1]) / inertia(q + h * w)
            w_new = w + 0.5 * h * (a + a1)
            q, w, a = q + 0.5 * h * (w + w_new), w_new, a1
            out[k] = q, w, a, T1
        return out[:, 0], out[:, 1], out[:, 2], out[:, 3]


def _trace(ts, T, q, w, a) -> MotorTrace:
    nan = np.full(len(ts), np.nan)
    return MotorTrace(ts, nan, nan, nan, nan, np.asarray(T, float), q, w, a, nan, nan, nan, nan, nan, nan, nan, nan)
