"""Unit tests of the DC motor model (cosim.motor): closed-form checks, controller behaviour and
bad input. Expected values come from closed-form solutions of the motor equations."""
import math

import numpy as np
import pytest

from cosim import scenario as sc
from cosim.motor import Motor, MotorParameters, SetPoint
from cosim.motor_design import derive_pm_dc_motor
from tmm_core import InputError

RPM = math.pi / 30


def _params(**kw):
    values, _ = derive_pm_dc_motor(0.5 * 745.7, 1750 * RPM, 90.0)
    base = dict(values, supply_voltage_V=90.0, gear_ratio=4.0, flywheel_inertia_kg_m2=5e-3)
    base.update(kw)
    return MotorParameters(**base)


def test_derived_motor_meets_its_rating():
    """At rated voltage and rated output torque the derived motor runs at rated speed with the
    assumed efficiency (closed-form steady state of V = R i + Ke w, Kt i = T + b w + Tc)."""
    P, w, V = 0.5 * 745.7, 1750 * RPM, 90.0
    p, _ = derive_pm_dc_motor(P, w, V, efficiency=0.8)
    R, K, b, Tc = p["resistance_ohm"], p["torque_constant_Nm_A"], p["viscous_friction_Nm_s_rad"], p["coulomb_friction_Nm"]
    T = P / w
    # Steady speed at voltage V and load T: V = R (T + b w + Tc) / K + K w.
    speed = (V - R * (T + Tc) / K) / (K + R * b / K)
    i = (T + b * speed + Tc) / K
    assert speed == pytest.approx(w, rel=1e-12)
    assert P / (V * i) == pytest.approx(0.8, rel=1e-12)
    assert p["inductance_H"] / R == pytest.approx(0.01)


def test_open_loop_current_rise_matches_closed_form():
    """Crank held at constant speed, constant voltage (integrator only, no gains): the armature
    current rises as i_ss (1 - exp(-t R / L))."""
    p = _params(kp_V_s_rad=0.0, ki_V_rad=0.0)
    motor = Motor(p, integrates_crank=False)
    w, V = 30.0, 60.0
    state = motor.start(0.0, 0.0, w)
    state = type(state)(0.0, 0.0, V, 0.0, w, 0.0, w)         # zero current, integrator = voltage
    ts = np.linspace(0.002, 0.05, 25)
    _, tr = motor.advance(state, 0.05, crank=lambda t: (w * t, np.full(np.shape(t), w)), samples=ts)
    i_ss = (V - p.back_emf_V_s_rad * p.gear_ratio * w) / p.resistance_ohm
    expected = i_ss * (1 - np.exp(-ts * p.resistance_ohm / p.inductance_H))
    np.testing.assert_allclose(tr.current_A, expected, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(tr.voltage_V, V)


def test_energy_states_close_the_motor_balance():
    """V i = R i^2 + d(L i^2 / 2)/dt + T_f w_m + T_drive w_crank (Ke = Kt): the integrated energy
    states must close to integration accuracy over a transient with a varying crank speed."""
    p = _params()
    motor = Motor(p, integrates_crank=False)
    s0 = motor.start(0.0, 0.0, 35.0)
    crank = lambda t: (35 * t - 0.1 * np.cos(40 * t), 35 + 4 * np.sin(40 * np.asarray(t)))   # noqa: E731
    s1, tr = motor.advance(s0, 0.2, crank=crank, samples=np.linspace(0.01, 0.2, 20))
    magnetic = 0.5 * p.inductance_H * (s1.current_A**2 - s0.current_A**2)
    balance = s1.energy_in_J - s1.copper_loss_J - s1.friction_loss_J - s1.drive_work_J - magnetic
    assert abs(balance) < 1e-7 * s1.energy_in_J


def test_speed_loop_rejects_a_constant_load():
    """Kinematic use (the motor turns the crank): after a load torque step the PI returns the
    crank to the set-point, and the current carries load plus friction."""
    p = _params().with_gains_for(5.0)
    motor = Motor(p, integrates_crank=True)
    w = 30.0
    p = type(p)(**{**p.__dict__, "setpoint": SetPoint("constant", w)})
    motor = Motor(p, integrates_crank=True)
    state = motor.start(0.0, 0.0, w)
    load = 2.0
    state, tr = motor.advance(state, 2.0, load_torque=lambda t: np.full(np.shape(t), load),
                              samples=np.linspace(0.01, 2.0, 200))
    assert tr.crank_speed_rad_s.min() < w - 0.05          # the step pulled the speed down ...
    assert state.crank_speed_rad_s == pytest.approx(w, abs=1e-6)   # ... and the integrator recovered it
    wm = p.gear_ratio * w
    friction = p.viscous_friction_Nm_s_rad * wm + p.coulomb_friction_Nm * math.tanh(wm / 0.01)
    assert state.current_A == pytest.approx((load / p.gear_ratio + friction) / p.torque_constant_Nm_A, rel=1e-6)


def test_voltage_saturates_and_integrator_does_not_wind_up():
    """A set-point step from rest: the voltage stays within the supply, the integrator does not
    grow past the supply voltage while saturated (conditional integration), and the speed settles
    without the large overshoot a wound-up integrator gives."""
    w = 35.0
    p = _params(setpoint=SetPoint("step", w, 0.0, 0.0), flywheel_inertia_kg_m2=0.1).with_gains_for(5.0)
    motor = Motor(p, integrates_crank=True)
    state = motor.start(0.0, 0.0, 0.0)
    ts = np.linspace(0.005, 3.0, 600)
    _, tr = motor.advance(state, 3.0, load_torque=lambda t: np.zeros(np.shape(t)), samples=ts)
    assert tr.voltage_V.max() <= p.supply_voltage_V + 1e-9
    assert tr.voltage_V.min() >= 0.0
    assert np.any(tr.voltage_V >= p.supply_voltage_V - 1e-9)      # it did saturate
    assert tr.crank_speed_rad_s.max() < 1.05 * w
    assert tr.crank_speed_rad_s[-1] == pytest.approx(w, rel=1e-4)


def test_setpoint_profiles():
    assert SetPoint("constant", 5.0)(np.array([0.0, 9.0])).tolist() == [5.0, 5.0]
    np.testing.assert_allclose(SetPoint("ramp", 10.0, 0.0, 1.0, 2.0)(np.array([0.0, 1.0, 2.0, 3.0, 4.0])),
                               [0.0, 0.0, 5.0, 10.0, 10.0])
    np.testing.assert_allclose(SetPoint("step", 10.0, 2.0, 1.0)(np.array([0.5, 1.5])), [2.0, 10.0])


def test_cascade_control_holds_speed_tighter_than_voltage_control():
    """With an inner current loop the same speed-loop bandwidth rejects a load disturbance
    without the inductance limiting it; both end at the set-point."""
    w = 30.0
    results = {}
    for name, cur in (("voltage", None), ("cascade", 500.0)):
        p = _params(setpoint=SetPoint("constant", w), reversible=True, supply_voltage_V=400.0)
        p = p.with_gains_for(40.0, 0.0, cur)
        motor = Motor(p, integrates_crank=True)
        state = motor.start(0.0, 0.0, w)
        _, tr = motor.advance(state, 0.5, load_torque=lambda t: 3.0 * np.sin(2 * math.pi * 25 * np.asarray(t)),
                              samples=np.linspace(0.001, 0.5, 500))
        results[name] = np.ptp(tr.crank_speed_rad_s[250:])
    assert results["cascade"] < 0.5 * results["voltage"], results


def test_compliant_shaft_tends_to_the_rigid_shaft():
    """A very stiff shaft gives the rigid-shaft motion; its steady twist is torque / stiffness."""
    w = 30.0
    common = dict(setpoint=SetPoint("constant", w))
    rigid = Motor(_params(**common).with_gains_for(3.0), integrates_crank=True)
    stiff_p = _params(**common, shaft_stiffness_Nm_rad=2e4, shaft_damping_Nm_s_rad=5.0).with_gains_for(3.0)
    stiff = Motor(stiff_p, integrates_crank=True)
    load = lambda t: 1.5 + 0.5 * np.sin(60 * np.asarray(t))        # noqa: E731
    ts = np.linspace(0.01, 0.6, 60)
    _, a = rigid.advance(rigid.start(0.0, 0.0, w, load_torque=1.5), 0.6, load_torque=load, samples=ts)
    s0 = stiff.start(0.0, 0.0, w, load_torque=1.5)
    _, b = stiff.advance(s0, 0.6, load_torque=load, samples=ts)
    np.testing.assert_allclose(b.crank_speed_rad_s, a.crank_speed_rad_s, atol=2e-3 * w)
    p = stiff_p
    wm = p.gear_ratio * w
    friction = p.viscous_friction_Nm_s_rad * wm + p.coulomb_friction_Nm * math.tanh(wm / 0.01)
    T = p.gear_ratio * (p.torque_constant_Nm_A * s0.current_A - friction)
    assert T == pytest.approx(1.5, rel=1e-9)
    assert s0.rotor_angle_rad - s0.crank_angle_rad == pytest.approx(T / p.shaft_stiffness_Nm_rad, rel=1e-12)


def test_clockwise_setpoint_runs_on_negative_voltage():
    w = -30.0
    p = _params(setpoint=SetPoint("constant", w)).with_gains_for(3.0)
    assert p.voltage_range == (-90.0, 0.0)
    motor = Motor(p, integrates_crank=True)
    state, tr = motor.advance(motor.start(0.0, 0.0, w), 1.0, load_torque=lambda t: np.zeros(np.shape(t)),
                              samples=np.linspace(0.01, 1.0, 100))
    assert state.crank_speed_rad_s == pytest.approx(w, rel=1e-4)
    assert tr.voltage_V.max() <= 0.0


@pytest.mark.parametrize("field, value, words", [
    ("rotor_inertia_kg_m2", -1e-3, "rotor_inertia_kg_m2"),
    ("flywheel_inertia_kg_m2", -1.0, "flywheel_inertia_kg_m2"),
    ("resistance_ohm", -1.0, "resistance_ohm"),
    ("inductance_H", 0.0, "inductance_H"),
    ("gear_ratio", 0.0, "gear_ratio"),
])
def test_bad_motor_parameters_are_refused(field, value, words):
    with pytest.raises(InputError, match=words):
        _params(**{field: value})


def test_setpoint_above_supply_speed_is_refused():
    p = _params()
    top = p.no_load_crank_speed()
    too_fast = _params(setpoint=SetPoint("constant", 1.01 * top))
    with pytest.raises(InputError, match=r"setpoint .* above .* supply allows"):
        too_fast.check_setpoint()


@pytest.mark.parametrize("overrides, key", [
    ({"motor.resistance": "-1 ohm"}, "motor.resistance"),
    ({"motor.rotor_inertia": "-1e-3 kg*m^2"}, "motor.rotor_inertia"),
    ({"motor.flywheel_inertia": "-1 kg*m^2", "motor.flywheels": None}, "motor.flywheel_inertia"),
    ({"motor.flywheels[0].diameter": "-6 in"}, r"motor.flywheels\[0\].diameter"),
    ({"drive.speed": "600 rpm", "drive.mode": "motor"}, "key 'drive.speed'.*setpoint"),
    ({"motor.gear_ratio": 0}, "motor.gear_ratio"),
    ({"coupling.scheme": "newton"}, "coupling.scheme"),
    ({"drive.mode": "motor", "motor": None}, "drive.mode"),
])
def test_bad_motor_scenario_names_the_key(overrides, key):
    with pytest.raises(sc.ScenarioError, match=key):
        sc.load("crank_rocker_373rpm").with_overrides(overrides)


def test_a_setpoint_beyond_the_supply_is_refused_only_where_the_motor_drives():
    """600 rpm is beyond the supply's no-load speed: refused for a motor-driven scenario and a
    motor run, accepted at a prescribed speed (the [motor] table is then unused)."""
    fast = sc.load("crank_rocker_373rpm").with_overrides({"drive.speed": "600 rpm", "drive.mode": "prescribed"})
    from cosim.master import CoSimulation
    with pytest.raises(InputError, match=r"setpoint .* above .* supply allows"):
        CoSimulation(fast, (), mode="motor")


def test_scenario_motor_declares_its_derived_constants():
    s = sc.load("crank_rocker_373rpm")
    keys = {a.key for a in s.assumptions}
    for k in ("motor.resistance", "motor.inductance", "motor.torque_constant", "motor.rotor_inertia",
              "motor.coulomb_friction", "motor.gear_ratio", "motor.controller"):
        assert k in keys
    assert "motor.flywheels[1]" in keys          # the added steel flywheel is an assumption
    # Two 6 x 0.75 in aluminium disks and a 12 x 2 in steel disk: m r^2 / 2 with m = rho pi r^2 t.
    def disk(d_in, t_in, rho):
        r, t = 0.5 * d_in * 0.0254, t_in * 0.0254
        return 0.5 * rho * math.pi * r**2 * t * r**2
    expected = 2 * disk(6, 0.75, 5.292 * 515.378818) + disk(12, 2, 0.284 * 27679.9047)
    assert s.motor.flywheel_inertia_kg_m2 == pytest.approx(expected, rel=1e-6)
    weak = sc.load("crank_rocker_373rpm_weak_drive")
    assert weak.motor.flywheel_inertia_kg_m2 == pytest.approx(2 * disk(6, 0.75, 5.292 * 515.378818), rel=1e-6)
