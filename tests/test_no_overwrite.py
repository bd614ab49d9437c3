"""Issue 32, "nothing overwritten that the bench did not create": a symlink planted in a run
folder is replaced, never written through; `cosim new`, `synthesize --scenario-out` and `--save`
refuse an existing file (a dangling symlink included) unless told to overwrite; an empty --out is
refused."""
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.files import create_new, open_new, write_atomic

ROOT = Path(__file__).resolve().parent.parent
RUN_FILES = ("traces.csv", "scenario.resolved.toml", "summary.json.tmp", "traces.parquet", "traces.parquet.tmp",
             "strains.png", "strains.svg", "run.rrd")


def _plant(folder: Path, names, victims: Path) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    victims.mkdir(parents=True, exist_ok=True)
    planted = {}
    for name in names:
        target = victims / f"victim-{name}"
        target.write_text("precious\n", encoding="utf-8")
        (folder / name).symlink_to(target)
        planted[name] = target
    return planted


def test_the_writers_replace_a_link_and_keep_its_target(tmp_path):
    planted = _plant(tmp_path / "run", ["a.json", "b.csv", "c.txt"], tmp_path / "outside")
    write_atomic(tmp_path / "run" / "a.json", "{}")
    with open_new(tmp_path / "run" / "b.csv") as fh:
        fh.write("x\n")
    with pytest.raises(FileExistsError):
        create_new(tmp_path / "run" / "c.txt", "x")
    assert all(t.read_text() == "precious\n" for t in planted.values())
    assert not (tmp_path / "run" / "a.json").is_symlink() and (tmp_path / "run" / "a.json").read_text() == "{}"
    dangling = tmp_path / "run" / "d.txt"
    dangling.symlink_to(tmp_path / "outside" / "created-through-the-link")
    with pytest.raises(FileExistsError):
        create_new(dangling, "x")
    assert not (tmp_path / "outside" / "created-through-the-link").exists()


def test_a_run_into_a_folder_with_planted_links_touches_no_target(tmp_path):
    out = tmp_path / "run"
    planted = _plant(out, RUN_FILES, tmp_path / "outside")
    res = subprocess.run([sys.executable, "-m", "cosim", "run", "crank_rocker_373rpm", "--engines", "tmm",
                          "--revolutions", "0.5", "--out", str(out), "--quiet"], cwd=ROOT, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode in (0, 1), res.stderr[-2000:]
    assert {n: t.read_text() for n, t in planted.items()} == {n: "precious\n" for n in planted}
    for name in ("traces.csv", "scenario.resolved.toml", "summary.json", "traces.parquet", "run.rrd"):
        assert (out / name).is_file() and not (out / name).is_symlink(), name


def test_cosim_new_refuses_a_dangling_symlink(tmp_path, capsys):
    (tmp_path / "my_rig.toml").symlink_to(tmp_path / "elsewhere.toml")
    assert main(["new", "my_rig", "--out", str(tmp_path)]) == 2
    assert not (tmp_path / "elsewhere.toml").exists()
    assert "symlink" in capsys.readouterr().err


SYNTH = ["synthesize", "--case", "II", "--ground", "11 in", "--oscillation", "81.07 deg",
         "--crank-limits", "44.6649 deg", "102.2467 deg"]


def test_synthesize_refuses_an_existing_scenario_out_unless_told(tmp_path, capsys):
    target = tmp_path / "mine.toml"
    target.write_text("# mine\n", encoding="utf-8")
    assert main(SYNTH + ["--scenario-out", str(target)]) == 2
    assert target.read_text() == "# mine\n"
    assert "--overwrite" in capsys.readouterr().err
    assert main(SYNTH + ["--scenario-out", str(target), "--overwrite"]) == 0
    assert "synthesize" in target.read_text()


@pytest.mark.parametrize("save, words", [("{out}/traces.csv", ".rrd"), ("{tmp}/exists.rrd", "--overwrite")])
def test_save_refuses_a_run_file_or_an_existing_recording(tmp_path, capsys, save, words):
    (tmp_path / "exists.rrd").write_bytes(b"keep")
    out = tmp_path / "run"
    argv = ["run", "crank_rocker_373rpm", "--engines", "tmm", "--revolutions", "0.1", "--out", str(out),
            "--save", save.format(out=out, tmp=tmp_path)]
    assert main(argv) == 2
    assert words in capsys.readouterr().err
    assert (tmp_path / "exists.rrd").read_bytes() == b"keep" and not (out / "traces.csv").exists()


def test_an_empty_out_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["run", "crank_rocker_373rpm", "--engines", "tmm", "--out", ""])
    assert exit_.value.code == 2 and "empty --out" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(not hasattr(__import__("resource"), "RLIMIT_FSIZE"), reason="needs RLIMIT_FSIZE")
def test_a_file_size_limit_fails_the_run_with_whole_rows_kept(tmp_path):
    """Under a file-size limit (as on a full disk) traces.csv used to end mid-row and the summary
    stayed 'incomplete' behind a bare OSError; now the run fails with a message naming the file,
    and the file ends on a whole row."""
    import json
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, 200_000))
    out = tmp_path / "run"
    res = subprocess.run([sys.executable, "-m", "cosim", "run", "crank_rocker_373rpm", "--engines", "tmm",
                          "--revolutions", "8", "--no-record", "--out", str(out)], cwd=ROOT, capture_output=True,
                         text=True, timeout=600, preexec_fn=limit)
    assert res.returncode == 1, res.stderr[-2000:]
    assert "Traceback" not in res.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "failed" and "traces.csv" in summary["error"], summary.get("error")
    text = (out / "traces.csv").read_text()
    assert text.endswith("\n")
    width = len(text.splitlines()[0].split(","))
    assert all(len(line.split(",")) == width for line in text.splitlines())
