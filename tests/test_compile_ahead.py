"""Kernels compiled ahead in a helper process (tmm_core.compiled.ahead): the helpers never outlive
the process that started them, a wait cut short ends its helper, and on an empty cache the
helpers fill the cache with the kernels handed to them."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from tmm_core.compiled import ahead

ROOT = Path(__file__).resolve().parent.parent
SLEEPER = [sys.executable, "-c", "import time; time.sleep(60)"]


def _ended(pid: int, within_s: float) -> bool:
    """Whether process ``pid`` (not a child of this one) has ended within ``within_s``."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def test_a_wait_past_its_limit_ends_the_helper_and_returns(monkeypatch):
    helper = subprocess.Popen(SLEEPER)
    monkeypatch.setattr(ahead, "WAIT_LIMIT_S", 0.3)
    monkeypatch.setitem(ahead._pending, "some_kernel", helper)
    started = time.monotonic()
    ahead.wait("some_kernel")             # the caller then compiles the kernel itself
    assert helper.poll() is not None
    assert time.monotonic() - started < 0.3 + 2.0
    assert "some_kernel" not in ahead._pending


def test_an_interrupted_wait_ends_the_helper_and_raises(monkeypatch):
    helper = subprocess.Popen(SLEEPER)
    real_wait = helper.wait

    def interrupted(timeout=None):
        if timeout == ahead.WAIT_LIMIT_S:
            raise KeyboardInterrupt
        return real_wait(timeout)
    monkeypatch.setattr(helper, "wait", interrupted)
    monkeypatch.setitem(ahead._pending, "some_kernel", helper)
    with pytest.raises(KeyboardInterrupt):
        ahead.wait("some_kernel")
    assert helper.poll() is not None


def test_a_waiting_helper_is_ended_when_its_process_exits():
    """At exit (atexit), a process ends the helpers nobody waited for."""
    script = textwrap.dedent(f"""
        import subprocess
        from tmm_core.compiled import ahead
        helper = subprocess.Popen({SLEEPER!r})
        ahead._pending["some_kernel"] = helper
        print(helper.pid, flush=True)
    """)
    out = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert _ended(int(out.stdout.split()[0]), within_s=5.0)


def test_a_helper_ends_itself_when_its_parent_is_killed():
    """A parent killed outright runs no exit handler: the helper (``python -m tmm_core.compiled``,
    here still waiting for its requests) sees its parent gone and ends."""
    script = textwrap.dedent("""
        import subprocess, sys, time
        helper = subprocess.Popen([sys.executable, "-m", "tmm_core.compiled"], stdin=subprocess.PIPE)
        print(helper.pid, flush=True)
        time.sleep(60)
    """)
    parent = subprocess.Popen([sys.executable, "-c", script], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        helper_pid = int(parent.stdout.readline())
        time.sleep(1.0)                       # the helper has imported and is reading its requests
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        assert _ended(helper_pid, within_s=10.0)
    finally:
        parent.kill()
        parent.wait()


def test_a_forked_child_does_not_own_its_parents_helpers(monkeypatch):
    helper = subprocess.Popen(SLEEPER)
    monkeypatch.setitem(ahead._pending, "some_kernel", helper)
    try:
        read, write = os.pipe()
        pid = os.fork()
        if pid == 0:                                          # the child: reports what it holds
            os.write(write, str(len(ahead._pending)).encode())
            os._exit(0)
        os.waitpid(pid, 0)
        assert os.read(read, 16) == b"0"
        assert helper.poll() is None                          # the parent's helper still runs
    finally:
        helper.kill()
        helper.wait()


@pytest.mark.slow
def test_on_an_empty_cache_the_maps_solve_is_compiled_by_a_helper_and_equals_numpy(tmp_path):
    """A compiled time-domain run on an empty cache (the first run): the load solves, the static
    solve's kernel and the march come from helpers (their cache files exist, and the process's
    own compile events do not list them), and the results equal numpy's."""
    script = textwrap.dedent("""
        import json, sys
        import numpy as np
        from numba.core import event
        compiled = []
        class Listener(event.Listener):
            def on_start(self, ev):
                compiled.append(ev.data["dispatcher"].py_func.__qualname__)
            def on_end(self, ev):
                pass
        event.register("numba:compile", Listener())
        from tmm_core import CrankMotion, TimeDomain
        from cosim.scenario import load
        sc = load("crank_rocker_373rpm")
        crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=2.0, revolutions=0.05)
        out = {}
        for backend in ("compiled", "numpy"):
            td = TimeDomain(sc.mechanism, backend=backend, gauges=sc.gauges)
            out[backend] = td.run(crank, start="quasi_static").drive_torque.tolist()
        json.dump({"compiled": compiled, "out": out}, sys.stdout)
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout)
    for kernel in ("solve_loads_many", "solve_loads", "solve_range", "march"):
        assert kernel not in result["compiled"], kernel
    assert "factor_configuration" in result["compiled"]       # the run's own share
    assert list(tmp_path.rglob("step_data.solve_loads_many-*.nbi")) and list(tmp_path.rglob("march.march-*.nbi"))
    np.testing.assert_allclose(result["out"]["compiled"], result["out"]["numpy"], rtol=1e-10, atol=1e-9)


def test_a_kernel_this_process_holds_starts_no_helper(monkeypatch):
    """Where numba cannot write its cache the cache stays empty; a kernel compiled or loaded in
    this process must not send every later march (one per periodic revolution) to a helper."""
    from cosim.scenario import load
    from tmm_core import CrankMotion, TimeDomain
    from tmm_core.compiled import binding
    sc = load("crank_rocker_373rpm")
    td = TimeDomain(sc.mechanism, backend="compiled", gauges=sc.gauges)
    crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=2.0, revolutions=0.05)
    td.run(crank, start="quasi_static")                    # the march compiled or loaded here
    started = []
    monkeypatch.setattr(ahead, "worth_it", lambda source, name: True)       # as on an empty cache
    monkeypatch.setattr(ahead, "start", lambda requests: started.append(requests))
    td.run(crank, start="quasi_static")
    assert binding.march().overloads and not started
    assert not binding.ahead_pays("march") and not binding.ahead_pays("solve_loads_many")
