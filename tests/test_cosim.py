"""Co-simulation master (issue 5): motor-driven engines against a monolithic reference, the
coupling order, the energy balance, the flywheel effect, motor vs prescribed drive, early stop,
partial results and bad input.

The monolithic reference (tests/monolithic.py) writes the rigid four-bar and the motor as one ODE
solved by scipy at rtol 1e-11; it shares no code with cosim.motor or cosim.master.
"""
import math

import numpy as np
import pytest

from cosim import scenario as sc
from cosim.master import CoSimulation, CouplingError
from cosim.metrics import speed_fluctuation
from tests.monolithic import RigidFourBarWithMotor

REVS = 3


def _fe(name="crank_rocker_373rpm", **overrides):
    """The rig without gauges (the rigid reference has no strains; MuJoCo then skips its strain
    solve), with key-path overrides."""
    return sc.load(name).with_overrides({"gauges": None, **overrides})


def _scenario(base, **coupling):
    return base.with_overrides({f"coupling.{k}": v for k, v in coupling.items()})


def _last_revolution(run, period):
    return run.t > run.t[-1] - period * (1 - 1e-9)


def _compare(channel, ref, scenario):
    """Mean speed, fluctuation and drive-torque errors of the last revolution against the reference."""
    run = channel.run
    f = channel.speed_fluctuation()
    g = speed_fluctuation(ref["t"], ref["angle"], ref["speed"])
    last = _last_revolution(run, scenario.revolution_period_s)
    T_ref = np.interp(run.t[last], ref["t"], ref["load_torque"])
    return {"mean": abs(f["mean"][-1] / g["mean"][-1] - 1),
            "fluctuation": abs(f["fluctuation"][-1] / g["fluctuation"][-1] - 1),
            "torque": float(np.max(np.abs(run.drive_torque[last] - T_ref)) / np.max(np.abs(T_ref))),
            "values": (f["mean"][-1], g["mean"][-1], f["fluctuation"][-1], g["fluctuation"][-1])}


@pytest.fixture(scope="module")
def fe_mujoco():
    s = _scenario(_fe(), scheme="gauss_seidel", extrapolation="linear")
    ref = RigidFourBarWithMotor(s.mechanism, s.motor).solve(REVS * s.revolution_period_s,
                                                            None, None, scenario=s)
    res = CoSimulation(s, ("mujoco",), mode="motor").run(revolutions=REVS)
    return s, ref, res["mujoco"]


@pytest.fixture(scope="module")
def stiff_tmm():
    """The FE rig with links 10^6 times stiffer (the toggle makes the instantaneous structure
    soft: at 1000x a 248 Hz mode remains near 0 deg), 2 segments, linear beams; compared with the
    monolithic model of the same lumped masses."""
    # The links' damping is declared as a ratio at their 79 Hz mode; 10^6 times stiffer, the same
    # stiffness-proportional coefficient would be far beyond critical, so it is dropped (and with
    # it the declared unknowns that vary it).
    base = _fe(**{"materials.aluminium.E": "1e13 psi", "solver.tmm.segments": 2, "solver.tmm.beam_column": False,
                 "solver.tmm.step": "1 deg", "links.coupler.damping": None, "links.rocker.damping": None,
                 "uncertainty": None})
    s = _scenario(base, scheme="iterated", macro_step="2 deg", tolerance=1e-6)
    ref = RigidFourBarWithMotor(s.mechanism, s.motor, "lumped").solve(REVS * s.revolution_period_s, None, None,
                                                                       scenario=s)
    res = CoSimulation(s, ("tmm",), mode="motor").run(revolutions=REVS)
    return s, ref, res["tmm"]


def test_mujoco_with_motor_matches_the_monolithic_reference(fe_mujoco):
    s, ref, ch = fe_mujoco
    assert ch.status == "completed", ch.error
    e = _compare(ch, ref, s)
    # Measured: mean 1e-6, fluctuation 0.3 %, torque 0.9 % of peak (gauss_seidel, 2 deg macro step).
    assert e["mean"] < 0.005, e
    assert e["fluctuation"] < 0.02, e
    assert e["torque"] < 0.02, e


def test_tmm_with_stiff_links_and_motor_matches_the_monolithic_reference(stiff_tmm):
    s, ref, ch = stiff_tmm
    assert ch.status == "completed", ch.error
    e = _compare(ch, ref, s)
    # Measured (iterated): mean 3e-6, fluctuation 0.01 %, torque 0.2 % of peak. Gauss-Seidel gives
    # 0.8 % and 3.4 %: the kinematic engine's torque follows the crank acceleration directly.
    assert e["mean"] < 0.005, e
    assert e["fluctuation"] < 0.02, e
    assert e["torque"] < 0.02, e
    assert ch.passes.max() <= s.coupling.max_iterations


@pytest.mark.parametrize("which", ["fe_mujoco", "stiff_tmm"])
def test_energy_balance_over_a_steady_revolution(which, request):
    """Electrical energy in = copper + friction losses + change of magnetic and drive kinetic
    energy + mechanical work the linkage takes (from the engine's own torque), within 1 %."""
    _, _, ch = request.getfixturevalue(which)
    e = ch.energy_balance()
    assert e["electrical_in_J"] > 0
    assert abs(e["residual_J"]) < 0.01 * e["electrical_in_J"], e


def test_coupling_error_shrinks_at_the_scheme_order():
    """Explicit Jacobi: first order with constant extrapolation, second with linear. The error
    is the crank-speed difference over the last revolution from the iterated (converged)
    coupling of the same engine at a small macro step, which removes MuJoCo's own O(h) error.
    Measured (x1e-4 of the mean speed at 4, 2, 1 deg): constant 501, 234, 111; linear 68.5,
    15.6, 3.7."""
    base = _fe(**{"solver.mujoco.step": "0.1 deg"})
    s = _scenario(base)
    w = s.drive.speed_rad_s

    def run(scheme, extrapolation, macro):
        si = _scenario(base, scheme=scheme, extrapolation=extrapolation, macro_step=macro)
        return CoSimulation(si, ("mujoco",), mode="motor").run(revolutions=REVS)["mujoco"].run

    ref = run("iterated", "linear", "0.5 deg")
    orders = {}
    for extrapolation in ("constant", "linear"):
        err = []
        for macro in ("4 deg", "2 deg", "1 deg"):
            r = run("jacobi", extrapolation, macro)
            last = _last_revolution(r, s.revolution_period_s)
            err.append(np.max(np.abs(r.crank_speed[last] - np.interp(r.t[last], ref.t, ref.crank_speed))) / w)
        orders[extrapolation] = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert np.all((orders["constant"] > 0.8) & (orders["constant"] < 1.3)), orders
    assert np.all((orders["linear"] > 1.7) & (orders["linear"] < 2.5)), orders


def test_removing_the_flywheels_raises_the_speed_fluctuation(fe_mujoco):
    """FE crank-rocker rig at 373 rpm (MuJoCo, motor as declared in the scenario). Measured:
    0.585 with the two aluminium flywheels, 0.719 without."""
    s, _, with_fw = fe_mujoco
    bare = _fe(**{"motor.flywheels": None})
    assert bare.motor.flywheel_inertia_kg_m2 == 0.0
    without = CoSimulation(bare, ("mujoco",), mode="motor").run(revolutions=REVS)["mujoco"]
    a = with_fw.speed_fluctuation()["fluctuation"][-1]
    b = without.speed_fluctuation()["fluctuation"][-1]
    print(f"FE rig 373 rpm speed fluctuation: {a:.3f} with flywheels, {b:.3f} without")
    assert b > 1.1 * a


def test_stiff_speed_loop_converges_to_the_prescribed_strains():
    """Alexander-Lawrence four-bar at 400 rpm (cw) with a test motor (0.5 hp, reversible, cascade
    control for the stiff loops): the strain difference from the prescribed-speed run over the
    last revolution falls as the speed-loop bandwidth rises. MuJoCo's rigid strains; measured
    (follower) 8.4 %, 4.6 %, 1.1 % at 2, 32, 128 Hz."""
    motor = {"rated_power": "0.5 hp", "rated_speed": "1750 rpm", "rated_voltage": "90 V", "gear_ratio": 4,
             "flywheel_inertia": "2e-3 kg*m^2", "reversible": True}
    s = sc.load("alexander_lawrence_400rpm").with_overrides({"motor": motor, "coupling": {"macro_step": "2 deg"},
                                                             "solver.mujoco.step": "0.2 deg"})
    prescribed = CoSimulation(s, ("mujoco",), mode="prescribed").run(revolutions=2)["mujoco"].run
    lastp = _last_revolution(prescribed, s.revolution_period_s)
    key = np.mod(prescribed.crank_angle[lastp], 2 * math.pi)
    order = np.argsort(key)
    errors = []
    for bw in (2, 32, 128):
        controller = ({"bandwidth": f"{bw} Hz"} if bw < 10 else
                      {"bandwidth": f"{bw} Hz", "current_bandwidth": f"{4 * bw} Hz"})
        run = CoSimulation(s.with_overrides({"motor.controller": controller}), ("mujoco",),
                           mode="motor").run(revolutions=2)["mujoco"].run
        last = _last_revolution(run, s.revolution_period_s)
        worst = 0.0
        for g, (bending, _) in run.gauges.items():
            ref = np.interp(np.mod(run.crank_angle[last], 2 * math.pi), key[order], prescribed.gauges[g][0][lastp][order])
            worst = max(worst, float(np.max(np.abs(bending[last] - ref)) / np.max(np.abs(ref))))
        errors.append(worst)
    assert errors[0] > errors[1] > errors[2], errors
    assert errors[2] < 0.02, errors


def test_prescribed_mode_through_the_master_is_the_engine_alone():
    """In prescribed mode the master only steps the engine: same strains as the engine driven
    directly (TMM fast path)."""
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    s = sc.load("crank_rocker_373rpm")
    res = CoSimulation(s, ("tmm",), mode="prescribed").run(revolutions=1)
    assert res.status == "completed" and res["tmm"].motor is None
    alone = run_prescribed(make_engine("tmm"), s, revolutions=1)
    n = min(len(alone.t), len(res["tmm"].run.t))
    np.testing.assert_allclose(res["tmm"].run.t[:n], alone.t[:n], rtol=1e-12)
    np.testing.assert_allclose(res["tmm"].run.gauges["coupler_mid"][0][:n], alone.gauges["coupler_mid"][0][:n],
                               rtol=1e-9, atol=1e-12)


def test_macro_step_time_comes_from_the_step_count(fe_mujoco):
    s, _, ch = fe_mujoco
    H = s.coupling.macro_step_s
    h = s.mujoco.step_s
    t = ch.run.t
    k = np.rint(t / h)
    np.testing.assert_array_equal(t, k * h)         # exactly the integer multiple, no accumulated drift
    assert np.isclose(H / h, round(H / h))


def test_callback_streams_and_stops_early():
    s = _scenario(_fe())
    seen = []

    def callback(step):
        seen.append((step.step, step.t, set(step.outputs)))
        return step.step == 10

    res = CoSimulation(s, ("mujoco",), mode="motor").run(revolutions=1, callback=callback)
    assert res.status == "stopped" and res["mujoco"].status == "stopped"
    assert [x[0] for x in seen] == list(range(1, 11))
    assert seen[-1][1] == pytest.approx(10 * s.coupling.macro_step_s, rel=1e-12)
    assert res["mujoco"].run.t[-1] == pytest.approx(seen[-1][1], rel=1e-12)
    assert len(res["mujoco"].motor.t) == len(res["mujoco"].run.t)


def test_a_failing_engine_keeps_its_partial_results_and_the_others_run_on():
    """An engine that fails after a few macro steps stops only its own channel: it keeps its
    samples and its message, and MuJoCo completes."""
    from cosim.engines.base import EngineError
    from cosim.engines.tmm import TMMEngine

    class FailsLater(TMMEngine):
        calls = 0

        def advance(self, t_next, drive):
            FailsLater.calls += 1
            if FailsLater.calls > 5:
                raise EngineError("tmm: a deliberate failure after 5 macro steps")
            return super().advance(t_next, drive)

    from cosim.engines import make_engine
    s = sc.load("crank_rocker_373rpm")
    res = CoSimulation(s, {"tmm": FailsLater(), "mujoco": make_engine("mujoco")}, mode="motor").run(revolutions=0.5)
    tmm, mj = res["tmm"], res["mujoco"]
    assert res.status == "failed"
    assert tmm.status == "failed" and "deliberate" in tmm.error
    assert len(tmm.run.t) > 0 and tmm.run.t[-1] < mj.run.t[-1]
    assert mj.status == "completed"


def test_weak_drive_pushes_the_rocker_past_its_euler_load_and_the_tmm_carries_on():
    """With the thesis's drive alone (crank_rocker_373rpm_weak_drive) the crank decelerates so hard
    near the toggle that the rocker's quasi-static compression passes its static Euler load (the
    old beam-column TMM stopped there at 7 ms). That is a transient of the dynamics: the time-domain
    TMM integrates through it as exudyn does, and the two agree on the speed fluctuation."""
    s = sc.load("crank_rocker_373rpm_weak_drive")
    res = CoSimulation(s, ("tmm", "mujoco"), mode="motor").run(revolutions=1.3)
    assert res["tmm"].status == "completed", res["tmm"].error
    f_tmm = res["tmm"].speed_fluctuation()["fluctuation"][0]
    f_mj = res["mujoco"].speed_fluctuation()["fluctuation"][0]
    assert f_tmm > 0.4 and f_tmm == pytest.approx(f_mj, abs=0.05)


def test_macro_step_that_is_not_a_multiple_of_an_engine_step_is_refused():
    s = _fe(**{"coupling.macro_step": "1.5e-4 s"})
    with pytest.raises(CouplingError, match=r"not a whole multiple of the mujoco step .*solver.mujoco.step"):
        CoSimulation(s, ("mujoco",), mode="motor")


def test_motor_mode_needs_a_motor_table():
    s = sc.load("alexander_lawrence_400rpm")
    with pytest.raises(Exception, match=r"no \[motor\] table"):
        CoSimulation(s, ("tmm",), mode="motor")


def test_start_from_rest_follows_the_ramp():
    # The thesis's drive alone: the default drive's added flywheel could not follow a 0.3 s ramp.
    base = _fe("crank_rocker_373rpm_weak_drive",
               **{"motor.setpoint": {"profile": "ramp", "start": "0 rpm", "duration": "0.3 s"}})
    s = _scenario(base, start="rest")
    ch = CoSimulation(s, ("mujoco",), mode="motor").run(0.6)["mujoco"]
    assert ch.status == "completed"
    assert ch.run.crank_speed[0] < 0.05 * s.drive.speed_rad_s
    f = ch.speed_fluctuation()
    assert len(f["mean"]) >= 2 and f["mean"][-1] == pytest.approx(s.drive.speed_rad_s, rel=0.05)


def test_exudyn_runs_with_the_motor_and_balances_energy(fe_mujoco):
    """The flexible exudyn model carries the drive inertia on its hub and takes the motor torque.
    Its first-revolution speed fluctuation is within 5 % of the rigid MuJoCo one (measured 0.718
    vs 0.737: the links' flexibility), and its energy balance over the second revolution closes
    within 1 % (the first is a start-up transient in which the drive returns energy)."""
    s = sc.load("crank_rocker_373rpm")
    ch = CoSimulation(s, ("exudyn",), mode="motor").run(revolutions=2.05)["exudyn"]
    assert ch.status == "completed", ch.error
    f = ch.speed_fluctuation()["fluctuation"][0]
    g = fe_mujoco[2].speed_fluctuation()["fluctuation"][0]
    assert f == pytest.approx(g, rel=0.05)
    e = ch.energy_balance()
    assert abs(e["residual_J"]) < 0.01 * e["electrical_in_J"], e
