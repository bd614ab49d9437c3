"""Issue 17: a run's memory must be flat in its length (goal: < 0.1 MB per revolution).

Measured 2026-11-26 (`/usr/bin/time -v cosim run crank_rocker_373rpm --engines tmm --revolutions N`,
recording on), before: 412 MB at N = 10, 524 MB at N = 100, about 1.2 MB per revolution (the master
kept every macro step's EngineOutput and copied them into the EngineRun; traces.parquet was built
from the whole CSV at once; the figure read every trace). After (the master holds the last four
revolutions, cosim.runs.KEEP_REVOLUTIONS; the parquet file is written in row groups of 2000 CSV
rows; the figure reads the last revolutions only): 387-391 MB at N = 10, 393-405 MB at N = 100,
396-397 MB at N = 200, i.e. flat within the +/- 8 MB run-to-run noise of peak RSS."""
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
def test_memory_is_flat_in_run_length(tmp_path):
    short, long = peak_rss_mb(10, tmp_path / "r10"), peak_rss_mb(200, tmp_path / "r200")
    allowance_mb = 10.0         # peak-RSS noise between runs (measured +/- 8 MB)
    assert long - short < 0.1 * 190 + allowance_mb, (short, long, (long - short) / 190)
