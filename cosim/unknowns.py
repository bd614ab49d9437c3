"""Declared unknowns of a scenario (its ``[uncertainty]`` table) and the fast model run behind
uncertainty bands and identification.

Each unknown sets one or more keys::

    [uncertainty.parameters.damping]
    keys = ["links.coupler.damping.ratio", "links.rocker.damping.ratio"]
    distribution = "uniform"       # uniform | loguniform (low, high) | normal (mean, std) | choice (values)
    low = "1 %"
    high = "15 %"
    unit = "%"                     # the unit a drawn number is written in
    rationale = "why this range"

A key is one of three kinds:

* a **scenario key** (``links.coupler.damping.ratio``, ``gravity.vector``, ...): the variant is
  made with :meth:`cosim.scenario.Scenario.with_overrides` and validated by the loader;
* a **model key** (``model.*``, :data:`MODEL_KEYS`): physics the scenario file has no key for,
  carried by the transfer-matrix model only: the drive's inertia (a free-wheeling crank,
  :mod:`tmm_core.free_wheel`), moments at the pins (gauge wires, joint friction,
  :mod:`tmm_core.pin_moments`), and gravity written as the fraction of g in the linkage plane and
  its direction (set as ``gravity.vector``);
* a **measurement key**: how a gauge reads the model's strain: ``gauges.<g>.face`` (top/bottom:
  flips the bending sign) and ``measurement.polarity.<g>`` (+1/-1: flips bending and axial).
  They are applied to the solved strains (no new solve).

:func:`solve` runs one variant: the transfer-matrix model marched to its periodic steady state
with one revolution of factorized configurations reused (the compiled kernel), which measured
6-8x faster than the periodic shooting solver for the same peaks (docs/validation.md, "How far the bench is
from the measurement").

Owns: the fast model run of bands and identification (the declared unknowns are read by
:mod:`cosim.unknowns_table`, re-exported here). Boundaries: no fitting
(cosim.identify) and no sampling design (cosim.uncertainty).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from tmm_core import CrankMotion, TMMError
from tmm_core.free_wheel import free_wheel
from tmm_core.pin_moments import JointLoadedFourBar, JointMoment
from tmm_core.reduced import ReducedOptions
from tmm_core.reduced_periodic import periodic_steady_state_reduced
from tmm_core.revolution import march_to_steady

from .run_guards import estimate_cost
from .scenario import ScenarioError, from_dict
from .units import UREG
from .unknowns_table import (DISTRIBUTIONS, MODEL_KEYS, Unknown, Variant, declared,  # noqa: F401
                             variant)

# -- the fast model run ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Settings:
    """Transfer-matrix settings of bands and identification: 4 segments per link at 0.5 deg are
    within 2 % of the shipped 8 segments at 0.5 deg on the FE rig's peaks (docs/validation.md); marched until
    two revolutions agree to ``tolerance`` of the peak-to-peak (at most ``max_revolutions``)."""

    segments: int = 4
    step_deg: float = 0.5
    tolerance: float = 1e-6
    max_revolutions: int = 80
    n_grid: int = 360
    #: "full" (marched), "reduced" (tmm_core.reduced: periodic shooting on link modes plus a static
    #: correction), or None: the scenario's solver.tmm.model.
    model: str | None = None


def _joint_laws(model: dict):
    f = model.get("model.joint_friction", 0.0)
    laws = [JointMoment("B", friction=f)]
    for j in ("C", "D"):
        laws.append(JointMoment(j, moment=model.get(f"model.joint_moment.{j}", 0.0),
                                stiffness=model.get(f"model.joint_stiffness.{j}", 0.0), friction=f))
    return [law for law in laws if law.active]


def fast_model(sc, settings: Settings = Settings()):
    """The scenario at the fast model's mesh and step (what :func:`solve` runs)."""
    return sc.with_overrides({"solver.tmm.segments": settings.segments,
                              "solver.tmm.step": UREG.Quantity(settings.step_deg, "deg")})


def solve_cost(sc, settings: Settings = Settings()) -> dict:
    """One :func:`solve`'s :func:`cosim.run_guards.estimate_cost`, at its most revolutions
    (``settings.max_revolutions``: an upper bound; the FE rig settles in 11 at 373 rpm, 0.25 s
    measured on one core). Its march steps through one stored revolution at a time: a revolution
    is its macro step."""
    fast = fast_model(sc, settings)
    period = fast.revolution_period_s
    return estimate_cost(fast, ["tmm"], settings.max_revolutions * period, period)


def solve(sc, model: dict | None = None, settings: Settings = Settings()) -> dict:
    """Steady revolution of the transfer-matrix model of ``sc`` with the model values ``model``:
    ``{"status", "error", "angle_deg" (uniform grid), "gauges": {g: {"bending_ue", "axial_ue"}},
    "peaks": {g: {bending/axial max/min [ue]}}, "revolutions", "change", "speed_fluctuation",
    "wall_time_s"}`` (lists: picklable)."""

    tic = time.perf_counter()
    model = dict(model or {})
    unknown = set(model) - set(MODEL_KEYS)
    if unknown:
        raise ScenarioError(f"unknown model keys {sorted(unknown)}")
    sc = fast_model(sc, settings)
    base = sc.mechanism
    laws = _joint_laws(model)
    mech = JointLoadedFourBar.from_mechanism(base, laws) if laws else base
    s = sc.tmm
    out = {"status": "failed", "error": None, "speed_fluctuation": 0.0}
    try:
        discretized = sc.time_domain(mech).model
        kind = settings.model or s.model
        if kind not in ("full", "reduced"):
            raise ScenarioError(f"fast model: model must be 'full' or 'reduced', got {kind!r}")
        if kind == "reduced":
            options = ReducedOptions(modes=s.modes)
            n = options.steps
        else:
            n = int(round(360.0 / settings.step_deg))
        out["model"] = kind
        w = sc.drive.speed_rad_s
        if "model.drive_inertia" in model:
            crank, info = free_wheel(base, w, model["model.drive_inertia"], n, start_angle=sc.drive.start_angle_rad,
                                     gravity=sc.gravity, applied=mech if laws else None)
            out["speed_fluctuation"] = info["speed_fluctuation"]
        else:
            crank = CrankMotion.constant_speed(w, step_deg=360.0 / n, revolutions=1.0,
                                               start_angle=sc.drive.start_angle_rad)
        if kind == "reduced":
            p = periodic_steady_state_reduced(discretized, crank=crank, options=options)
            angles = p.angle
            outs = np.column_stack([p.drive_torque] + [np.column_stack(p.gauges[g.name]) for g in sc.gauges])
            revs, change = 1, p.residual
        else:
            outs, revs, change = march_to_steady(discretized, crank, settings.tolerance, settings.max_revolutions)
            angles = crank.angle[1:]
    except (TMMError, FloatingPointError, np.linalg.LinAlgError) as exc:
        out.update(error=f"{type(exc).__name__}: {exc}", wall_time_s=time.perf_counter() - tic)
        return out
    grid = np.arange(settings.n_grid) * 360.0 / settings.n_grid
    a = np.mod(np.degrees(angles), 360.0)
    order = np.argsort(a)
    out.update(status="completed" if change < settings.tolerance else "not steady", revolutions=revs, change=change,
               angle_deg=grid.tolist(), gauges={}, peaks={}, wall_time_s=time.perf_counter() - tic)
    if change >= settings.tolerance:
        out["error"] = f"not steady after {revs} revolutions (change {change:.3g})"
    for i, g in enumerate(sc.gauges):
        b, ax = outs[:, 1 + 2 * i] * 1e6, outs[:, 2 + 2 * i] * 1e6
        out["gauges"][g.name] = {"bending_ue": np.interp(grid, a[order], b[order], period=360.0).tolist(),
                                 "axial_ue": np.interp(grid, a[order], ax[order], period=360.0).tolist()}
        out["peaks"][g.name] = {"bending_max_ue": float(b.max()), "bending_min_ue": float(b.min()),
                                "axial_max_ue": float(ax.max()), "axial_min_ue": float(ax.min())}
    return out


def read(result: dict, signs: dict) -> dict:
    """``result`` as the gauges read it: bending and axial multiplied by each gauge's signs
    (a flipped reading swaps and negates the max and min)."""
    if result.get("status") != "completed" or not signs:
        return result
    out = dict(result, gauges={}, peaks={})
    for g, h in result["gauges"].items():
        sb, sa = signs.get(g, (1, 1))
        out["gauges"][g] = {"bending_ue": [sb * x for x in h["bending_ue"]], "axial_ue": [sa * x for x in h["axial_ue"]]}
        p = result["peaks"][g]
        bmax, bmin = (p["bending_max_ue"], p["bending_min_ue"]) if sb > 0 else (-p["bending_min_ue"], -p["bending_max_ue"])
        amax, amin = (p["axial_max_ue"], p["axial_min_ue"]) if sa > 0 else (-p["axial_min_ue"], -p["axial_max_ue"])
        out["peaks"][g] = {"bending_max_ue": bmax, "bending_min_ue": bmin, "axial_max_ue": amax, "axial_min_ue": amin}
    return out


def solve_job(raw: dict, path: str, overrides: dict, model: dict, settings: Settings = Settings()) -> dict:
    """One solve in a worker process: the scenario from its tree, the variant, :func:`solve`."""
    try:
        sc = from_dict(raw, path)
        if overrides:
            sc = sc.with_overrides(overrides)
    except ScenarioError as exc:
        return {"status": "failed", "error": f"ScenarioError: {exc}"}
    return solve(sc, model, settings)
