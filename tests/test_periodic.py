"""Periodic steady state, Floquet multipliers (issue 9)."""
import math

import numpy as np
import pytest

from cosim.scenario import load
from tmm_core import CrankMotion, TimeDomain
from tmm_core.periodic import mathieu_multipliers, periodic_steady_state


def _on_angle(angle, values, N):
    a = np.mod(angle, 2 * math.pi)
    order = np.argsort(a)
    return values[order]


def test_periodic_solution_equals_time_marching_to_steady_state():
    """FE crank-rocker rig at 241 rpm (2 % damping): the one-solve periodic response and the
    time-marched steady state (same integrator and step) agree to 0.5 % of peak-to-peak
    (measured 5e-10: the periodic state is the marched map's fixed point)."""
    s = load("crank_rocker_241rpm")
    w = s.drive.speed_rad_s
    td = TimeDomain(s.mechanism, integrator="generalized_alpha", gauges=s.gauges)
    p = periodic_steady_state(td, w, step_deg=1.0)
    assert p.residual < 1e-6
    assert np.max(np.abs(p.multipliers)) < 1.0
    r = td.run(CrankMotion.constant_speed(w, step_deg=1.0, revolutions=60), start="quasi_static", steady_tol=1e-7,
               record_displacements=False)
    assert r.steady
    N = p.info["steps_per_revolution"]
    for g in p.gauges:
        marched = _on_angle(r.crank_angle[-N:], r.gauges[g][0][-N:], N)
        periodic = _on_angle(p.angle, p.gauges[g][0], N)
        assert np.max(np.abs(marched - periodic)) < 0.005 * np.ptp(marched)
    np.testing.assert_allclose(_on_angle(p.angle, p.drive_torque, N), _on_angle(r.crank_angle[-N:], r.drive_torque[-N:], N),
                               atol=0.005 * np.ptp(r.drive_torque[-N:]))


@pytest.mark.parametrize("delta, epsilon, stable", [
    # First (principal) tongue of the Mathieu chart: boundaries delta = 1/4 -+ epsilon/2 for small epsilon.
    (0.25, 0.1, False),          # inside the tongue
    (0.25 + 0.08, 0.1, True),    # above its upper boundary 0.30
    (0.25 - 0.08, 0.1, True),    # below its lower boundary 0.20
    # Second tongue near delta = 1: boundaries 1 - epsilon^2/12 and 1 + 5 epsilon^2/12.
    (1.0 + 0.05, 0.4, False),    # between 0.987 and 1.067
    (1.0 + 0.12, 0.4, True),
])
def test_floquet_multipliers_reproduce_the_mathieu_stability_chart(delta, epsilon, stable):
    mu = mathieu_multipliers(delta, epsilon)
    assert (np.max(np.abs(mu)) <= 1.0 + 1e-6) == stable
    assert abs(np.prod(mu) - 1.0) < 1e-8            # Liouville: undamped, det = 1
