"""Issue 18 items 4, 5, 7, 10, 11: where results go, progress and logging, `python -m cosim`,
a robust `cosim compare`, the user's own records and scenarios (`--records`, `cosim new`, `extends`)."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.scenario import SCENARIO_DIR, load

ROOT = Path(__file__).resolve().parent.parent


def cosim(*args, cwd=ROOT, timeout=600):
    return subprocess.run([sys.executable, "-m", "cosim", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout)


# -- item 4: output location, item 7: python -m cosim, item 5: logging -----------------------------
def test_runs_go_to_logs_of_the_working_directory_and_say_so(tmp_path):
    res = cosim("run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.25", "--no-record",
                cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    folders = list((tmp_path / "logs").glob("crank_rocker_95rpm-*"))
    assert len(folders) == 1 and (folders[0] / "summary.json").exists()
    assert f"written to {folders[0]}" in res.stdout
    assert f"results to {folders[0]}" in res.stderr                  # said before the run, on stderr (logging)
    assert not (ROOT / "logs" / folders[0].name).exists()


def test_quiet_leaves_stderr_empty_and_the_table_on_stdout(tmp_path):
    res = cosim("-q", "run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.25", "--no-record",
                "--out", str(tmp_path / "q"))
    assert res.returncode == 0 and res.stderr == "", res.stderr
    assert "bend max" in res.stdout and f"written to {tmp_path / 'q'}" in res.stdout
    res = cosim("run", "crank_rocker_95rpm", "-q", "--engines", "tmm", "--revolutions", "0.25", "--no-record",
                "--out", str(tmp_path / "q2"))                       # -q after the subcommand works too
    assert res.returncode == 0 and res.stderr == ""


def test_python_m_cosim_is_the_cli():
    res = cosim("--version")
    assert res.returncode == 0 and res.stdout.startswith("cosim ")
    res = cosim("sweep", "--help")
    assert "--no-campbell" in res.stdout and "--records" in res.stdout and "-q, --quiet" in res.stdout
    for sub in ("run", "uncertainty"):
        assert "--records" in cosim(sub, "--help").stdout


def test_run_folders_of_the_same_second_do_not_collide(tmp_path, monkeypatch):
    from cosim.runlog import run_folder
    monkeypatch.chdir(tmp_path)
    a, b = run_folder("x"), run_folder("x")
    assert a != b and a.parent == b.parent == tmp_path / "logs"


def test_uncertainty_map_shows_a_bar_and_keeps_the_order():
    from cosim.uncertainty import parallel_map
    assert parallel_map(pow, [(2, k) for k in range(6)], workers=2, scheduler=None, desc="test") == [1, 2, 4, 8, 16, 32]


# -- item 10: cosim compare ------------------------------------------------------------------------
def write_summary(folder: Path, data) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "summary.json").write_text(data if isinstance(data, str) else json.dumps(data))
    return folder


SWEEP = {"scenario": "crank_rocker_95rpm", "status": "completed", "rpm": [90.0, 100.0], "engines": ["tmm"],
         "method": "periodic", "points": [
             {"rpm": 90.0, "engines": {"tmm": {"status": "completed", "floquet_max": 0.002, "gauges": {
                 "coupler_mid": {"bending_max_ue": 28.0, "bending_min_ue": -25.0}}}}},
             {"rpm": 100.0, "engines": {"tmm": {"status": "failed", "error": "TMMError: buckling"}}}],
         "points_without_solution": [100.0], "parametric_resonance_rpm": [],
         "resonance_candidates": [{"mode": 1, "harmonic": 47, "band_Hz": [78.9, 79.1], "rpm": [100.7, 101.0]}]}
UNCERTAINTY = {"scenario": "crank_rocker_373rpm", "status": "completed", "samples": 24, "seed": 1, "wall_time_s": 80.0,
               "parameters": {"damping": {}}, "band": {"coupler_mid": {"peak_max_range_ue": [70.0, 90.0],
                                                                       "peak_min_range_ue": [-140.0, -120.0]}},
               "most_influential": {"coupler_mid": "damping"},
               "records": [{"record": "fe_table1", "title": "FE crank-rocker thesis, TABLE I (measurement)",
                            "gauge": "coupler_mid", "peak": "+", "recorded_ue": 79.3, "inside": True}]}


def test_compare_prints_a_sweep_folders_own_table(tmp_path, capsys):
    assert main(["compare", str(write_summary(tmp_path / "sw", SWEEP))]) == 0
    out = capsys.readouterr().out
    assert "sweep of crank_rocker_95rpm" in out and "2 of 2 points" in out
    assert "28.0" in out and "TMMError: buckling" in out and "no solution at [100.0] rpm" in out
    assert "mode 1 x harmonic 47" in out


def test_compare_into_a_closed_pipe_ends_quietly(tmp_path):
    """Issue 31: `cosim compare ... | head` ended with 'Broken pipe' and exit 2. The read end is
    closed before the command starts, so its first write meets a closed pipe whatever the timing."""
    folder = write_summary(tmp_path / "sw", SWEEP)
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        res = subprocess.run([sys.executable, "-m", "cosim", "compare", str(folder)], stdout=write_end,
                             stderr=subprocess.PIPE, text=True, cwd=ROOT, timeout=600)
    finally:
        os.close(write_end)
    assert res.returncode == 141, res.stderr            # 128 + SIGPIPE, the shell's convention
    assert res.stderr == ""


def test_compare_prints_an_uncertainty_folders_own_table(tmp_path, capsys):
    assert main(["compare", str(write_summary(tmp_path / "u", UNCERTAINTY))]) == 0
    out = capsys.readouterr().out
    assert "uncertainty of crank_rocker_373rpm" in out and "+peak 70.0..90.0 ue" in out
    assert "FE crank-rocker thesis, TABLE I (measurement) coupler_mid +peak 79.3 ue: inside the band" in out


@pytest.mark.parametrize("content, words", [
    ("[1, 2, 3]", "not a bench summary (a JSON list"),
    ("garbage{", "not valid JSON"),
    ('"just a string"', "not a bench summary (a JSON str"),
    ('{"foo": 1}', "no key scenario and status"),
    (json.dumps({"scenario": "x", "status": "completed",
                 "engines": {"tmm": {"gauges": {"g": {"bending_max_ue": "abc"}}}}}),
     "cannot be shown"),
    (json.dumps({"scenario": "x", "status": "completed", "engines": [1, 2]}), "cannot be shown"),
])
def test_compare_refuses_a_bad_summary_with_one_error_line(tmp_path, capsys, content, words):
    folder = write_summary(tmp_path / "bad", content)
    assert main(["compare", str(folder)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and words in err[0], captured.err
    assert str(folder) in err[0] and captured.out == ""


def test_compare_refuses_a_bad_summary_without_a_traceback_from_the_shell(tmp_path):
    folder = write_summary(tmp_path / "bad", "[]")
    res = cosim("compare", str(folder))
    assert res.returncode == 2 and "Traceback" not in res.stderr and res.stderr.startswith("error: ")


@pytest.mark.parametrize("status, words", [("incomplete", "INCOMPLETE: still running, or killed"),
                                           ("interrupted", "INTERRUPTED")])
def test_compare_says_when_a_folder_did_not_finish(tmp_path, capsys, status, words):
    folder = write_summary(tmp_path / status, {"scenario": "crank_rocker_95rpm", "status": status, "progress": 0.4,
                                               "engines": {}})
    assert main(["compare", str(folder)]) == 0
    out = capsys.readouterr().out
    assert words in out and ("progress 40 %" in out) == (status == "incomplete")
    sweep = dict(SWEEP, status="incomplete", points=SWEEP["points"][:1])
    assert main(["compare", str(write_summary(tmp_path / "sw", sweep))]) == 0
    out = capsys.readouterr().out
    assert "1 of 2 points" in out and "INCOMPLETE" in out and "sweep.csv holds every finished point" in out


def test_compare_shows_the_motor_current_and_energy_balance(tmp_path, capsys):
    from cosim.runs import RunOptions, run_scenario
    res = run_scenario("crank_rocker_95rpm", RunOptions(engines=("mujoco",), mode="motor", revolutions=1.2,
                                                        out=tmp_path / "m", viewer="none", progress=False))
    assert res.summary["status"] == "completed"
    assert main(["compare", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    e = res.summary["engines"]["mujoco"]
    assert f"current {e['motor']['current_min_A']:.2f} .. {e['motor']['current_max_A']:.2f} A" in out
    assert f"electrical in {e['energy_J']['electrical_in_J']:.3f} = copper" in out and "residual" in out


# -- item 11: user records, cosim new, extends outside scenarios/ --------------------------------
def user_records(folder: Path, rig="fe_crank_rocker") -> Path:
    folder.mkdir(parents=True)
    (folder / "my_lab.csv").write_text("rpm,gauge,peak,quantity,value,unit\n95,coupler_mid,+,bending,30,microstrain\n"
                                       "95,coupler_mid,-,bending,28,microstrain\n")
    (folder / "my_lab.toml").write_text(f'[record]\nname = "my_lab"\nformat = "peaks"\nkind = "measurement"\n'
                                        f'rig = "{rig}"\ndescription = "our bench"\n[provenance]\n'
                                        f'source = "Our lab, run 7"\ntable = "peaks: averaged over 20 revolutions"\n')
    return folder


def test_run_scores_against_the_users_own_records(tmp_path):
    recs = user_records(tmp_path / "recs")
    res = cosim("-q", "run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.5", "--no-record",
                "--records", str(recs), "--out", str(tmp_path / "r"))
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert {s["record"] for s in summary["scores"]} == {"my_lab"}          # not the shipped Table I
    assert summary["records_dir"] == str(recs.resolve())
    assert summary["records"]["coupler_mid"][0]["title"] == "Our lab, peaks (measurement)"
    assert "my_lab" in res.stdout


def test_a_records_directory_that_is_missing_or_has_nothing_for_the_rig(tmp_path):
    res = cosim("run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.25", "--no-record",
                "--records", str(tmp_path / "nope"), "--out", str(tmp_path / "r"))
    assert res.returncode == 2 and res.stderr.startswith("error: records directory") and "nope" in res.stderr
    assert not (tmp_path / "r").exists()                                  # refused before anything ran
    other = user_records(tmp_path / "other", rig="someone_else")
    res = cosim("-q", "run", "crank_rocker_95rpm", "--engines", "tmm", "--revolutions", "0.25", "--no-record",
                "--records", str(other), "--out", str(tmp_path / "r2"))
    assert res.returncode == 0
    notes = json.loads((tmp_path / "r2" / "summary.json").read_text())["notes"]
    assert any(f"no record in {other}" in n and "nothing was scored" in n for n in notes)


def test_cosim_new_writes_a_commented_four_bar_that_loads_and_runs(tmp_path, capsys):
    assert main(["new", "my_rig", "--out", str(tmp_path)]) == 0
    path = tmp_path / "my_rig.toml"
    assert f"wrote {path}" in capsys.readouterr().out
    text = path.read_text()
    assert text.count("#") > 20 and 'type = "four-bar"' in text and 'name = "my_rig"' in text
    sc = load(path)
    assert sc.name == "my_rig" and len(sc.assumptions) >= 8 and {g.name for g in sc.gauges} == {"coupler_mid",
                                                                                              "rocker_mid"}
    from cosim.runs import RunOptions, run_scenario
    res = run_scenario(path, RunOptions(engines=("tmm", "mujoco"), revolutions=0.25, out=tmp_path / "r",
                                        viewer="none", progress=False))
    assert res.summary["status"] == "completed"
    capsys.readouterr()
    assert main(["new", "my_rig", "--out", str(tmp_path)]) == 2             # never overwrites
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "already exists" in err
    assert main(["new", "bad name!", "--out", str(tmp_path)]) == 2


def test_cosim_new_like_copies_the_scenario_and_its_base(tmp_path, capsys):
    assert main(["new", "my373", "--like", "crank_rocker_373rpm", "--out", str(tmp_path / "rigs")]) == 0
    path = tmp_path / "rigs" / "my373.toml"
    assert (tmp_path / "rigs" / "base" / "fe_crank_rocker.toml").read_text() == \
        (SCENARIO_DIR / "base" / "fe_crank_rocker.toml").read_text()
    sc, original = load(path), load("crank_rocker_373rpm")
    assert sc.name == "my373" and sc.rig == original.rig
    assert sc.drive.speed_rad_s == original.drive.speed_rad_s and "# FE crank-rocker thesis rig" in path.read_text()
    assert main(["new", "x", "--like", "no_such_rig", "--out", str(tmp_path)]) == 2
    assert "not found" in capsys.readouterr().err


def test_extends_with_a_relative_base_outside_scenarios(tmp_path, monkeypatch):
    """A copy of a speed file outside scenarios/ extends its base by a path relative to itself,
    wherever the command runs from."""
    (tmp_path / "lab" / "base").mkdir(parents=True)
    (tmp_path / "lab" / "speeds").mkdir()
    shutil.copy(SCENARIO_DIR / "base" / "fe_crank_rocker.toml", tmp_path / "lab" / "base" / "rig.toml")
    (tmp_path / "lab" / "speeds" / "mine_150rpm.toml").write_text(
        'extends = "../base/rig"\n[scenario]\nname = "mine_150rpm"\ndescription = "ours"\n'
        '[drive]\nspeed = "150 rpm"\n')
    monkeypatch.chdir(tmp_path)                              # a different cwd from the file's folder
    sc = load(tmp_path / "lab" / "speeds" / "mine_150rpm.toml")
    assert sc.name == "mine_150rpm" and sc.rig == "fe_crank_rocker"
    assert sc.drive.speed_rad_s == pytest.approx(150 * 3.141592653589793 / 30)
    sc_rel = load(Path("lab/speeds/mine_150rpm.toml"))     # a relative path to the file works as well
    assert sc_rel.drive.speed_rad_s == sc.drive.speed_rad_s
