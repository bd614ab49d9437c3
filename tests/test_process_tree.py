"""Issue 32, "one process tree": the workers of a sweep end with their parent, whatever ends it
(SIGTERM, SIGKILL), and a command ended by a signal exits by the shell's convention (128 + the
signal) with a summary that says ``interrupted``."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CHILDREN = Path("/proc/self/task")

pytestmark = pytest.mark.skipif(not CHILDREN.exists() or not hasattr(signal, "SIGKILL"),
                                reason="needs Linux /proc and POSIX signals")


def _children(pid: int) -> set:
    out = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            out |= {int(c) for c in (task / "children").read_text().split()}
        except OSError:
            pass
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _start_sweep(out: Path):
    """A long sweep on two workers; returns the process once both workers run."""
    proc = subprocess.Popen([sys.executable, "-m", "cosim", "sweep", "crank_rocker_373rpm", "--rpm", "100:500:2",
                             "--workers", "2", "--no-campbell", "--no-record", "--out", str(out), "--quiet"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 180
    while time.time() < deadline and len(_children(proc.pid)) < 2:
        assert proc.poll() is None, proc.stderr.read()[-2000:]
        time.sleep(0.1)
    workers = _children(proc.pid)
    assert len(workers) >= 2, "the sweep's workers did not start"
    return proc, workers


def _gone_within(pids, seconds: float) -> bool:
    deadline = time.time() + seconds
    while time.time() < deadline:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


def test_sigkill_of_a_sweep_ends_its_workers(tmp_path):
    proc, workers = _start_sweep(tmp_path / "kill")
    try:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
        assert _gone_within(workers, 10.0), [p for p in workers if _alive(p)]
    finally:
        for p in workers:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def test_sigterm_of_a_sweep_exits_143_interrupted_without_workers_left(tmp_path):
    out = tmp_path / "term"
    proc, workers = _start_sweep(out)
    try:
        tic = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
        stopped_in = time.monotonic() - tic
        assert proc.returncode == 143, (proc.returncode, proc.stderr.read()[-2000:])
        assert "Traceback" not in proc.stderr.read()
        assert stopped_in < 10, stopped_in
        assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
        assert _gone_within(workers, 5.0)
    finally:
        for p in workers | {proc.pid}:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def test_ctrl_c_of_an_identification_ends_promptly_without_workers_left(tmp_path):
    """Ctrl-C used to wait for the running least-squares starts (45 s); the workers are ended
    now and the command exits 130 within seconds, without a traceback."""
    out = tmp_path / "identify"
    proc = subprocess.Popen([sys.executable, "-m", "cosim", "identify", "crank_rocker_241rpm", "--starts", "4",
                             "--workers", "2", "--out", str(out), "--quiet"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    workers = set()
    try:
        deadline = time.time() + 240
        while time.time() < deadline and len(workers) < 2:
            assert proc.poll() is None, proc.stderr.read()[-2000:]
            workers = _children(proc.pid)
            time.sleep(0.1)
        assert len(workers) >= 2, "the identification's workers did not start"
        time.sleep(2.0)                       # the starts are running
        tic = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
        stopped_in = time.monotonic() - tic
        err = proc.stderr.read()
        assert proc.returncode == 130 and "Traceback" not in err, (proc.returncode, err[-2000:])
        assert stopped_in < 10, stopped_in
        assert _gone_within(workers, 5.0)
    finally:
        for p in workers | {proc.pid}:
            if _alive(p):
                os.kill(p, signal.SIGKILL)
