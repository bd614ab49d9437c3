"""The physics behind the declared unknowns (issue 19): moments at the pins (gauge wires, joint
friction), a free-wheeling crank (drive inertia), the periodic solver on a periodic crank
history, and how the gauges read (face, polarity). Expected values are closed forms or a second
solution method of the same model."""
import math

import numpy as np
import pytest

from cosim.scenario import load
from cosim.unknowns import Settings, declared, read, solve, variant
from tmm_core import CrankMotion, InputError, TimeDomain
from tmm_core.free_wheel import free_wheel
from tmm_core.periodic import periodic_steady_state
from tmm_core.pin_moments import JOINTS, JointLoadedFourBar, JointMoment, mean_relative_angle
from tmm_core.revolution import march_to_steady

FAST = Settings(step_deg=1.0)


@pytest.fixture(scope="module")
def rig95():
    return load("crank_rocker_95rpm")


def _td(sc, mech=None, segments=4):
    sc = sc.with_overrides({"solver.tmm.segments": segments})
    s = sc.tmm
    return TimeDomain(mech or sc.mechanism, integrator=s.integrator, coupling=s.coupling, beam_column=s.beam_column,
                      gravity=sc.gravity, gauges=sc.gauges, axial_force=s.axial_force)


def test_a_moment_pair_at_the_coupler_rocker_pin_bends_both_midspans_by_half_of_it(rig95):
    """Closed form: a pin-ended link with an end moment M carries M/2 at mid-span, surface strain
    (M/2) (h/2) / EI; the pair is equal and opposite on coupler and rocker (same section)."""
    M = 0.1
    base, loaded = solve(rig95, {}, FAST), solve(rig95, {"model.joint_moment.C": M}, FAST)
    link = rig95.mechanism.coupler
    EI = link.material.E_Pa * link.section.inertia_m4
    expected = (M / 2) * (0.125 * 0.0254 / 2) / EI * 1e6
    d = {g: np.array(loaded["gauges"][g]["bending_ue"]) - np.array(base["gauges"][g]["bending_ue"])
         for g in ("coupler_mid", "rocker_mid")}
    for g, x in d.items():
        assert np.mean(np.abs(x)) == pytest.approx(expected, rel=0.03), g
    assert np.sign(np.mean(d["coupler_mid"])) == -np.sign(np.mean(d["rocker_mid"]))


def test_a_moment_at_the_rocker_pivot_bends_only_the_rocker(rig95):
    """Statics of the three-hinged coupler-rocker pair: a moment on the rocker at its ground pivot
    reaches the coupler only as an axial force."""
    base, loaded = solve(rig95, {}, FAST), solve(rig95, {"model.joint_moment.D": 0.1}, FAST)
    dc = np.abs(np.array(loaded["gauges"]["coupler_mid"]["bending_ue"]) - base["gauges"]["coupler_mid"]["bending_ue"])
    dr = np.abs(np.array(loaded["gauges"]["rocker_mid"]["bending_ue"]) - base["gauges"]["rocker_mid"]["bending_ue"])
    assert dr.mean() > 10.0 and dc.max() < 0.02 * dr.mean()


def test_joint_moments_do_the_work_of_a_spring_and_of_friction(rig95):
    """Over a revolution a spring does no net work (conservative) and Coulomb friction takes
    T times the total relative rotation of its pins (the motor's mean torque makes it up)."""
    q = np.linspace(0, 2 * np.pi, 20001)
    spring = JointLoadedFourBar.from_mechanism(rig95.mechanism, [JointMoment("C", moment=0.05, stiffness=0.1),
                                                                 JointMoment("D", stiffness=0.2)])
    assert abs(np.trapezoid(spring.generalized_force(q), q)) < 1e-6
    T = 0.02
    friction = JointLoadedFourBar.from_mechanism(rig95.mechanism, [JointMoment(j, friction=T) for j in JOINTS])
    mo = rig95.mechanism.motion(q, 1.0, 0.0)
    travel = 0.0
    for joint, (first, second) in JOINTS.items():
        phi = mo.link(second).angle - (mo.link(first).angle if first else rig95.mechanism.ground_angle)
        travel += np.sum(np.abs(np.diff(np.unwrap(phi))))
    assert -np.trapezoid(friction.generalized_force(q), q) == pytest.approx(T * travel, rel=0.02)
    with pytest.raises(InputError, match="wind up"):
        JointMoment("B", stiffness=0.1)


def test_a_free_wheeling_crank_conserves_energy_and_keeps_its_mean_speed(rig95):
    mech, w = rig95.mechanism, rig95.drive.speed_rad_s
    for Jd in (0.02, 10.0):
        crank, info = free_wheel(mech, w, Jd, 720)
        J, _, _ = mech.crank_inertia(crank.angle)
        E = 0.5 * (J + Jd) * crank.speed ** 2
        assert np.ptp(E) < 1e-6 * E.mean()
        assert crank.t[-1] == pytest.approx(2 * np.pi / abs(w), rel=1e-12)
        assert crank.angle[-1] - crank.angle[0] == pytest.approx(2 * np.pi, rel=1e-12)
        dw = np.gradient(crank.speed, crank.t)
        assert np.max(np.abs(dw[2:-2] - crank.acceleration[2:-2])) < 0.01 * np.max(np.abs(crank.acceleration))
    # A large inertia: the fluctuation tends to (J_max - J_min) / (2 J_d).
    J, _, _ = mech.crank_inertia(np.linspace(0, 2 * np.pi, 3601))
    assert info["speed_fluctuation"] == pytest.approx((J.max() - J.min()) / (2 * 10.0), rel=0.02)


def test_the_periodic_solver_takes_a_periodic_crank_history(rig95):
    """tmm_core addition: a constant-speed history gives the constant-speed answer; a
    fluctuating one gives what marching to the steady revolution gives."""
    sc = rig95
    w = sc.drive.speed_rad_s
    ref = periodic_steady_state(_td(sc), w, step_deg=3.0)
    hist = periodic_steady_state(_td(sc), 0.0, crank=CrankMotion.constant_speed(w, step_deg=3.0))
    for g in ref.gauges:
        np.testing.assert_allclose(hist.gauges[g][0], ref.gauges[g][0], rtol=1e-10, atol=1e-14)
    crank, _ = free_wheel(sc.mechanism, w, 0.02, 120)
    p = periodic_steady_state(_td(sc), 0.0, crank=crank)
    outs, revs, change = march_to_steady(_td(sc).model, crank, 1e-9, 200)
    for i, g in enumerate(p.gauges):
        np.testing.assert_allclose(p.gauges[g][0], outs[:, 1 + 2 * i], rtol=0, atol=1e-6 * np.ptp(outs[:, 1 + 2 * i]))
    with pytest.raises(InputError, match="exactly one period"):
        periodic_steady_state(_td(sc), 0.0, crank=CrankMotion.constant_speed(w, step_deg=3.0, revolutions=0.5))


def test_faces_and_polarities_are_readings_of_one_solve(rig95):
    unknowns = declared(rig95.raw, str(rig95.path))[2]
    a = variant(rig95, unknowns, {"damping": 3.0})
    b = variant(rig95, unknowns, {"damping": 3.0, "rocker_face": "bottom", "coupler_polarity": -1})
    assert a.physics_key() == b.physics_key()
    assert b.signs == {"rocker_mid": (-1, 1), "coupler_mid": (-1, -1)}
    res = solve(rig95, {}, FAST)
    flipped = read(res, b.signs)
    for g, (sb, sa) in b.signs.items():
        p, q = res["peaks"][g], flipped["peaks"][g]
        assert q["bending_max_ue"] == -p["bending_min_ue"] and q["bending_min_ue"] == -p["bending_max_ue"]
        assert (q["axial_max_ue"], q["axial_min_ue"]) == ((p["axial_max_ue"], p["axial_min_ue"]) if sa > 0 else
                                                          (-p["axial_min_ue"], -p["axial_max_ue"]))
        np.testing.assert_array_equal(flipped["gauges"][g]["bending_ue"], -np.array(res["gauges"][g]["bending_ue"]))
    assert mean_relative_angle(rig95.mechanism, "C") == pytest.approx(
        mean_relative_angle(rig95.mechanism, "C", n=4000), abs=1e-4)
