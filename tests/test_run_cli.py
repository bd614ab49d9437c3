"""End-to-end (issue 6): `cosim list/run/sweep/compare`, the run folder, interrupted runs,
one-line errors, the scenario scripts."""
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cosim.report import comparison_table, load_summary
from cosim.scenario import load, scenario_names
from cosim.traces import read_traces

ROOT = Path(__file__).resolve().parent.parent
COSIM = [sys.executable, "-m", "cosim.cli"]
ALL_SCENARIOS = ("crank_rocker_95rpm", "crank_rocker_241rpm", "crank_rocker_373rpm", "alexander_lawrence_400rpm",
                 "bahgat_willmert_125rads", "wang_steel_342rpm", "wang_composite_205rpm", "wang_composite_255rpm",
                 "wang_composite_280rpm", "wang_composite_297rpm")


def cosim(*args, timeout=600):
    return subprocess.run(COSIM + list(args), capture_output=True, text=True, cwd=ROOT, timeout=timeout)


def test_list_shows_every_scenario_with_its_description():
    out = cosim("list")
    assert out.returncode == 0, out.stderr
    lines = {line.split()[0]: line for line in out.stdout.splitlines() if line.strip()}
    for name in ALL_SCENARIOS:
        assert name in lines
        assert len(lines[name].split(None, 1)[1]) > 20           # a real description
    assert set(ALL_SCENARIOS) <= set(scenario_names())


@pytest.mark.parametrize("name", ALL_SCENARIOS)
def test_every_scenario_loads_with_sources_and_assumptions(name):
    s = load(name)
    assert s.sources and s.description and s.gauges
    assert all(a.rationale for a in s.assumptions)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "crank_rocker_373rpm"
    res = cosim("run", "crank_rocker_373rpm", "--revolutions", "2", "--out", str(out), "--quiet")
    assert res.returncode == 0, res.stderr[-3000:]
    return out, res


def test_run_writes_the_four_log_files_with_finite_summary(run_dir):
    out, res = run_dir
    for f in ("traces.csv", "scenario.resolved.toml", "run.rrd", "summary.json"):
        assert (out / f).exists() and (out / f).stat().st_size > 0, f
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"] == "crank_rocker_373rpm" and summary["status"] == "completed"
    for engine in ("tmm", "exudyn", "mujoco"):
        e = summary["engines"][engine]
        assert e["status"] == "completed"
        assert math.isfinite(e["wall_time_s"]) and e["wall_time_s"] > 0
        assert e["sim_time_s"] == pytest.approx(2 * load("crank_rocker_373rpm").revolution_period_s, rel=0.01)
        for gauge in ("coupler_mid", "rocker_mid"):
            g = e["gauges"][gauge]
            for k in ("bending_max_ue", "bending_min_ue", "axial_max_ue", "axial_min_ue"):
                assert math.isfinite(g[k]), (engine, gauge, k)
            assert g["bending_max_ue"] > g["bending_min_ue"]
    assert "written to" in res.stdout and "coupler_mid" in res.stdout


def test_traces_have_time_units_and_every_engine(run_dir):
    out, _ = run_dir
    cols, data, note = read_traces(out / "traces.csv")
    assert note is None and cols[0] == "time_s"
    assert np.all(np.diff(data[:, 0]) > 0)
    for engine in ("tmm", "exudyn", "mujoco"):
        for col in (f"{engine}.crank_angle_rad", f"{engine}.drive_torque_Nm", f"{engine}.coupler_mid.bending_ue",
                    f"{engine}.rocker_mid.axial_ue"):
            assert col in cols
            assert np.isfinite(data[:, cols.index(col)]).sum() > 10
    resolved = (out / "scenario.resolved.toml").read_text()
    assert "[resolved" in resolved and "rationale" in resolved and "E_Pa" in resolved


def test_compare_prints_the_table(run_dir):
    out, _ = run_dir
    res = cosim("compare", str(out))
    assert res.returncode == 0
    assert "coupler_mid" in res.stdout and "exudyn" in res.stdout and "bend max" in res.stdout
    assert comparison_table(load_summary(out)) == res.stdout.rstrip("\n")


def test_a_killed_run_leaves_readable_traces_and_an_incomplete_summary(tmp_path):
    out = tmp_path / "killed"
    proc = subprocess.Popen(COSIM + ["run", "crank_rocker_373rpm", "--engines", "tmm,mujoco", "--revolutions", "40",
                                     "--out", str(out), "--quiet"], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 300
        while time.time() < deadline:
            assert proc.poll() is None, "the run ended before it could be killed"
            summary = out / "summary.json"
            if (out / "traces.csv").exists() and (out / "traces.csv").stat().st_size > 200_000 and summary.exists() \
                    and json.loads(summary.read_text()).get("progress", 0) > 0:
                break
            time.sleep(0.5)
        else:
            pytest.fail("the run did not get going")
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    cols, data, _ = read_traces(out / "traces.csv")
    assert len(data) > 100 and "tmm.coupler_mid.bending_ue" in cols
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "incomplete" and 0 < summary["progress"] < 1


def test_sigterm_writes_an_interrupted_summary(tmp_path):
    out = tmp_path / "term"
    proc = subprocess.Popen(COSIM + ["run", "crank_rocker_373rpm", "--engines", "tmm", "--revolutions", "60",
                                     "--out", str(out), "--quiet", "--no-record"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 300
    while time.time() < deadline and not ((out / "traces.csv").exists() and (out / "traces.csv").stat().st_size > 50_000):
        assert proc.poll() is None, proc.stderr.read()[-2000:]
        time.sleep(0.3)
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=120)
    assert proc.returncode == 143             # 128 + SIGTERM (issue 32; was 130, the SIGINT status)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted" and summary["engines"]["tmm"]["sim_time_s"] > 0
    read_traces(out / "traces.csv")


@pytest.mark.parametrize("args, words", [
    (("run", "no_such_rig"), "not found"),
    (("run", "crank_rocker_373rpm", "--engines", "tmm,ansys"), "unknown engine 'ansys'"),
    (("sweep", "crank_rocker_373rpm", "--rpm", "400:100:25"), "malformed rpm range"),
    (("sweep", "crank_rocker_373rpm", "--rpm", "100:x:25"), "malformed rpm range"),
    (("run", "alexander_lawrence_400rpm", "--drive", "motor"), "no [motor] table"),
    (("compare", "/nonexistent/run"), "no summary.json"),
])
def test_bad_input_exits_nonzero_with_one_line(args, words):
    res = cosim(*args)
    assert res.returncode != 0
    err = res.stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and words in err[0], res.stderr
    assert "Traceback" not in res.stderr


def test_help_is_complete():
    for sub in ("run", "sweep", "compare", "list"):
        res = cosim(sub, "--help")
        assert res.returncode == 0
    text = cosim("run", "--help").stdout
    for opt in ("--engines", "--drive", "--revolutions", "--out", "--save", "--spawn", "--connect"):
        assert opt in text
    assert "--scheduler" in cosim("sweep", "--help").stdout


def test_scenario_runs_as_a_plain_script(tmp_path):
    res = subprocess.run([sys.executable, "scenarios/crank_rocker_95rpm.py", "--engines", "tmm", "--revolutions",
                          "0.25", "--no-record", "--quiet", "--out", str(tmp_path / "s")], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert json.loads((tmp_path / "s" / "summary.json").read_text())["scenario"] == "crank_rocker_95rpm"


@pytest.mark.parametrize("name", [n for n in ALL_SCENARIOS if n != "crank_rocker_373rpm"])
def test_every_scenario_runs_a_short_prescribed_tmm_run(name, tmp_path):
    from cosim.runs import RunOptions, run_scenario
    res = run_scenario(name, RunOptions(engines=("tmm",), revolutions=0.2, out=tmp_path / name, viewer="none",
                                        progress=False))
    assert res.summary["status"] == "completed", res.summary


def test_sweep_runs_points_in_parallel_and_records_peaks(tmp_path):
    res = cosim("sweep", "crank_rocker_95rpm", "--rpm", "90:100:10", "--engines", "tmm", "--revolutions", "1",
                "--workers", "2", "--out", str(tmp_path / "sw"), "--quiet")
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads((tmp_path / "sw" / "summary.json").read_text())
    assert summary["status"] == "completed" and sorted(p["rpm"] for p in summary["points"]) == [90.0, 100.0]
    lines = (tmp_path / "sw" / "sweep.csv").read_text().splitlines()
    assert lines[0].startswith("rpm,engine,gauge") and len(lines) == 1 + 2 * 2


def test_sweep_on_a_local_dask_cluster(tmp_path):
    from distributed import LocalCluster

    from cosim.sweeps import run_sweep
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        folder, summary = run_sweep("crank_rocker_95rpm", "90,100", ("tmm",), revolutions=0.5,
                                    scheduler=cluster.scheduler_address, out=tmp_path / "dask", progress=False)
    assert summary["status"] == "completed" and summary["executor"].startswith("dask")
    local = [p for p in summary["points"] if p["rpm"] == 90.0][0]["engines"]["tmm"]["gauges"]["coupler_mid"]
    from cosim.sweeps import sweep_point
    direct = sweep_point(load("crank_rocker_95rpm").raw, "crank_rocker_95rpm", 90.0, ("tmm",), 0.5)
    assert local["bending_max_ue"] == pytest.approx(direct["engines"]["tmm"]["gauges"]["coupler_mid"]["bending_max_ue"],
                                                    rel=1e-12)


def test_recording_holds_every_engine_motor_and_strain_series(run_dir):
    """Read the run's .rrd back with rerun's own reader (cosim.recording.read_back uses
    rerun.chunk.RrdReader)."""
    from cosim.recording import read_back, read_blueprint
    out, _ = run_dir
    counts = read_back(out / "run.rrd")
    roots = {e.strip("/").split("/")[0] for e in counts}
    assert {"tmm", "exudyn", "mujoco", "records", "scenario"} <= roots, roots
    assert "motor" not in roots                 # a prescribed run has no motor (its drive power is /<e>/drive_power)
    assert counts.get("/records/strain/rocker_mid/fe_table1", 0) > 0
    for engine in ("tmm", "exudyn", "mujoco"):
        for gauge in ("coupler_mid", "rocker_mid"):
            assert counts.get(f"/{engine}/strain/{gauge}", 0) > 10, (engine, gauge)
        assert counts.get(f"/{engine}/linkage/deformed", 0) > 0
    views = read_blueprint(out / "run.rrd")
    gauge_view = [v for v in views if "coupler_mid" in (v.get("name") or "")]
    assert gauge_view and all(f"/{e}/strain/coupler_mid" in gauge_view[0]["contents"] for e in ("tmm", "exudyn", "mujoco"))


def _last_revolution_extremes(csv_path, engine, gauge):
    import csv
    with open(csv_path) as fh:
        rows = [r for r in csv.DictReader(fh) if r[f"{engine}.{gauge}.bending_ue"]]
    angle = np.array([float(r[f"{engine}.crank_angle_rad"]) for r in rows])
    b = np.array([float(r[f"{engine}.{gauge}.bending_ue"]) for r in rows])
    last = abs(angle - angle[-1]) < 2 * math.pi * (1 - 1e-12)
    return b[last].max(), b[last].min()


def test_run_scores_every_engine_against_table_one(run_dir):
    """`cosim run crank_rocker_373rpm` compares with the FE thesis's Table I at 373 rpm (and its
    published analysis, Table II) and writes the table."""
    out, res = run_dir
    summary = json.loads((out / "summary.json").read_text())
    scores = {(s["engine"], s["gauge"], s["record"]): s for s in summary["scores"]}
    for engine in ("tmm", "exudyn", "mujoco"):
        for gauge in ("coupler_mid", "rocker_mid"):
            s = scores[(engine, gauge, "fe_table1")]
            assert s["record_max_ue"] == {"coupler_mid": 79.343, "rocker_mid": 509.222}[gauge]
            assert s["record_min_ue"] == {"coupler_mid": -135.372, "rocker_mid": -191.322}[gauge]
            # The error of the peaks read back from traces.csv (the engine's last revolution by
            # crank angle), not from the summary the scores were made from.
            hi, lo = _last_revolution_extremes(out / "traces.csv", engine, gauge)
            assert s["plus_peak_error"] == pytest.approx(hi / s["record_max_ue"] - 1, rel=1e-6)
            assert s["minus_peak_error"] == pytest.approx(lo / s["record_min_ue"] - 1, rel=1e-6)
            assert math.isfinite(scores[(engine, gauge, "fe_table2_373rpm")]["phase_lag_deg"])
    assert any("face is not stated" in w for w in summary["record_warnings"])
    assert "scores against records" in res.stdout and "fe_table1" in res.stdout


def test_console_names_each_engines_model_and_points_to_the_measurement_gap():
    """Each engine's line says what it models; large errors against a record point to the docs'
    measurement-gap section, and a rigid engine among the scored is named as the rigid model."""
    score = {"gauge": "coupler", "record": "fe_table1", "plus_peak_error": 2.36, "minus_peak_error": 0.1}
    summary = {"scenario": "x", "status": "completed", "engines": {
        "tmm": {"status": "completed"}, "mujoco": {"status": "completed"}},
        "scores": [dict(score, engine="tmm"), dict(score, engine="mujoco", plus_peak_error=0.2)]}
    text = comparison_table(summary)
    tmm_line = next(line for line in text.splitlines() if line.startswith("tmm ") and "completed" in line)
    assert "flexible: transfer-matrix" in tmm_line
    assert "rigid bodies" in next(line for line in text.splitlines() if line.startswith("mujoco ") and
                                  "completed" in line)
    assert "How far the bench is from the measurement" in text and "mujoco: the rigid model" in text
    summary["scores"] = [dict(score, engine="tmm", plus_peak_error=0.05)]
    assert "How far the bench" not in comparison_table(summary)
