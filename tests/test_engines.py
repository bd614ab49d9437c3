"""Cross-engine checks: one scenario feeds the TMM, exudyn and MuJoCo engines (issue 4)."""
import dataclasses
import importlib

import numpy as np
import pytest

from cosim import scenario as scenario_mod
from cosim.engines import EngineUnavailable, available_engines, make_engine
from cosim.master import run_prescribed
from cosim.scenario import SCENARIO_DIR, ScenarioError, load
from tmm_core import Coupling
from tmm_core.frequencies import fourbar_frequencies

AL = "alexander_lawrence_400rpm"


def _history(run, gauge, period, n=720):
    """Bending strain over the last revolution, resampled on n points of that revolution."""
    m = run.last_revolution(period)
    t = run.t[m]
    grid = np.linspace(t[0], t[-1], n)
    return np.interp(grid, t, run.gauges[gauge][0][m])


@pytest.fixture(scope="module")
def al_steady():
    """TMM (rotating-frame terms on, the physics exudyn contains) and exudyn, 8 revolutions."""
    sc = load(AL)
    sc_tmm = dataclasses.replace(sc, tmm=dataclasses.replace(sc.tmm, coupling=Coupling.all()))
    return sc, {"tmm": run_prescribed(make_engine("tmm"), sc_tmm, 8),
                "exudyn": run_prescribed(make_engine("exudyn"), sc, 8)}


def test_one_scenario_builds_all_three_engines_and_a_length_change_reaches_all(tmp_path):
    text = (SCENARIO_DIR / f"{AL}.toml").read_text()
    changed = text.replace('length = "11 in"', 'length = "11.3 in"').replace('position = "11 in"', 'position = "11.3 in"')
    assert changed != text
    path = tmp_path / "al_longer_coupler.toml"
    path.write_text(changed)
    base, longer = load(AL), load(path)
    assert longer.mechanism.coupler.length_m == pytest.approx(11.3 * 0.0254)
    for name in ("tmm", "exudyn", "mujoco"):
        a = run_prescribed(make_engine(name), base, 0.05)
        b = run_prescribed(make_engine(name), longer, 0.05)
        # The rocker tip (joint C) moves elsewhere in every engine.
        assert np.max(np.abs(a.nodes["rocker"][-1, -1] - b.nodes["rocker"][-1, -1])) > 1e-3, name


def test_exudyn_and_tmm_strain_histories_agree(al_steady):
    """Same mechanism, prescribed 400 rpm, same (stiffness-proportional) damping, steady state:
    RMS difference over a revolution within 5 % of the exudyn peak-to-peak, and the coupler's
    and the follower's negative peaks within 5 %. Measured: follower 3.8 %, coupler 2.2 % RMS."""
    sc, runs = al_steady
    for gauge in ("follower_mid", "coupler_mid"):
        t, e = _history(runs["tmm"], gauge, sc.revolution_period_s), _history(runs["exudyn"], gauge, sc.revolution_period_s)
        assert np.sqrt(np.mean((t - e) ** 2)) < 0.05 * np.ptp(e), gauge
        assert t.min() == pytest.approx(e.min(), rel=0.05), gauge
    t, e = (_history(runs[k], "coupler_mid", sc.revolution_period_s) for k in ("tmm", "exudyn"))
    assert t.max() == pytest.approx(e.max(), rel=0.05)


def test_exudyn_and_tmm_follower_positive_peak(al_steady):
    """Follower positive peak at 400 rpm within 5 %. With the quasi-static axial force it was
    17 % low (TMM +267 vs exudyn +324 microstrain): the gap was the second-order beam physics
    (shortening from bending and the step's own axial force) that the 'dynamic' default now
    carries."""
    sc, runs = al_steady
    t, e = (_history(runs[k], "follower_mid", sc.revolution_period_s) for k in ("tmm", "exudyn"))
    assert t.max() == pytest.approx(e.max(), rel=0.05)


def test_stiff_links_approach_the_rigid_quasi_static_estimate():
    """E x 1000: the flexible engines' strains approach MuJoCo's rigid-body-inertia estimate, and
    all three drive torques coincide (same sign convention)."""
    sc = load(AL)
    mech = sc.mechanism
    stiff = {l.name: dataclasses.replace(l, material=dataclasses.replace(l.material, E_Pa=l.material.E_Pa * 1000))
             for l in mech.links()}
    sc = dataclasses.replace(sc, mechanism=dataclasses.replace(mech, **stiff))
    runs = {name: run_prescribed(make_engine(name), sc, 2) for name in ("tmm", "exudyn", "mujoco")}
    T = sc.revolution_period_s
    for gauge in ("follower_mid", "coupler_mid"):
        rigid = _history(runs["mujoco"], gauge, T)
        for name in ("tmm", "exudyn"):
            flex = _history(runs[name], gauge, T)
            assert np.sqrt(np.mean((flex - rigid) ** 2)) < 0.02 * np.ptp(rigid), (name, gauge)
    grid = np.linspace(T, 2 * T, 360)
    torque = {k: np.interp(grid, r.t, r.drive_torque) for k, r in runs.items()}
    peak = np.max(np.abs(torque["mujoco"]))
    for name in ("tmm", "exudyn"):
        np.testing.assert_allclose(torque[name], torque["mujoco"], atol=0.02 * peak)


def test_exudyn_natural_frequencies_match_the_tmm_search():
    from cosim.engines.exudyn import natural_frequencies
    sc = load(AL)
    for angle in (0.0, 1.0):
        f_exu = natural_frequencies(sc, angle, 3)
        f_tmm = fourbar_frequencies(sc.mechanism, np.array([angle]), 3, 1000.0)[0]
        np.testing.assert_allclose(f_exu, f_tmm, rtol=2e-2)


@pytest.mark.slow
def test_exudyn_converges_in_mesh_and_step():
    """Strain peaks change by < 1 % from 8 to 16 elements and from 1e-4 s to 5e-5 s."""
    sc = load(AL)
    T = sc.revolution_period_s
    peaks = []
    for elements, step in ((8, 1e-4), (16, 1e-4), (16, 5e-5)):
        s = dataclasses.replace(sc, exudyn=dataclasses.replace(sc.exudyn, elements=elements, step_s=step))
        r = run_prescribed(make_engine("exudyn"), s, 5)
        peaks.append([f(_history(r, g, T)) for g in ("follower_mid", "coupler_mid") for f in (np.min, np.max)])
    peaks = np.array(peaks)
    np.testing.assert_allclose(peaks[1], peaks[0], rtol=1e-2)
    np.testing.assert_allclose(peaks[2], peaks[1], rtol=1e-2)


def test_missing_engine_library_gives_a_clear_message_and_the_others_run(monkeypatch):
    real = importlib.import_module

    def fake(name, *a, **k):
        if name == "exudyn":
            raise ImportError("libexudyn.so: cannot open shared object file")
        return real(name, *a, **k)

    monkeypatch.setattr(importlib, "import_module", fake)
    with pytest.raises(EngineUnavailable, match=r"engine 'exudyn' is unavailable.*pip install"):
        make_engine("exudyn")
    assert "exudyn" in (available_engines()["exudyn"] or "")
    assert available_engines()["tmm"] is None
    run = run_prescribed(make_engine("tmm"), load(AL), 0.05)
    assert np.all(np.isfinite(run.drive_torque))


@pytest.mark.parametrize("edit, key, value", [
    # An unknown key is named, its value never echoed (a file that is not a scenario stays private).
    (('[drive]', '[drive]\nsped = "400 rpm"'), "drive.sped", None),
    (('length = "4 in"', 'length = "4"'), "links.crank.length", "4"),
    (('length = "4 in"', 'length = "-4 in"'), "links.crank.length", "-4 in"),
    (('length = "4 in"', 'length = "4 kg"'), "links.crank.length", "4 kg"),
    (('ground = "10 in"', 'ground = "30 in"'), "linkage", None),
    (('section = "crank"', 'section = "cranky"'), "links.crank.section", "cranky"),
])
def test_bad_scenario_input_names_file_key_and_value(tmp_path, edit, key, value):
    text = (SCENARIO_DIR / f"{AL}.toml").read_text().replace(*edit, 1)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as err:
        load(path)
    msg = str(err.value)
    assert str(path) in msg and f"key '{key}'" in msg
    if value is not None:
        assert repr(value) in msg


def test_scenario_not_found_lists_the_available_ones():
    with pytest.raises(ScenarioError, match="not found.*alexander_lawrence_400rpm"):
        load("no_such_rig")


def test_scenario_records_assumptions_and_converts_units():
    sc = load(AL)
    keys = {a.key for a in sc.assumptions}
    assert {"materials.aluminium.E", "materials.aluminium.density", "links.coupler.damping"} <= keys
    assert sc.mechanism.crank.length_m == pytest.approx(0.1016)
    assert sc.mechanism.crank.material.E_Pa == pytest.approx(10.3e6 * 6894.757, rel=1e-6)
    assert sc.drive.speed_rad_s == pytest.approx(-400 * 2 * np.pi / 60)
    assert scenario_mod.UREG is not None
