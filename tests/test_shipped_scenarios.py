"""Every shipped scenario runs, with one pinned number each (issue 16).

Each pinned number comes from something other than the engine under test:
* flexible rigs: exudyn's steady bending peak at twice the default elements and half the default
  step (an independent, geometrically exact engine, refined), the transfer-matrix engine runs at
  the scenario's defaults to its steady state; tolerance 2 % of exudyn's peak-to-peak (the
  measured agreement is 0.1-1.0 %, docs/validation.md, "Engines that agree");
* Wang's rigs (no exudyn: mass-proportional damping, viscoelastic links): the transfer-matrix
  model refined (twice the segments, a quarter of the step), a convergence study; 1 %;
* the weak-drive variant: the speed fluctuation of the rigid linkage with the motor as one ODE
  (tests/monolithic.py, scipy DOP853, shares no code with cosim.motor), MuJoCo co-simulated;
* the flexible-crank variant: its first natural frequency at crank angle 0 from exudyn's
  eigenvalue analysis, against the transfer-matrix frequency search;
* Shin's static structures are pinned to Shin's tables in tests/test_multiloop.py.
Values measured 2026-11-24; ``python -m tests.benchmarks.pinned_references`` regenerates every one
of them from its reference (not run in CI: the refined exudyn runs take minutes each).
"""
import math

import numpy as np
import pytest

from cosim.engines import make_engine
from cosim.master import run_prescribed
from cosim.master import CoSimulation
from cosim.metrics import run_change
from tmm_core.revolution import last_revolution
from cosim.scenario import load, scenario_names

# scenario: (gauge, +peak [microstrain] of the reference, its - peak, tolerance as a fraction of p-p)
EXUDYN_REFINED = {
    "alexander_lawrence_400rpm": ("follower_mid", 320.89, -541.22, 0.02),
    "bahgat_willmert_125rads": ("coupler_mid", 6165.3, -5629.9, 0.02),
    "crank_rocker_95rpm": ("rocker_mid", 41.10, -48.80, 0.02),
    "crank_rocker_241rpm": ("rocker_mid", 194.91, -547.34, 0.02),
    "crank_rocker_373rpm": ("rocker_mid", 1706.94, -2609.71, 0.02),
    "slider_crank_600rpm": ("coupler_mid", 29.80, -29.81, 0.02),
    "watt_sixbar_600rpm": ("rocker_E", 216.48, -595.88, 0.02),
    "shin_multiloop_motion": ("coupler_at_3", 1545.19, -1670.25, 0.02),
    # Light-damping variants (issue 34, docs/light_damping.md): exudyn from rest at its default 16
    # elements / 0.2 deg (32 / 0.1 deg moved the bending peaks by 0.2 % at 381 rpm, 2 %; the
    # refined run at these dampings is not done yet).
    "crank_rocker_373rpm_damping_1pct": ("rocker_mid", 1630.3, -2357.3, 0.02),
    "crank_rocker_373rpm_damping_0p5pct": ("rocker_mid", 1573.5, -2314.6, 0.02),
}
TMM_REFINED = {
    "wang_steel_342rpm": ("rocker_mid", 65.64, -105.69, 0.01),
    "wang_composite_205rpm": ("rocker_mid", 14.25, -27.47, 0.01),
    "wang_composite_255rpm": ("rocker_mid", 22.05, -42.90, 0.01),
    "wang_composite_280rpm": ("rocker_mid", 26.81, -51.49, 0.01),
    "wang_composite_297rpm": ("rocker_mid", 30.22, -57.92, 0.01),
}
SLOW = {"bahgat_willmert_125rads", "crank_rocker_373rpm_damping_1pct", "crank_rocker_373rpm_damping_0p5pct"}
#: Known failures, each with its issue: the transfer-matrix model marched from its quasi-static
#: start does not settle at 0.5 % damping: a large irregular response coexists with the steady one
#: (in exudyn too, which stays in it from rest at crank 90 deg; docs/light_damping.md).
XFAIL = {"crank_rocker_373rpm_damping_0p5pct": "issue 34: the TMM march stays in the irregular response that "
                                               "coexists with the steady one at 0.5 %"}


def _cases(table):
    return [pytest.param(name, marks=[pytest.mark.slow] + ([pytest.mark.xfail(strict=True, reason=XFAIL[name])]
                                                            if name in XFAIL else []))
            if name in SLOW else name for name in table]


def test_every_shipped_scenario_has_a_pinned_number():
    pinned = set(EXUDYN_REFINED) | set(TMM_REFINED) | {"crank_rocker_373rpm_weak_drive",
                                                       "crank_rocker_373rpm_flexible_crank",
                                                       "shin_multiloop_small", "shin_multiloop_large"}
    assert set(scenario_names()) <= pinned, sorted(set(scenario_names()) - pinned)


@pytest.mark.parametrize("name", _cases({**EXUDYN_REFINED, **TMM_REFINED}))
def test_the_tmm_default_run_reaches_the_pinned_steady_peak(name):
    gauge, hi, lo, tol = {**EXUDYN_REFINED, **TMM_REFINED}[name]
    sc = load(name)
    run = run_prescribed(make_engine("tmm"), sc)
    assert run_change(run) < sc.output.steady_tolerance
    b = run.gauges[gauge][0][last_revolution(run.crank_angle)] * 1e6
    span = hi - lo
    assert abs(b.max() - hi) < tol * span, (b.max(), hi)
    assert abs(b.min() - lo) < tol * span, (b.min(), lo)


def test_weak_drive_speed_fluctuation_matches_the_monolithic_rigid_motor_ode():
    """58.39 % per revolution at steady running (monolithic reference, revolutions 3-6)."""
    sc = load("crank_rocker_373rpm_weak_drive")
    ch = CoSimulation(sc.with_overrides({"coupling.macro_step": "2 deg"}), ("mujoco",), mode="motor").run(revolutions=4)
    assert ch["mujoco"].speed_fluctuation()["fluctuation"][-1] == pytest.approx(0.5839, abs=0.01)


def test_flexible_crank_variant_first_mode_matches_exudyn():
    """exudyn's constrained eigenvalues at crank angle 0: 67.19 Hz (the rigid crank's 78.9 Hz
    pulled down by the 100x crank's own modes)."""
    from tmm_core.frequencies import fourbar_frequencies
    sc = load("crank_rocker_373rpm_flexible_crank")
    f = fourbar_frequencies(sc.mechanism, np.array([0.0]), 1, 500.0)[0, 0]
    assert f == pytest.approx(67.19, rel=0.01)
    assert not math.isnan(f)
