"""End-to-end: the static example script and the cosim command line."""
import json
import subprocess
import sys
from pathlib import Path

from scenarios import static_fourbar

ROOT = Path(__file__).resolve().parent.parent


def test_static_example_writes_results(tmp_path, capsys):
    assert static_fourbar.main(["--crank-angle", "45", "--segments", "4", "--out", str(tmp_path)]) == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["scenario"] == "static_fourbar" and summary["mode"] == "beam_column"
    assert abs(summary["equilibrium_residual"]["Fx_N"]) < 1e-9
    lines = (tmp_path / "nodes.csv").read_text().splitlines()
    assert len(lines) == 1 + 3 * 5 and lines[0].startswith("link,node,x_m")
    assert "drive torque at crank pivot A" in capsys.readouterr().out


def test_static_example_bad_input_gives_one_line_error(tmp_path, capsys):
    assert static_fourbar.main(["--segments", "0", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: member 'crank': n_segments")


def test_cosim_version_and_list():
    out = subprocess.run([sys.executable, "-m", "cosim.cli", "--version"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.startswith("cosim ")
    out = subprocess.run([sys.executable, "-m", "cosim.cli", "list"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and "static_fourbar" in out.stdout
