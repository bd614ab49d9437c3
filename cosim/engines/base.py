"""Engine protocol shared by the transfer-matrix, exudyn and MuJoCo engines.

Sign conventions (all engines): crank angle from the ground line A->D, counter-clockwise
positive, radians; the *drive torque* is the moment the linkage takes at the crank pivot,
counter-clockwise positive [N m] (the torque a drive must apply to the crank to move the
linkage; when an engine also carries the drive's own inertia, that inertia's share
J_drive alpha is not included); gauge strains are dimensionless, positive = tension on the
gauged face (:class:`tmm_core.Gauge`), bending = that face's bending strain, axial = N/EA.
Node positions are global [m].

A master advances every engine over macro steps with :meth:`Engine.advance`. A drive input is
either a *prescribed* crank motion (a function of time returning angle, speed, acceleration;
the engine follows it and reports the torque it takes) or a *torque* (the engine integrates the
crank motion; kinematically driven engines refuse it).

Engines are either *kinematic* (``kinematic = True``: the crank motion is an input, as in the
transfer-matrix model with the crank clamped at its pivot) or *torque-driven* (they integrate the
crank; a motor coupled to them puts its rotor and flywheel inertia on their crank through
``reset(..., drive_inertia_kg_m2=...)``). ``save()``/``restore()`` let a master repeat a macro
step (iterated coupling).

Owns: the engine protocol, ``EngineOutput``/``DriveInput``/``EngineRun``. Boundaries: no
engine-specific code; the run loop itself (and ``run_prescribed``, one engine through it) is
cosim.master, which engines never import.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np

from tmm_core.revolution import last_revolution
from ..scenario import Scenario

CrankProfile = Callable[[np.ndarray], tuple]   # t [s] -> (angle [rad], speed [rad/s], acceleration [rad/s^2])


class EngineError(RuntimeError):
    """An engine cannot do what was asked (unsupported drive, solver failure)."""


class EngineUnavailable(EngineError):
    """The engine's library is missing or broken; the message says how to install it."""


@dataclass(frozen=True)
class DriveInput:
    """Drive of one macro step: exactly one of ``prescribed`` and ``torque``.

    ``torque`` [N m] is a constant over the step or a function of time. ``ahead``: the
    prescribed profile is the crank's whole history, valid beyond this macro step too (a
    prescribed-speed run; not a motor's extrapolation), so an engine may compute ahead;
    ``until`` [s]: with ``ahead``, the last time the run will ask for (its end; None: not
    known), beyond which computing ahead is wasted.
    """

    prescribed: CrankProfile | None = None
    torque: float | Callable | None = None
    ahead: bool = False
    until: float | None = None

    def __post_init__(self):
        if (self.prescribed is None) == (self.torque is None):
            raise ValueError("DriveInput needs exactly one of 'prescribed' and 'torque'")
        if self.ahead and self.prescribed is None:
            raise ValueError("DriveInput: 'ahead' needs a prescribed crank history")
        if self.until is not None and not self.ahead:
            raise ValueError("DriveInput: 'until' is the end of a history given 'ahead'")

    def torque_at(self, t):
        return self.torque(t) if callable(self.torque) else np.full(np.shape(t), float(self.torque))


@dataclass
class EngineOutput:
    """Samples of one macro step (the engine's output times in (t_start, t_next], the last at t_next)."""

    t: np.ndarray
    crank_angle: np.ndarray
    crank_speed: np.ndarray
    drive_torque: np.ndarray
    gauges: dict = field(default_factory=dict)        # {gauge: (bending, axial)}, each (k,)
    nodes: dict = field(default_factory=dict)         # {link: (k, n_nodes, 2)} deformed positions [m]
    extras: dict = field(default_factory=dict)        # {name: (unit, (k,) array)}


class Engine(Protocol):
    name: str
    kinematic: bool

    @property
    def internal_step_s(self) -> float: ...

    def reset(self, scenario: Scenario, t0: float, angle: float, speed: float,
              drive_inertia_kg_m2: float = 0.0) -> None: ...

    def initial_output(self) -> EngineOutput:
        """One sample at the reset time (drive torque NaN where the engine does not know it yet)."""

    def node_stations(self) -> dict:
        """{link: local x [m] of the nodes in EngineOutput.nodes} (after reset)."""

    def advance(self, t_next: float, drive: DriveInput) -> EngineOutput: ...

    def save(self): ...

    def restore(self, token) -> None: ...


def constant_speed_profile(speed: float, start_angle: float = 0.0, t0: float = 0.0) -> CrankProfile:
    """Crank at constant speed [rad/s] from ``start_angle`` at ``t0``."""
    def profile(t):
        t = np.asarray(t, dtype=float)
        return start_angle + speed * (t - t0), np.full(t.shape, speed), np.zeros(t.shape)
    return profile


def steps_in(t_start: float, t_next: float, step: float, engine: str) -> int:
    """Whole number of internal steps of length ``step`` in the macro step, or an error."""
    n = (t_next - t_start) / step
    if n < 0.5 or abs(n - round(n)) > 1e-6 * max(1.0, n):
        raise EngineError(f"{engine}: the macro step {t_next - t_start:.9g} s is not a whole multiple of the "
                          f"internal step {step:.9g} s")
    return int(round(n))


@dataclass
class EngineRun:
    """Concatenated outputs of a run, one entry per sample."""

    engine: str
    t: np.ndarray
    crank_angle: np.ndarray
    crank_speed: np.ndarray
    drive_torque: np.ndarray
    gauges: dict
    nodes: dict
    extras: dict
    wall_time_s: float

    def last_revolution(self, period: float | None = None) -> np.ndarray:
        """Boolean mask of the samples in the last crank revolution, by crank angle
        (:func:`tmm_core.revolution.last_revolution`, the one definition of that window). ``period``
        [s] is accepted from older callers and not used: under a motor a revolution is not a
        fixed time."""
        return last_revolution(self.crank_angle)


def concatenate(engine: str, outputs: list, wall_time_s: float) -> EngineRun:
    def cat(arrays):
        return np.concatenate([np.atleast_1d(a) for a in arrays]) if arrays else np.zeros(0)
    gauges = {g: (cat([o.gauges[g][0] for o in outputs]), cat([o.gauges[g][1] for o in outputs]))
              for g in (outputs[0].gauges if outputs else {})}
    nodes = {k: np.concatenate([o.nodes[k] for o in outputs]) for k in (outputs[0].nodes if outputs else {})}
    extras = {k: (outputs[0].extras[k][0], cat([o.extras[k][1] for o in outputs]))
              for k in (outputs[0].extras if outputs else {})}
    return EngineRun(engine, cat([o.t for o in outputs]), cat([o.crank_angle for o in outputs]),
                     cat([o.crank_speed for o in outputs]), cat([o.drive_torque for o in outputs]),
                     gauges, nodes, extras, wall_time_s)
