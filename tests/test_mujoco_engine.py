"""MuJoCo rigid reference engine on the Alexander-Lawrence four-bar (400 rpm clockwise).

References are independent of MuJoCo: the closed-form kinematics (``mech.motion``), rigid-body
inverse dynamics by virtual power on a fine discretisation of each link's mass, and the
simply-supported-rocker closed form of the quasi-static midspan strain.
"""
import math
import tomllib

import numpy as np
import pytest

pytest.importorskip("mujoco")

import cosim.scenario as cs  # noqa: E402
from cosim.engines import DriveInput, EngineError, make_engine  # noqa: E402
from cosim.master import run_prescribed  # noqa: E402
from cosim.engines.base import concatenate, constant_speed_profile  # noqa: E402
from cosim.engines.mujoco_tree import link_inertia  # noqa: E402
from tmm_core import Link, Material, PointMass, Section, gauge_strains, rigid_body_loads, solve_static  # noqa: E402
from tmm_core.mechanism import EndBlock  # noqa: E402

NAME = "alexander_lawrence_400rpm"


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def mass_points(link, per_link=400):
    """Stations [m] and masses [kg] of a fine midpoint discretisation of the distributed mass
    (about ``per_link`` points, each segment on its own) plus the point masses."""
    x, h, rho_a = link.stations, np.diff(link.stations), link.segment_mass_per_length()
    xs, dm = [], []
    for i in range(len(h)):
        k = max(1, math.ceil(per_link * h[i] / link.length_m))
        xs.append(x[i] + (np.arange(k) + 0.5) * h[i] / k)
        dm.append(np.full(k, rho_a[i] * h[i] / k))
    xs.append([p.position_m for p in link.point_masses])
    dm.append([p.mass_kg for p in link.point_masses])
    return np.concatenate(xs), np.concatenate(dm)


def inverse_dynamics_torque(mech, angle, speed, accel=0.0):
    """Drive torque [N m] from virtual power with the unit-crank-speed velocities v/w:
    T + sum(-dm a . v/w) + sum(-J alpha omega/w) = 0 (no gravity)."""
    motion, unit = mech.motion(angle, speed, accel), mech.motion(angle, 1.0)
    power = 0.0
    for link in mech.links():
        xs, dm = mass_points(link)
        lm, lu = motion.link(link.name), unit.link(link.name)
        power = power - np.sum(dm[:, None] * lm.point(xs)[2] * lu.point(xs)[1], axis=(-1, -2))
        power = power - sum(p.inertia_kg_m2 for p in link.point_masses) * lm.alpha * lu.omega
    return -power


@pytest.fixture(scope="module")
def scenario():
    return cs.load(NAME)


@pytest.fixture(scope="module")
def run3(scenario):
    """Three revolutions at 400 rpm, prescribed constant speed, default settings."""
    run = run_prescribed(make_engine("mujoco"), scenario, 3)
    w = scenario.drive.speed_rad_s
    reference = scenario.drive.start_angle_rad + w * run.t
    steady = run.t > scenario.revolution_period_s          # after the first revolution
    return run, reference, steady


def test_kinematics_match_closed_form(scenario, run3):
    run, ref, _ = run3
    mech, w = scenario.mechanism, scenario.drive.speed_rad_s
    motion = mech.motion(ref, w)
    rocker_err = np.degrees(np.abs(wrap(run.extras["rocker_angle_rad"][1] - motion.rocker.angle)))
    coupler_err = np.degrees(np.abs(wrap(run.extras["coupler_angle_rad"][1] - motion.coupler.angle)))
    closure = run.extras["loop_closure_m"][1]
    print(f"rocker {rocker_err.max():.2e} deg, coupler {coupler_err.max():.2e} deg, "
          f"crank {np.degrees(np.abs(run.crank_angle - ref)).max():.2e} deg, closure {closure.max():.2e} m")
    assert run.t[-1] >= 3 * scenario.revolution_period_s - 1e-12
    assert rocker_err.max() < 0.01 and coupler_err.max() < 0.01
    assert closure.max() < 1e-5
    # Rigid node positions: every node of every link where the closed form puts it.
    for link in mech.links():
        expected = motion.link(link.name).point(link.stations)[0]
        assert run.nodes[link.name].shape == (len(run.t), link.n_nodes, 2)
        np.testing.assert_allclose(run.nodes[link.name], expected, atol=1e-5)
    np.testing.assert_allclose(np.diff(run.t), scenario.mujoco.step_s, rtol=1e-9)


def test_drive_torque_matches_rigid_inverse_dynamics(scenario, run3):
    run, ref, steady = run3
    expected = inverse_dynamics_torque(scenario.mechanism, ref, scenario.drive.speed_rad_s)
    peak = np.max(np.abs(expected))
    err = np.max(np.abs(run.drive_torque - expected)[steady])
    print(f"torque error {100 * err / peak:.3f} % of peak {peak:.4g} N m")
    assert err < 0.01 * peak


def test_torque_drive_follows_the_inverse_dynamics_profile(scenario):
    """Open loop: the inverse-dynamics torque keeps the crank at constant speed (the residual
    drift is the first-order error of the Euler integrator: 0.44 % at 1e-4 s)."""
    mech, w = scenario.mechanism, scenario.drive.speed_rad_s
    engine = make_engine("mujoco")
    engine.reset(scenario, 0.0, 0.0, w)
    macro = 21 * engine.internal_step_s
    drive = DriveInput(torque=lambda t: inverse_dynamics_torque(mech, w * np.asarray(t), w))
    run = concatenate("mujoco", [engine.advance((k + 1) * macro, drive)
                                 for k in range(math.ceil(scenario.revolution_period_s / macro))], 0.0)
    np.testing.assert_array_equal(run.drive_torque, drive.torque_at(run.t))
    dev = np.max(np.abs(run.crank_speed / w - 1))
    print(f"speed deviation {100 * dev:.3f} %, angle {np.degrees(np.max(np.abs(run.crank_angle - w * run.t))):.3f} deg")
    assert dev < 0.01
    # A constant CCW torque from rest turns the crank CCW.
    engine.reset(scenario, 0.0, 0.0, 0.0)
    out = engine.advance(100 * engine.internal_step_s, DriveInput(torque=0.5))
    assert out.crank_speed[-1] > 0 and out.crank_angle[-1] > 0


def test_rigid_strain_matches_rocker_closed_form(scenario, run3):
    """Rocker pinned at D and C under its own inertia rho A alpha4 x: midspan top-face bending
    strain -(3/8) rho alpha4 L^3 / (h E) (tests/test_ked.py)."""
    run, ref, steady = run3
    mech = scenario.mechanism
    gauge = next(g for g in scenario.gauges if g.link == "rocker")
    assert gauge.face == "top" and gauge.position_m == pytest.approx(mech.rocker.length_m / 2)
    r = mech.rocker
    alpha4 = mech.motion(ref, scenario.drive.speed_rad_s).rocker.alpha
    expected = -(3 / 8) * r.material.density_kg_m3 * alpha4 * r.length_m**3 / r.section.depth_m / r.material.E_Pa
    bending = run.gauges[gauge.name][0]
    peak = np.max(np.abs(expected))
    err = np.max(np.abs(bending - expected)[steady])
    print(f"rocker mid strain error {100 * err / peak:.3f} % of peak {peak:.4g}")
    assert err < 0.01 * peak


def test_link_length_change_changes_the_result(scenario):
    text = scenario.path.read_text(encoding="utf-8")
    # The coupler length and its bearing at C (at the coupler's end) are the only '"11 in"'.
    assert text.count('"11 in"') == 2
    changed = cs.from_dict(tomllib.loads(text.replace('"11 in"', '"11.2 in"')), "edited")
    assert changed.mechanism.coupler.length_m == pytest.approx(11.2 * 0.0254)
    runs = [run_prescribed(make_engine("mujoco"), sc, 0.25) for sc in (scenario, changed)]
    rocker = [r.extras["rocker_angle_rad"][1] for r in runs]
    assert np.degrees(np.max(np.abs(wrap(rocker[1] - rocker[0])))) > 0.5
    w = changed.drive.speed_rad_s
    expected = changed.mechanism.motion(w * runs[1].t, w).rocker.angle
    assert np.degrees(np.max(np.abs(wrap(rocker[1] - expected)))) < 0.01


def test_macro_step_must_be_whole_internal_steps(scenario):
    engine = make_engine("mujoco")
    engine.reset(scenario, 0.0, 0.0, scenario.drive.speed_rad_s)
    drive = DriveInput(prescribed=constant_speed_profile(scenario.drive.speed_rad_s))
    with pytest.raises(EngineError, match="whole multiple"):
        engine.advance(2.5 * engine.internal_step_s, drive)
    out = engine.advance(3 * engine.internal_step_s, drive)
    assert out.t[-1] == 3 * engine.internal_step_s and len(out.t) == 3


def test_gravity_holding_still_matches_static_solution():
    """At rest under gravity the strain estimate and torque are the static ones (MuJoCo's
    framelinacc reads a - g; a sign slip would flip them)."""
    data = tomllib.loads((cs.SCENARIO_DIR / f"{NAME}.toml").read_text(encoding="utf-8"))
    data["gravity"] = {"vector": ["0 m/s^2", "-9.80665 m/s^2"]}
    sc = cs.from_dict(data)
    mech, th = sc.mechanism, math.radians(60.0)
    engine = make_engine("mujoco")
    engine.reset(sc, 0.0, th, 0.0)
    out = engine.advance(200 * engine.internal_step_s, DriveInput(prescribed=constant_speed_profile(0.0, th)))
    motion = mech.motion(th)
    sol = solve_static(mech.structure(), mech.load_case(motion, rigid_body_loads(mech, motion, sc.gravity)))
    assert out.drive_torque[-1] == pytest.approx(float(sol.reaction_moment("A")), rel=1e-5)
    for g in sc.gauges:
        bending, axial = gauge_strains(sol.members[g.link], g)
        assert out.gauges[g.name][0][-1] == pytest.approx(float(bending), rel=1e-5)
        assert out.gauges[g.name][1][-1] == pytest.approx(float(axial), rel=1e-5)


def test_link_inertia_and_model_masses(scenario):
    steel = Material("steel", 2.0e11, 7800.0)
    link = Link("rocker", 0.3, Section.rectangle(0.02, 0.005), steel, 5,
                (PointMass(0.06, 0.05, 2e-5, "sleeve"),),
                start_block=EndBlock(0.03, Section.rectangle(0.03, 0.02), steel))
    xs, dm = mass_points(link, 40000)
    m = dm.sum()
    xc = dm @ xs / m
    assert link_inertia(link) == pytest.approx((m, xc, dm @ (xs - xc) ** 2 + 2e-5), rel=1e-7)

    engine = make_engine("mujoco")
    engine.reset(scenario, 0.0, 0.0, scenario.drive.speed_rad_s)
    for link in scenario.mechanism.links():
        mass, com, izz = link_inertia(link)
        body = engine.model.body(link.name)
        assert body.mass[0] == pytest.approx(mass, rel=1e-12)
        np.testing.assert_allclose(body.ipos, [com, 0, 0], atol=1e-15)
        assert body.inertia[2] == pytest.approx(izz, rel=1e-12)
