"""The ``[uncertainty]`` table of a scenario: its declared unknowns read and checked, and a
sample turned into what it changes (:class:`Variant`).

Owns: :class:`Unknown`, :func:`declared`, :func:`variant` and the model and measurement keys
they know. Boundaries: light (no solver imports), so that the scenario loader checks the table
at load (:mod:`cosim.scenario`) and the studies (:mod:`cosim.unknowns`, uncertainty, identify)
read it from here: imports run one way, loader -> this module.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from .scenario_types import ScenarioError
from .units import UREG

MODEL_KEYS = {
    "model.drive_inertia": "kg*m**2",
    "model.gravity_in_plane": "",
    "model.gravity_direction": "rad",
    "model.joint_moment.C": "N*m",
    "model.joint_moment.D": "N*m",
    "model.joint_stiffness.C": "N*m/rad",
    "model.joint_stiffness.D": "N*m/rad",
    "model.joint_friction": "N*m",
}
_FACE = re.compile(r"^gauges\.(\w+)\.face$")
_POLARITY = re.compile(r"^measurement\.polarity\.(\w+)$")
DISTRIBUTIONS = ("uniform", "loguniform", "normal", "choice")


@dataclass(frozen=True)
class Unknown:
    """One declared unknown. Continuous values are numbers in ``unit``; a choice's values are
    the TOML values as written."""

    name: str
    keys: tuple
    distribution: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    mean: float | None = None
    std: float | None = None
    values: tuple = ()
    rationale: str = ""

    @property
    def discrete(self) -> bool:
        return self.distribution == "choice"

    @property
    def measurement_only(self) -> bool:
        """Changes only how the gauges read the strains (no new solve)."""
        return all(_FACE.match(k) or _POLARITY.match(k) for k in self.keys)

    def at(self, u: float):
        """The value at ``u`` in [0, 1] of its range (a quantile for ``normal``)."""
        u = float(np.clip(u, 0.0, 1.0))
        if self.distribution == "uniform":
            return self.low + u * (self.high - self.low)
        if self.distribution == "loguniform":
            return self.low * (self.high / self.low) ** u
        if self.distribution == "normal":
            from scipy.stats import norm
            return self.mean + self.std * float(norm.ppf(np.clip(u, 1e-3, 1 - 1e-3)))
        return self.values[min(int(u * len(self.values)), len(self.values) - 1)]

    def fraction(self, x) -> float:
        """Inverse of :meth:`at` for continuous unknowns."""
        if self.distribution == "uniform":
            return 0.0 if self.high == self.low else (float(x) - self.low) / (self.high - self.low)
        if self.distribution == "loguniform":
            return math.log(float(x) / self.low) / math.log(self.high / self.low)
        if self.distribution == "normal":
            from scipy.stats import norm
            return float(norm.cdf((float(x) - self.mean) / self.std))
        return self.values.index(x) / max(len(self.values) - 1, 1)

    def dvalue_du(self, u: float) -> float:
        """d(value)/du of a continuous unknown (for confidences in the unknown's unit)."""
        if self.distribution == "uniform":
            return self.high - self.low
        if self.distribution == "loguniform":
            return self.at(u) * math.log(self.high / self.low)
        h = 1e-4
        return (self.at(u + h) - self.at(u - h)) / (2 * h)

    def bounds(self) -> tuple:
        if self.distribution in ("uniform", "loguniform"):
            return self.low, self.high
        if self.distribution == "normal":
            return self.mean - 2 * self.std, self.mean + 2 * self.std
        return self.values[0], self.values[-1]

    def describe(self) -> dict:
        d = {"keys": list(self.keys), "distribution": self.distribution, "unit": self.unit,
             "rationale": self.rationale}
        if self.discrete:
            d["values"] = list(self.values)
        elif self.distribution == "normal":
            d.update(mean=self.mean, std=self.std)
        else:
            d.update(low=self.low, high=self.high)
        return d


def quantity_in(text, unit, where):
    try:
        q = UREG.Quantity(str(text).replace("^", "**"))
        if unit:
            return float(q.to(unit.replace("^", "**")).magnitude)
        return float(q.to("").magnitude) if hasattr(q, "to") else float(q)
    except Exception as exc:
        raise ScenarioError(f"{where}: cannot read {text!r} in unit {unit or 'dimensionless'!r} ({exc})") from None


def declared(raw: dict, path: str = "<scenario>") -> tuple:
    """``(samples, seed, {name: Unknown}, options)`` from the scenario's ``[uncertainty]`` table
    (``options``: its other keys, e.g. ``identify``, ``morris_trajectories``)."""
    u = raw.get("uncertainty")
    if not isinstance(u, dict) or not isinstance(u.get("parameters"), dict) or not u["parameters"]:
        raise ScenarioError(f"scenario '{path}': it declares no unknowns ([uncertainty.parameters.<name>] tables)")
    out = {}
    for name, d in u["parameters"].items():
        key = f"scenario '{path}': key 'uncertainty.parameters.{name}"
        if not isinstance(d, dict):
            raise ScenarioError(f"{key}' must be a table")
        keys = d.get("keys")
        if not isinstance(keys, list) or not keys or not all(isinstance(k, str) for k in keys):
            raise ScenarioError(f"{key}.keys' must list the scenario keys it sets")
        for k in keys:
            if k.startswith("model.") and k not in MODEL_KEYS:
                raise ScenarioError(f"{key}.keys': unknown model key {k!r}; model keys: {', '.join(MODEL_KEYS)}")
            if k.startswith("measurement.") and not _POLARITY.match(k):
                raise ScenarioError(f"{key}.keys': unknown measurement key {k!r} (measurement.polarity.<gauge>)")
        dist = d.get("distribution")
        unit = str(d.get("unit", ""))
        common = dict(name=name, keys=tuple(keys), distribution=dist, unit=unit,
                      rationale=str(d.get("rationale", d.get("assumption", ""))))

        def num(k):
            if k not in d:
                raise ScenarioError(f"{key}.{k}' is required for a {dist} distribution")
            return quantity_in(d[k], unit, f"{key}.{k}'")
        if dist in ("uniform", "loguniform"):
            lo, hi = num("low"), num("high")
            if hi < lo:
                raise ScenarioError(f"{key}': high below low")
            if dist == "loguniform" and not lo > 0:
                raise ScenarioError(f"{key}.low': a loguniform range must be positive")
            out[name] = Unknown(low=lo, high=hi, **common)
        elif dist == "normal":
            out[name] = Unknown(mean=num("mean"), std=num("std"), **common)
        elif dist == "choice":
            values = d.get("values")
            if not isinstance(values, list) or not values:
                raise ScenarioError(f"{key}.values' must list the choices")
            out[name] = Unknown(values=tuple(values), **common)
        else:
            raise ScenarioError(f"{key}.distribution' = {dist!r}: {', '.join(DISTRIBUTIONS)}")
    options = {k: v for k, v in u.items() if k not in ("parameters", "samples", "seed")}
    return int(u.get("samples", 32)), int(u.get("seed", 1)), out, options


# -- a sample -> a variant ---------------------------------------------------------------------------
@dataclass
class Variant:
    """What a sample changes: scenario ``overrides``, ``model`` values (SI, :data:`MODEL_KEYS`),
    and per gauge the ``signs`` (bending, axial) of the reading."""

    overrides: dict = field(default_factory=dict)
    model: dict = field(default_factory=dict)
    signs: dict = field(default_factory=dict)

    def physics_key(self) -> tuple:
        """Hashable identity of what needs a solve (the reading signs excluded)."""
        return (tuple(sorted((k, repr(v)) for k, v in self.overrides.items())),
                tuple(sorted((k, round(v, 12)) for k, v in self.model.items())))


def _scalar(x):
    return float(x) if isinstance(x, (np.floating, np.integer, float, int)) and not isinstance(x, bool) else x


def variant(sc, unknowns: dict, sample: dict) -> Variant:
    """The :class:`Variant` of ``sample`` ({name: value}) on the scenario ``sc``."""
    v = Variant()
    faces = {g.name: g.face for g in sc.gauges}
    for name, x in sample.items():
        if name not in unknowns:
            raise ScenarioError(f"unknown {name!r} is not declared in [uncertainty.parameters] of "
                                f"'{sc.path or sc.name}' (declared: {', '.join(unknowns)})")
        spec = unknowns[name]
        x = _scalar(x)
        for key in spec.keys:
            m_face, m_pol = _FACE.match(key), _POLARITY.match(key)
            if m_face or m_pol:
                g = (m_face or m_pol).group(1)
                if g not in faces:
                    raise ScenarioError(f"unknown {name!r}: key {key!r} names no gauge of '{sc.name}' "
                                        f"(gauges: {', '.join(faces)})")
                sb, sa = v.signs.get(g, (1, 1))
                if m_face:
                    if x not in ("top", "bottom"):
                        raise ScenarioError(f"unknown {name!r}: a face is 'top' or 'bottom', got {x!r}")
                    sb *= 1 if x == faces[g] else -1
                else:
                    if x not in (1, -1, 1.0, -1.0):
                        raise ScenarioError(f"unknown {name!r}: a polarity is 1 or -1, got {x!r}")
                    sb, sa = sb * int(x), sa * int(x)
                v.signs[g] = (sb, sa)
            elif key.startswith("model."):
                v.model[key] = quantity_in(f"{x} {spec.unit}".strip(), MODEL_KEYS[key], f"unknown '{name}'")
            elif spec.discrete or not spec.unit:
                v.overrides[key] = x
            else:
                v.overrides[key] = f"{x!r} {spec.unit}"
    if "model.gravity_in_plane" in v.model or "model.gravity_direction" in v.model:
        f = v.model.pop("model.gravity_in_plane", 1.0)
        a = v.model.pop("model.gravity_direction", 0.0)
        g0 = 9.80665 * f
        v.overrides["gravity.vector"] = [f"{g0 * math.sin(a)!r} m/s^2", f"{-g0 * math.cos(a)!r} m/s^2"]
    return v
