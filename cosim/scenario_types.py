"""The scenario's data types: the resolved settings of every table, in SI (frozen dataclasses).

Owns: :class:`Scenario` (a moving linkage: four-bar, slider-crank or general linkage; a static
structure is :class:`cosim.structure_scenario.StaticScenario`), the settings per engine, the
drive, the output and coupling settings, :class:`Assumption` and :class:`ScenarioError`, and the
quantities derived from a crank speed (rpm, the revolution period; the TMM step in seconds is
:meth:`Scenario.engine_step_s`): no other module converts them. The
reader (:mod:`cosim.scenario_reader`) fills them; :mod:`cosim.scenario` loads files. Boundaries:
it imports no reader and no loader (``with_overrides`` calls the loader that built the scenario).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from tmm_core import Coupling, FourBarMechanism, InputError, SliderCrankMechanism, TimeDomain

from .overrides import OverrideError, apply_overrides


def to_rpm(speed_rad_s: float) -> float:
    """A crank speed [rad/s] in revolutions per minute, sign kept: the one place the bench
    converts between the two."""
    return speed_rad_s * 30.0 / math.pi


def from_rpm(rpm: float) -> float:
    """A crank speed [rev/min] in rad/s, sign kept (the inverse of :func:`to_rpm`)."""
    return rpm * math.pi / 30.0


def revolution_period_s(speed_rad_s: float) -> float:
    """The time [s] of one crank revolution at ``speed_rad_s`` [rad/s], either sign."""
    return 2 * math.pi / abs(speed_rad_s)


class ScenarioError(InputError):
    """A scenario file is malformed; the message names the file, the key and the value."""


@dataclass(frozen=True)
class Assumption:
    """A value the sources do not give, with the reason it was chosen."""

    key: str
    value: str
    rationale: str


class Variants:
    """``with_overrides`` for a loaded scenario of any kind (it has ``raw``, ``path``, ``name`` and
    ``loader``).

    ``loader`` is the function that built the scenario from its TOML tree
    (:func:`cosim.scenario.from_dict`, which sets it): a variant is built by the same loader. It is
    handed over rather than imported so that the types know no loader: the loader imports the
    types, never the reverse."""

    def with_overrides(self, overrides: dict):
        """A variant of this scenario with key paths of its file set to new values, e.g.
        ``{"drive.speed": "300 rpm", "links.coupler.damping.ratio": "3 %"}``, validated by the
        loader (its errors name the key)."""
        label = f"{self.path or self.name} (with {', '.join(f'{k} = {v!r}' for k, v in overrides.items())})"
        if self.loader is None:
            raise ScenarioError(f"scenario '{self.path or self.name}': built without a loader, so it has no variants "
                                "(load it with cosim.scenario.load or from_dict)")
        try:
            data = apply_overrides(self.raw, overrides)
        except OverrideError as exc:
            raise ScenarioError(f"scenario '{self.path or self.name}': {exc}") from None
        return self.loader(data, label, default_name=self.name)


@dataclass(frozen=True)
class DriveSpec:
    """Crank drive. ``speed_rad_s`` is signed (CCW positive); ``mode`` 'prescribed' or 'motor'."""

    mode: str = "prescribed"
    speed_rad_s: float = 0.0
    start_angle_rad: float = 0.0
    #: What drives the crank in 'motor' mode: "motor" (the [motor] table) or "fmu" (``fmu``, a
    #: :class:`cosim.fmi.drive_spec.FmuDriveSpec`: an FMU with its variables mapped).
    type: str = "motor"
    fmu: object = None

    @property
    def speed_rpm(self) -> float:
        """The drive speed in revolutions per minute, unsigned (the direction is the sign of
        ``speed_rad_s``): the one conversion the console, the summary and the sweeps print."""
        return abs(to_rpm(self.speed_rad_s))

    @property
    def period_s(self) -> float:
        """The time [s] of one crank revolution at the drive speed."""
        return revolution_period_s(self.speed_rad_s)


@dataclass(frozen=True)
class TMMSettings:
    segments: int = 8
    integrator: str = "generalized_alpha"
    step_s: float | None = None
    step_rad: float | None = math.radians(1.0)
    beam_column: bool = True
    start: str = "quasi_static"
    coupling: Coupling = Coupling.all()
    axial_force: str = "dynamic"
    #: "full" (every node) or "reduced" (link modes plus a static correction, tmm_core.reduced):
    #: periodic solves of sweeps, bands and identification; time-marching runs refuse "reduced".
    model: str = "full"
    #: Mode shapes of the reduced model (tmm_core.reduced.DEFAULT_MODES: docs/theory.md "Reduced model").
    modes: int = 4

    def step_s_at(self, speed_rad_s: float) -> float:
        """The time step [s]: ``step_s``, or the crank-angle step ``step_rad`` at ``speed_rad_s``."""
        return self.step_s if self.step_s is not None else self.step_rad / abs(speed_rad_s)


@dataclass(frozen=True)
class ExudynSettings:
    elements: int = 8
    step_s: float = 1e-4
    spectral_radius: float = 0.9
    newton_tolerance: float = 1e-6


@dataclass(frozen=True)
class MujocoSettings:
    step_s: float = 1e-4
    servo_frequency_Hz: float | None = None
    solref_factor: float = 2.0
    solimp: float = 0.9999


@dataclass(frozen=True)
class CouplingSettings:
    """Co-simulation coupling (see :mod:`cosim.master`). ``macro_step_s`` None: the largest engine
    step, if the others divide it."""

    macro_step_s: float | None = None
    scheme: str = "gauss_seidel"
    extrapolation: str = "linear"
    interface_jacobian: bool = True
    tolerance: float = 1e-6
    max_iterations: int = 20
    start: str = "steady"


@dataclass(frozen=True)
class OutputSettings:
    """``revolutions``: a fixed run length; None (default) runs until every engine is steady
    (its last two revolutions agree to ``steady_tolerance``, :mod:`cosim.metrics`) or until
    ``max_revolutions``."""

    revolutions: float | None = None
    engines: tuple = ("tmm", "exudyn", "mujoco")     # the engines `cosim run` uses by default
    max_revolutions: float = 30.0
    steady_tolerance: float = 0.005


@dataclass(frozen=True)
class Scenario(Variants):
    """A resolved scenario, SI throughout."""

    name: str
    description: str
    path: Path | None
    sources: tuple
    mechanism: FourBarMechanism | SliderCrankMechanism | object   # or a tmm_core.linkage mechanism
    drive: DriveSpec
    gauges: tuple
    gravity: tuple | None
    tmm: TMMSettings
    exudyn: ExudynSettings
    mujoco: MujocoSettings
    output: OutputSettings
    assumptions: tuple
    raw: dict = field(repr=False, default_factory=dict)
    motor: object = None                  # cosim.motor.MotorParameters, or None without a [motor] table
    coupling: CouplingSettings = CouplingSettings()
    rig: str | None = None                # the physical rig (records of it are matched by this name)
    #: The loader that built it, which builds its variants (:class:`Variants`).
    loader: object = field(default=None, repr=False, compare=False)

    def engine_step_s(self, engine: str) -> float:
        """Internal step of an engine [s]."""
        if engine == "tmm":
            if self.tmm.step_s is not None:
                return self.tmm.step_s
            if not self.drive.speed_rad_s:
                raise ScenarioError(f"scenario '{self.path}': key 'solver.tmm.step': a crank-angle step needs a "
                                    "non-zero drive.speed")
            return self.tmm.step_s_at(self.drive.speed_rad_s)
        return {"exudyn": self.exudyn.step_s, "mujoco": self.mujoco.step_s}[engine]

    @property
    def kind(self) -> str:
        """The linkage type of the file: 'four-bar', 'slider-crank' or 'linkage'."""
        t = self.raw.get("linkage", {}).get("type") if isinstance(self.raw.get("linkage"), dict) else None
        return t if t in ("four-bar", "slider-crank", "linkage") else "four-bar"

    @property
    def crank_speed_rad_s(self) -> float:
        return self.drive.speed_rad_s

    @property
    def revolution_period_s(self) -> float:
        """The time [s] of one crank revolution at the drive speed."""
        return self.drive.period_s

    def time_domain(self, mechanism=None, backend: str | None = None, dynamic_terms: tuple | None = None):
        """The transfer-matrix time domain (:class:`tmm_core.TimeDomain`) of this scenario with its
        ``solver.tmm`` settings, gravity and gauges; ``mechanism`` replaces the scenario's (e.g.
        the same four-bar with applied joint moments); ``backend`` and ``dynamic_terms`` as
        TimeDomain's (None: its default; e.g. ``('shortening', 'axial_force')`` for the
        second-order segments instead of the co-rotational ones)."""
        s = self.tmm
        terms = {} if dynamic_terms is None else {"dynamic_terms": tuple(dynamic_terms)}
        return TimeDomain(self.mechanism if mechanism is None else mechanism, integrator=s.integrator,
                          coupling=s.coupling, beam_column=s.beam_column, gravity=self.gravity, gauges=self.gauges,
                          axial_force=s.axial_force, backend=backend, **terms)
