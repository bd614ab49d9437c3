"""Uncertainty bands over the extended declared unknowns with a Morris ranking (issue 19)."""
import csv

import numpy as np
import pytest

from cosim.scenario import SCENARIO_DIR, ScenarioError, load
from cosim.uncertainty import run_uncertainty
from cosim.unknowns import Settings, declared, solve, variant

PINNED = {"damping": 3.0, "modulus": 10.3e6, "gravity_in_plane": 1.0, "gravity_direction": 30.0,
          "wire_moment_C": 0.05, "wire_stiffness_C": 0.05, "wire_moment_D": -0.05, "wire_stiffness_D": 0.05,
          "joint_friction": 0.01, "drive_inertia": 0.05}


def _pinned(tmp_path):
    """The 95 rpm rig with every declared unknown pinned to one value (zero spread)."""
    sc = load("crank_rocker_95rpm")
    unknowns = declared(sc.raw, str(sc.path))[2]
    text = [f'extends = "{SCENARIO_DIR / "crank_rocker_95rpm"}.toml"', "[uncertainty]", "samples = 2"]
    for name, u in unknowns.items():
        text.append(f"[uncertainty.parameters.{name}]")
        if u.discrete:
            text.append(f"values = [{u.values[-1]!r}]".replace("'", '"'))
        else:
            x = PINNED[name]
            text += [f'low = "{x} {u.unit}"', f'high = "{x} {u.unit}"']
    path = tmp_path / "pinned.toml"
    path.write_text("\n".join(text) + "\n")
    sample = {n: (u.values[-1] if u.discrete else PINNED[n]) for n, u in unknowns.items()}
    return path, sc, unknowns, sample


def test_zero_spread_reproduces_the_pinned_model(tmp_path):
    path, sc, unknowns, sample = _pinned(tmp_path)
    folder, summary = run_uncertainty(str(path), workers=1, out=tmp_path / "u0", record=False, sensitivity=False,
                                      progress=False)
    assert summary["status"] == "completed"
    v = variant(sc, unknowns, sample)
    from cosim.unknowns import read
    direct = read(solve(sc.with_overrides(v.overrides), v.model, Settings()), v.signs)
    for r in csv.DictReader(open(folder / "band.csv")):
        assert float(r["low_ue"]) == pytest.approx(float(r["high_ue"]), abs=1e-9)
    for g, b in summary["band"].items():
        assert b["peak_max_range_ue"] == pytest.approx([direct["peaks"][g]["bending_max_ue"]] * 2, abs=1e-6)
        assert b["peak_min_range_ue"] == pytest.approx([direct["peaks"][g]["bending_min_ue"]] * 2, abs=1e-6)


def test_band_with_morris_ranking_and_the_record_check_per_peak(tmp_path):
    folder, summary = run_uncertainty("crank_rocker_95rpm", samples=2, trajectories=2, workers=2,
                                      out=tmp_path / "u1", progress=False, settings=Settings(step_deg=1.0))
    assert summary["status"] == "completed", summary.get("failed_samples")
    declared_names = set(summary["parameters"])
    assert len(declared_names) == 15
    sens = summary["sensitivity"]
    assert sens["method"] == "morris" and sens["trajectories_used"] == 2
    assert {r["unknown"] for r in sens["ranking"]} == declared_names
    scores = [r["score"] for r in sens["ranking"]]
    assert scores == sorted(scores, reverse=True)
    for g in ("coupler_mid", "rocker_mid"):
        assert set(sens["mu_star_ue"][g]) == {"+", "-"}
        assert summary["most_influential"][g] in declared_names
    recs = summary["records"]
    assert {(r["gauge"], r["peak"]) for r in recs} == {(g, s) for g in ("coupler_mid", "rocker_mid") for s in "+-"}
    for r in recs:
        lo, hi = r["band_ue"]
        assert r["inside"] == (lo <= r["recorded_ue"] <= hi) and r["kind"] == "measurement"
    for f in ("band.csv", "band.png", "band.svg", "uncertainty.rrd", "summary.json"):
        assert (folder / f).exists()


def test_bad_declarations_are_refused(tmp_path):
    base = f'extends = "{SCENARIO_DIR / "crank_rocker_95rpm"}.toml"\n'
    cases = {
        'keys = ["model.flux_capacitor"]\ndistribution = "uniform"\nlow = 0\nhigh = 1': "unknown model key",
        'keys = ["model.drive_inertia"]\ndistribution = "loguniform"\nlow = "0 kg*m^2"\nhigh = "1 kg*m^2"\n'
        'unit = "kg*m^2"': "must be positive",
        'keys = ["model.drive_inertia"]\ndistribution = "triangular"': "uniform, loguniform, normal, choice",
    }
    for body, message in cases.items():
        path = tmp_path / "bad.toml"
        path.write_text(base + "[uncertainty.parameters.bad]\n" + body + "\n")
        with pytest.raises(ScenarioError, match=message):
            run_uncertainty(str(path), out=tmp_path / "never", progress=False)
    sc = load("crank_rocker_95rpm")
    with pytest.raises(ScenarioError, match="'nope' is not declared"):
        variant(sc, declared(sc.raw, str(sc.path))[2], {"nope": 1.0})
