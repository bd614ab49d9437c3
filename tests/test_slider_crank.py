"""Slider-crank through the whole bench (issue 8): the TMM's instantaneous structure with a pinned
slider block, quasi-static and time-domain analysis, and the exudyn and MuJoCo models of the same
scenario."""
import json

import numpy as np
import pytest

from cosim.engines import make_engine
from cosim.master import run_prescribed
from cosim.scenario import load
from tmm_core import Gauge, quasi_static


@pytest.fixture(scope="module")
def scenario():
    return load("slider_crank_600rpm")


def test_quasi_static_drive_torque_is_the_virtual_work_torque(scenario):
    """With the links' own lumped masses, the clamped crank's reaction equals the rigid torque
    J'(q) w^2 / 2 of the equivalent-inertia equation (constant speed); elasticity changes it by
    the (tiny) deflection of this stiff rig."""
    mech = scenario.mechanism
    w = scenario.drive.speed_rad_s
    q = np.linspace(0, 2 * np.pi, 36, endpoint=False)
    qs = quasi_static(mech, q, w, beam_column=False)
    _, dJ, _ = mech.crank_inertia(q, lumped=True)
    expected = 0.5 * dJ * w**2
    np.testing.assert_allclose(qs.drive_torque, expected, atol=2e-3 * np.max(np.abs(expected)))


def test_slider_has_no_force_along_the_slide_beyond_its_inertia(scenario):
    """The pinned block on a frictionless guide: the coupler's force along the slide at C equals
    the block's D'Alembert force."""
    mech = scenario.mechanism
    w = scenario.drive.speed_rad_s
    q = np.linspace(0.1, 6.0, 7)
    qs = quasi_static(mech, q, w, beam_column=False)
    r = qs.solution.members["coupler"]
    F = r.internal_force_global[..., -1, 0, :]          # force on the coupler's positive face at C
    m_block = mech.slider_mass_kg
    a_slide = mech.motion(q, w).slider_acceleration
    coupler = mech.links()[1]
    # The coupler's end node also carries half its last segment's own mass.
    m_end = coupler.node_masses()[0][-1] - m_block
    a_C = mech.motion(q, w).coupler.point(coupler.length_m)[2]
    along = F[..., 0] * np.cos(mech.ground_angle) + F[..., 1] * np.sin(mech.ground_angle)
    np.testing.assert_allclose(along, -(m_block * a_slide + m_end * a_C[..., 0]), rtol=1e-6, atol=1e-9)


def test_tmm_quasi_static_matches_exudyn_at_moderate_speed(scenario):
    """600 rpm against a 229 Hz coupler: the exudyn flexible model's steady peaks and the TMM's
    quasi-static peaks agree within 5 % (measured: +30.0 / -30.0 against +29.7 / -29.7 ue)."""
    g = [gg for gg in scenario.gauges if gg.name == "coupler_mid"][0]
    q = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    qs = quasi_static(scenario.mechanism, q, scenario.drive.speed_rad_s, gauges=[g])
    b_tmm = qs.gauges["coupler_mid"][0] * 1e6
    run = run_prescribed(make_engine("exudyn"), scenario, revolutions=3)
    last = run.last_revolution(scenario.revolution_period_s)
    b_exu = run.gauges["coupler_mid"][0][last] * 1e6
    assert b_exu.max() == pytest.approx(b_tmm.max(), rel=0.05)
    assert b_exu.min() == pytest.approx(b_tmm.min(), rel=0.05)


def test_mujoco_rigid_slider_crank_matches_the_tmm(scenario):
    g = [gg for gg in scenario.gauges if gg.name == "coupler_mid"][0]
    run = run_prescribed(make_engine("mujoco"), scenario, revolutions=1.5)
    last = run.last_revolution(scenario.revolution_period_s)
    qs = quasi_static(scenario.mechanism, run.crank_angle[last], scenario.drive.speed_rad_s, gauges=[g],
                      beam_column=False)
    b = run.gauges["coupler_mid"][0][last]
    np.testing.assert_allclose(b, qs.gauges["coupler_mid"][0], atol=0.02 * np.ptp(qs.gauges["coupler_mid"][0]))
    assert np.max(run.extras["loop_closure_m"][1]) < 1e-4
    np.testing.assert_allclose(run.drive_torque[last], qs.drive_torque, atol=0.02 * np.ptp(qs.drive_torque))


def test_slider_crank_runs_through_cosim_run_with_all_engines(tmp_path):
    from cosim.cli import main
    out = tmp_path / "sc"
    assert main(["run", "slider_crank_600rpm", "--revolutions", "1", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed"
    for engine in ("tmm", "exudyn", "mujoco"):
        assert summary["engines"][engine]["status"] == "completed"
        assert np.isfinite(summary["engines"][engine]["gauges"]["coupler_mid"]["bending_max_ue"])
