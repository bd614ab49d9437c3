"""Issue 17: a run's memory must be flat in its length (goal: < 0.1 MB per revolution).

Measured 2026-11-26 (`/usr/bin/time -v cosim run crank_rocker_373rpm --engines tmm --revolutions N`,
recording on): 412 MB at N = 10, 524 MB at N = 100, about 1.2 MB per revolution; with --no-record
405 and 535 MB, so the growth is the run's own process, not the recording's child. What holds it
(tracemalloc/RSS probes around cosim.master._Channel.result and cosim.run._write_results): the
master keeps every macro step's EngineOutput (cosim.master._Channel.outputs: 180 per revolution,
each with its small arrays of t, angle, speed, torque, gauges, extras and the (k, nodes, 2) node
positions: about 0.7 MB per revolution with the per-array overhead), and
cosim.engines.base.concatenate copies them once more into the EngineRun at the end (+0.4 MB per
revolution at the peak). traces.parquet and the figure add a constant ~150 MB (imports, one table).
Making it flat means the master keeping only the revolutions the summary needs (the steady-state
check, scores and figure use the last two) while traces.csv keeps the rest: not done yet, so the
test is an expected failure until it is."""
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TIME = shutil.which("time") or ("/usr/bin/time" if Path("/usr/bin/time").exists() else None)


def peak_rss_mb(revolutions: int, out: Path) -> float:
    res = subprocess.run([TIME, "-v", sys.executable, "-m", "cosim", "-q", "run", "crank_rocker_373rpm", "--engines",
                          "tmm", "--revolutions", str(revolutions), "--out", str(out)], cwd=ROOT,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    return int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", res.stderr).group(1)) / 1024


@pytest.mark.slow
@pytest.mark.skipif(TIME is None, reason="needs GNU time (/usr/bin/time -v)")
@pytest.mark.xfail(reason="the master keeps every macro step's outputs (about 1.2 MB per revolution); see the "
                          "module docstring", strict=False)
def test_memory_is_flat_in_run_length(tmp_path):
    short, long = peak_rss_mb(10, tmp_path / "r10"), peak_rss_mb(100, tmp_path / "r100")
    allowance_mb = 5.0          # allocator noise and the traces' longer tables read at the end
    assert long - short < 0.1 * 90 + allowance_mb, (short, long, (long - short) / 90)
