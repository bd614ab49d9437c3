"""Speed sweeps with the periodic solver, resonance maps and uncertainty bands (issue 9)."""
import json
import math

import numpy as np
import pytest

from cosim.scenario import SCENARIO_DIR, load
from cosim.sweeps import run_sweep
from cosim.uncertainty import run_uncertainty
from tmm_core import CrankMotion, TimeDomain


def _light(tmp_path, name="crank_rocker_373rpm", extra=""):
    """The rig with 4 segments per link (a test setting: the comparisons below are between two
    solution methods of the same model, and 4 segments halve the cost)."""
    path = tmp_path / f"{name}_light.toml"
    path.write_text(f'extends = "{SCENARIO_DIR / name}.toml"\n\n[solver.tmm]\nsegments = 4\n{extra}',
                    encoding="utf-8")
    return path


SPEEDS = (120.0, 200.0, 280.0, 360.0, 400.0)


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("sweep")
    folder, summary = run_sweep(str(_light(tmp)), ",".join(map(str, SPEEDS)), ("tmm",), workers=2, out=tmp / "out",
                                progress=False)
    return folder, summary, load(_light(tmp))


def test_sweep_finishes_with_figures_and_floquet(sweep):
    folder, summary, sc = sweep
    assert summary["status"] == "completed" and len(summary["points"]) == len(SPEEDS)
    assert summary["method"] == "periodic"
    for p in summary["points"]:
        assert p["engines"]["tmm"]["status"] == "completed", p
        assert p["engines"]["tmm"]["floquet_max"] < 1.0       # damped and below ~405 rpm: stable
    for f in ("sweep_peaks.png", "sweep_peaks.svg", "campbell.png", "campbell.svg", "sweep.csv", "sweep.rrd"):
        assert (folder / f).exists(), f
    assert summary["resonance_candidates"] and summary["natural_frequencies_Hz"]["modes"]


@pytest.mark.slow
def test_eighty_one_point_sweep_reports_where_the_response_stops_being_periodic(tmp_path):
    """100-500 rpm in 5 rpm steps. Up to 400 rpm every point has a stable periodic solution. Above,
    the second-order model's periodic orbit turns unstable (|multiplier| > 1 at 410 rpm, flagged as
    parametric resonance) and then the Newton shooting finds none (exudyn too changes from
    revolution to revolution at 460 rpm); each such point says so."""
    folder, summary = run_sweep(str(_light(tmp_path)), "100:500:5", ("tmm",), workers=2, out=tmp_path / "out",
                                progress=False)
    # issue 32: points without a periodic solution make the sweep 'completed with unsolved points'
    assert summary["status"] == ("completed with unsolved points" if summary["points_without_solution"]
                                 else "completed") and len(summary["points"]) == 81
    for p in summary["points"]:
        e = p["engines"]["tmm"]
        if p["rpm"] <= 400:
            assert e["status"] == "completed" and e["floquet_max"] < 1.0, p["rpm"]
        elif e["status"] == "completed":
            assert e["parametric_resonance"] == (e["floquet_max"] > 1.0)
        else:
            assert "periodic" in e["error"], p["rpm"]


def test_sweep_peaks_match_time_marching_at_five_speeds(sweep):
    """The periodic solution at each speed against time marching to the steady state (same
    integrator and step), within 1 % of the peak."""
    folder, summary, sc = sweep
    points = {p["rpm"]: p for p in summary["points"]}
    s = sc.tmm
    step_deg = math.degrees(s.step_rad)
    for rpm in SPEEDS:
        w = rpm * math.pi / 30
        td = TimeDomain(sc.mechanism, integrator=s.integrator, beam_column=s.beam_column, gauges=sc.gauges,
                        coupling=s.coupling, axial_force=s.axial_force)
        r = td.run(CrankMotion.constant_speed(w, step_deg=step_deg, revolutions=80), start="quasi_static",
                   steady_tol=1e-6, record_displacements=False)
        assert r.steady, rpm
        N = r.info["steps_per_revolution"]
        for g, stats in points[rpm]["engines"]["tmm"]["gauges"].items():
            b = r.gauges[g][0][-N:] * 1e6
            assert stats["bending_max_ue"] == pytest.approx(b.max(), rel=0.01, abs=1e-3)
            assert stats["bending_min_ue"] == pytest.approx(b.min(), rel=0.01, abs=1e-3)


def _with_unknowns(tmp_path, name, parameters, samples):
    """The light rig with only these declared unknowns (the base file declares more)."""
    return load(_light(tmp_path, name)).with_overrides(
        {"uncertainty": {"samples": samples, "seed": 1, "parameters": parameters}})


# The three unknowns of the first band (issue 9): damping, bearing weight per end or total, modulus.
FIRST_UNKNOWNS = {
    "damping": {"keys": ["links.coupler.damping.ratio", "links.rocker.damping.ratio"], "distribution": "uniform",
                "low": "1 %", "high": "5 %", "unit": "%"},
    "bearing_weight": {"keys": ["links.coupler.point_masses[0].weight", "links.coupler.point_masses[1].weight"],
                       "distribution": "choice", "values": ["0.13128 lbf", "0.06564 lbf"]},
    "modulus": {"keys": ["materials.aluminium.E"], "distribution": "uniform", "low": "9.9e6 psi",
                "high": "10.7e6 psi", "unit": "psi"},
}


def test_uncertainty_with_zero_spread_reproduces_the_deterministic_run(tmp_path):
    zero = {"damping": dict(FIRST_UNKNOWNS["damping"], low="2 %", high="2 %"),
            "bearing_weight": dict(FIRST_UNKNOWNS["bearing_weight"], values=["0.13128 lbf"]),
            "modulus": dict(FIRST_UNKNOWNS["modulus"], low="10.3e6 psi", high="10.3e6 psi")}
    folder, summary = run_uncertainty(_with_unknowns(tmp_path, "crank_rocker_241rpm", zero, 3), workers=2,
                                      out=tmp_path / "u0", record=False, sensitivity=False)
    assert summary["status"] == "completed"
    import csv
    rows = list(csv.DictReader(open(folder / "band.csv")))
    for r in rows:
        nominal = float(r["nominal_ue"])
        assert float(r["low_ue"]) == pytest.approx(nominal, abs=1e-9)
        assert float(r["high_ue"]) == pytest.approx(nominal, abs=1e-9)


def test_uncertainty_band_contains_the_deterministic_history(tmp_path):
    """The FE rig at 241 rpm with its declared uncertain parameters (damping 1-5 %, bearing weight
    per end or total, modulus +/- 4 %): the envelope of 12 samples (the nominal run excluded)
    contains the nominal history."""
    folder, summary = run_uncertainty(_with_unknowns(tmp_path, "crank_rocker_241rpm", FIRST_UNKNOWNS, 12),
                                      samples=12, workers=2, out=tmp_path / "u1")
    assert summary["status"] == "completed"
    for g, b in summary["band"].items():
        assert b["nominal_inside_envelope"] >= 0.99, (g, b)
        assert b["peak_max_range_ue"][1] > b["peak_max_range_ue"][0]           # a real spread
    assert set(summary["most_influential"]) == {"coupler_mid", "rocker_mid"}
    assert summary["records"] and all("inside" in r for r in summary["records"])
    for f in ("band.csv", "band.png", "band.svg", "uncertainty.rrd"):
        assert (folder / f).exists()


def test_a_sweep_can_use_the_reduced_model_and_agrees_with_the_converged_full_one(tmp_path):
    """--model reduced at 300 rpm (a speed between the shipped ones) against the full model at
    0.125 deg (converged: 0.25 deg moves no peak by more than 0.6 % from it): within 1 %. The
    full model at the scenario's 0.5 deg is 2.8 % low on the rocker's + peak there, so the
    reference is the converged one. Time marching with the reduced model is refused."""
    fine = tmp_path / "fine.toml"
    fine.write_text(f'extends = "{SCENARIO_DIR / "crank_rocker_241rpm"}.toml"\n\n[solver.tmm]\nstep = "0.125 deg"\n',
                    encoding="utf-8")
    runs = {m: run_sweep(str(fine if m == "full" else SCENARIO_DIR / "crank_rocker_241rpm.toml"), "300", ("tmm",),
                         workers=1, out=tmp_path / m, progress=False, record=False, resonance=False, model=m)[1]
            for m in ("full", "reduced")}
    assert runs["reduced"]["model"] == "reduced" and runs["full"]["model"] == "full"
    f, r = runs["full"]["points"][0]["engines"]["tmm"], runs["reduced"]["points"][0]["engines"]["tmm"]
    assert f["status"] == r["status"] == "completed"
    for g in f["gauges"]:
        for peak in ("bending_max_ue", "bending_min_ue"):
            assert r["gauges"][g][peak] == pytest.approx(f["gauges"][g][peak], rel=0.01), (g, peak)
    with pytest.raises(ValueError, match="reduced TMM model solves the periodic steady state only"):
        run_sweep("crank_rocker_241rpm", "300", ("tmm",), method="march", model="reduced", out=tmp_path / "m",
                  progress=False, record=False, resonance=False)


def test_sweep_points_share_one_reduced_basis_and_get_the_same_answer():
    """The reduced basis depends on the geometry, not the speed: a sweep worker builds it once
    (cosim.sweeps keeps it by scenario without its speed). The point solved on the shared basis
    equals the one that builds its own, bit for bit; a changed mesh builds a new basis."""
    from cosim import sweeps as sweep_module
    from tmm_core.reduced import ReducedOptions
    from tmm_core.reduced_periodic import periodic_steady_state_reduced
    sweep_module._REDUCED.clear()
    base = load("crank_rocker_241rpm").with_overrides({"solver.tmm.model": "reduced"})
    at = {rpm: base.with_overrides({"drive.speed": f"{rpm} rpm"}) for rpm in (200, 300)}
    sweep_module.periodic_solution(at[200])
    shared = sweep_module.periodic_solution(at[300])
    assert len(sweep_module._REDUCED) == 1
    sc = at[300]
    own = periodic_steady_state_reduced(sc.time_domain(), sc.drive.speed_rad_s, start_angle=sc.drive.start_angle_rad,
                                        options=ReducedOptions(modes=sc.tmm.modes))
    for g, (b, a) in own.gauges.items():
        np.testing.assert_array_equal(shared.gauges[g][0], b)
        np.testing.assert_array_equal(shared.gauges[g][1], a)
    # A worker with many speeds also keeps the speed-free stage matrices: equal to round-off.
    many = sweep_module.periodic_solution(sc, many=True)
    for g, (b, a) in own.gauges.items():
        assert np.max(np.abs(many.gauges[g][0] - b)) <= 1e-9 * np.max(np.abs(b)), g
    sweep_module.periodic_solution(sc.with_overrides({"solver.tmm.segments": 4}))
    assert len(sweep_module._REDUCED) == 2


def test_an_interrupted_sweep_writes_the_points_it_finished(tmp_path, monkeypatch):
    """The sweep's files are rewritten at most every SAVE_EVERY_S while points finish; a sweep
    stopped by Ctrl-C between two saves still writes every finished point (here the save
    interval is longer than the sweep, so only the final save can write them)."""
    import contextlib
    from concurrent.futures import Future
    from cosim import sweeps as sweep_module

    def fake_point(raw, path, rpm, *args):
        return {"rpm": rpm, "engines": {"tmm": {"status": "completed", "error": None,
                                                "gauges": {"g": {"bending_max_ue": rpm, "bending_min_ue": -rpm}}}},
                "wall_time_s": 0.0}

    class Immediate:
        def submit(self, fn, *args):
            fut = Future()
            fut.set_result(fake_point(*args))
            return fut

    def two_then_ctrl_c(futures):
        yield from list(futures)[:2]
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_module, "executor", lambda *a: contextlib.nullcontext(Immediate()))
    monkeypatch.setattr(sweep_module, "as_completed", two_then_ctrl_c)
    monkeypatch.setattr(sweep_module, "SAVE_EVERY_S", 1e9)
    # Every point through the stand-in executor: no first point solved in this process for a
    # continued sweep (cosim.sweeps.warm_up).
    monkeypatch.setattr(sweep_module, "CONTINUED_MODELS", ())
    folder, summary = run_sweep(str(_light(tmp_path)), "100,150,200", ("tmm",), out=tmp_path / "out",
                                progress=False, record=False, resonance=False)
    written = json.loads((folder / "summary.json").read_text())
    assert written["status"] == "interrupted"
    assert [p["rpm"] for p in written["points"]] == [100.0, 150.0]
    assert (folder / "sweep.csv").read_text().count("\n") == 3         # header and two rows


def test_a_marched_sweep_reports_points_that_do_not_settle(tmp_path):
    """Marched points carry whether their last two revolutions agree (output.steady_tolerance):
    at 450 rpm, near the FE rig's buckling speed, the response stays irregular (40 revolutions,
    the last two differing by ~100 % of their peak-to-peak; the periodic solver finds no periodic
    state there either), so its peaks are a transient's and the sweep says so; 200 rpm settles."""
    from cosim.report import sweep_table
    folder, summary = run_sweep(str(_light(tmp_path)), "200,450", ("tmm",), workers=2, out=tmp_path / "out",
                                progress=False, record=False, resonance=False, method="march")
    steady = {p["rpm"]: p["engines"]["tmm"]["steady"] for p in summary["points"]}
    assert steady == {200.0: True, 450.0: False}
    assert summary["points_not_steady"] == [450.0]
    assert summary["points"][1]["engines"]["tmm"]["revolution_change"] > 0.1
    assert "not steady at [450.0] rpm" in sweep_table(summary)
    assert "steady" in (folder / "sweep.csv").read_text().splitlines()[0].split(",")


def _fake_sweep(monkeypatch, unsolved_from: float, did_not_run=()):
    """run_sweep's executor replaced by one that answers at once: below ``unsolved_from`` [rpm] a
    solved periodic point, from it on the periodic solver's failure, at ``did_not_run`` a worker's
    exception."""
    import contextlib
    from concurrent.futures import Future
    from cosim import sweeps as sweep_module

    def fake_point(raw, path, rpm, *args):
        if rpm in did_not_run:
            raise RuntimeError("worker died")
        if rpm >= unsolved_from:
            return {"rpm": rpm, "engines": {"tmm": {"status": "failed", "error": "ConvergenceError: periodic solver: "
                                                    f"Newton shooting did not converge in 30 iterations ({rpm})"}}}
        return {"rpm": rpm, "engines": {"tmm": {"status": "completed", "error": None, "floquet_max": 0.9,
                                                "gauges": {"rocker_mid": {"bending_max_ue": rpm, "bending_min_ue": -rpm,
                                                                          "axial_max_ue": 1.0, "axial_min_ue": -1.0}}}}}

    class Immediate:
        def submit(self, fn, *args):
            fut = Future()
            try:
                fut.set_result(fake_point(*args))
            except Exception as exc:
                fut.set_exception(exc)
            return fut

    monkeypatch.setattr(sweep_module, "executor", lambda *a: contextlib.nullcontext(Immediate()))


def test_a_sweep_with_unsolved_points_does_not_read_as_a_plain_success(tmp_path, monkeypatch, capsys):
    """Issue 32: a 1000-point sweep said 'completed' with 584 points unsolved. Every point ran but
    three have no periodic solution: the status says so with the count, the table and the
    console line give the count and the reason once, and a solver failing past the last solved
    speed is named a finding, not a lost point; the exit status stays 0 (the sweep is whole)."""
    from cosim import cli
    from cosim.report import sweep_table
    _fake_sweep(monkeypatch, unsolved_from=440.0)
    scenario = str(_light(tmp_path))
    status = cli.main(["sweep", scenario, "--rpm", "400:460:10", "--no-campbell", "--no-record", "-q",
                       "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert status == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "completed with unsolved points"
    u = summary["unsolved_points"]
    assert (u["count"], u["of"], u["rpm"]) == (3, 7, [440.0, 450.0, 460.0])
    assert len(u["reasons"]) == 1 and u["reasons"][0]["count"] == 3       # alike but for their numbers
    assert "finding" in u["note"] and "430 rpm" in u["note"]
    assert "sweep completed with unsolved points: 7 points; 3 of 7 points without a solution" in out
    table = sweep_table(summary)
    assert "COMPLETED WITH UNSOLVED POINTS: 3 of 7" in table and "3 x ConvergenceError" in table


def test_a_sweep_whose_points_all_solve_is_completed_and_one_with_a_point_not_run_failed(tmp_path, monkeypatch):
    """'completed' only when every point solved; a point that did not run at all (a worker that
    died) fails the sweep (exit 1), distinct from points without a solution."""
    from cosim import cli
    _fake_sweep(monkeypatch, unsolved_from=math.inf)
    folder, summary = run_sweep(str(_light(tmp_path)), "400,410", ("tmm",), out=tmp_path / "a", progress=False,
                                record=False, resonance=False)
    assert summary["status"] == "completed" and summary["unsolved_points"] is None
    _fake_sweep(monkeypatch, unsolved_from=410.0, did_not_run=(420.0,))
    status = cli.main(["sweep", str(_light(tmp_path)), "--rpm", "400,410,420", "--no-campbell", "--no-record", "-q",
                       "--out", str(tmp_path / "b")])
    summary = json.loads((tmp_path / "b" / "summary.json").read_text())
    assert status == 1 and summary["status"] == "failed"
    assert summary["unsolved_points"]["rpm"] == [410.0]


def test_the_fe_rig_past_buckling_is_a_sweep_with_unsolved_points(tmp_path):
    """The FE rig's periodic sweep 400:500:10 rpm (measured: 8 of 11 unsolved, from 430 rpm up;
    at 420 rpm the rocker's compression is ~3.7 times its Euler load): here 420 and 440 rpm. 440
    has no periodic solution; the sweep says so and names it a finding."""
    folder, summary = run_sweep("crank_rocker_373rpm", "420,440", ("tmm",), workers=2, out=tmp_path / "out",
                                progress=False, record=False, resonance=False)
    assert summary["status"] == "completed with unsolved points"
    u = summary["unsolved_points"]
    assert (u["count"], u["of"], u["rpm"]) == (1, 2, [440.0])
    assert "periodic" in u["reasons"][0]["error"]
    assert "finding" in u["note"] and "buckling load" in u["note"]


def test_a_sweep_lists_its_unstable_orbits_by_kind_apart_from_unsolved_points():
    from cosim.report import unstable_orbit_lines
    from cosim.sweeps import unstable_orbits

    def point(rpm, orbit, mu):
        return {"rpm": rpm, "engines": {"tmm": {"status": "completed", "orbit": orbit, "floquet_max": mu}}}
    points = [point(400.0, "stable", 0.9), point(410.0, "period doubling", 1.25), point(415.0, "saddle", 1.07),
              {"rpm": 420.0, "engines": {"tmm": {"status": "failed", "error": "no orbit"}}}]
    orbits = unstable_orbits(points)
    assert [(o["rpm"], o["kind"]) for o in orbits] == [(410.0, "period doubling"), (415.0, "saddle")]
    lines = unstable_orbit_lines(orbits)
    assert lines[0].startswith("unstable orbit, period doubling: 410 rpm (|mu| = 1.25); a real multiplier below -1")
    assert lines[1].startswith("unstable orbit, saddle: 415 rpm (|mu| = 1.07)")
