"""Issue 32: Ctrl-C at any moment of a command's start-up ends it quietly with exit status 130
(128 + SIGINT): no traceback, and no Ctrl-C lost."""
import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim import cli, engines, runs
from cosim.interrupts import LostInterrupts, caused_by_interrupt

ROOT = Path(__file__).resolve().parent.parent
#: The console script's own code (``cosim`` in the venv's bin): it imports cosim.cli before
#: ``main`` runs, so a Ctrl-C during that import is outside main's reach.
ENTRY = "import sys; from cosim.cli import main; sys.exit(main())"


def _sigint_default():
    # A test run in the background inherits SIGINT ignored, and Python keeps ignoring it.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX signals")
@pytest.mark.parametrize("delay_s", [0.5, 1.0, 2.0, 3.5])
def test_ctrl_c_during_start_up_ends_quietly_with_130(tmp_path, delay_s):
    """SIGINT at a moment of `cosim run`'s start-up (importing the CLI, the engines' libraries,
    the engines' set-up, the first steps, depending on the machine's speed): exit 130 without
    a traceback, or 0 if the run had already finished; never a run that goes on regardless.
    (Was: a traceback through cosim.cli's import of tmm_core, 3 s of imports; and a Ctrl-C while
    mujoco's extension initialised came back as ImportError, the engine was dropped as
    'unavailable' and the run finished with 0.)"""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    proc = subprocess.Popen([sys.executable, "-c", ENTRY, "run", "crank_rocker_373rpm", "--revolutions", "1",
                             "--out", str(tmp_path / "out"), "--quiet"], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, preexec_fn=_sigint_default)
    time.sleep(delay_s)
    finished = proc.poll() is not None
    proc.send_signal(signal.SIGINT)
    sent = time.monotonic()
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise AssertionError("the run did not end within 120 s of Ctrl-C")
    waited = time.monotonic() - sent
    assert "Traceback" not in err, err[-3000:]
    assert proc.returncode == (0 if finished else 130), (proc.returncode, err[-2000:])
    # The goal is 2 s; a loaded 2-core machine gets a generous bound (a lost Ctrl-C runs ~10 s).
    assert finished or waited < 8.0, f"ended {waited:.1f} s after Ctrl-C"


def test_ctrl_c_while_an_engine_library_initialises_is_not_a_missing_engine(monkeypatch):
    """A compiled extension interrupted while it initialises raises ImportError caused by the
    KeyboardInterrupt: the engine's import raises KeyboardInterrupt again, not EngineUnavailable."""
    def interrupted(name):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as ki:
            raise ImportError("initialization failed") from ki
    monkeypatch.setattr(importlib, "import_module", interrupted)
    with pytest.raises(KeyboardInterrupt):
        engines.make_engine("mujoco")
    assert not caused_by_interrupt(ImportError("no module named mujoco"))


#: A SIGTERM that lands in a __del__ (Python ignores exceptions there, as in logging's at-fork hook
#: while a sweep's worker is forked), inside an Interrupts context; prints what check() does.
UNRAISABLE = """
import os, signal, time
from cosim.interrupts import Interrupts

class SignalsOnCollection:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)                    # the handler runs here, inside __del__

with Interrupts() as interrupts:
    SignalsOnCollection()                   # collected at once: its KeyboardInterrupt is unraisable
    try:
        interrupts.check()
        print("not remembered")
    except KeyboardInterrupt:
        print("remembered")
"""


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX signals")
def test_a_signal_python_cannot_raise_is_remembered_and_not_printed():
    """Seen in CI: a SIGTERM landing while a sweep forked a worker printed "Exception ignored ...
    Traceback" on stderr (and once the sweep ran on to exit 0). Now it is not printed, and
    ``check`` raises it at the next point. (A subprocess: pytest takes unraisable exceptions
    itself.)"""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    res = subprocess.run([sys.executable, "-c", UNRAISABLE], env=env, capture_output=True, text=True, timeout=120)
    assert res.stdout.strip() == "remembered", (res.stdout, res.stderr)
    assert "Traceback" not in res.stderr and "Exception ignored" not in res.stderr, res.stderr


def test_a_ctrl_c_a_library_catches_while_the_engines_load_still_ends_the_run(monkeypatch, tmp_path):
    """A library may catch the KeyboardInterrupt of a Ctrl-C: exudyn's import falls back to its
    other build when one fails to import, and an interrupted import fails. Caught while the
    engines load (before the run's loop), it was lost, and the run went on and ended with 0 (a
    Ctrl-C at about 1 s of `cosim run`'s start-up, seen once in CI). The run remembers signals
    from its start and ends before it writes anything."""
    real = runs.make_engine

    def catching_library(name, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.5)             # the handler runs here, at the next bytecode
        except KeyboardInterrupt:
            pass                        # the library's fallback
        return real(name, **kwargs)

    monkeypatch.setattr(runs, "make_engine", catching_library)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        runs.run_scenario("crank_rocker_373rpm", runs.RunOptions(engines=("mujoco",), revolutions=0.1, out=out,
                                                                 viewer="none", progress=False, figures=False))
    assert not out.exists()


class _Finalizer:
    """An object whose finalizer raises KeyboardInterrupt: what a Ctrl-C that lands in a callback
    Python runs and whose errors it ignores (importlib's module-lock weakref callback) looks like
    to Python: reported to ``sys.unraisablehook``, not raised."""

    def __del__(self):
        raise KeyboardInterrupt


def test_a_ctrl_c_python_could_not_raise_before_the_run_still_ends_it(tmp_path):
    """Seen in CI: a Ctrl-C at 0.5 s of `cosim run` landed in importlib's module-lock callback,
    Python printed "Exception ignored ... KeyboardInterrupt" and the run went on. Noted while the
    command starts (LostInterrupts), the run's Interrupts raises it before anything is written."""
    out = tmp_path / "out"
    with LostInterrupts():
        finalizer = _Finalizer()
        del finalizer
        with pytest.raises(KeyboardInterrupt):
            runs.run_scenario("crank_rocker_373rpm", runs.RunOptions(engines=("mujoco",), revolutions=0.1, out=out,
                                                                     viewer="none", progress=False, figures=False))
    assert not out.exists()


def test_a_lost_ctrl_c_ends_a_command_without_its_own_interrupts_with_130(monkeypatch, capsys):
    """`cosim list` has no Interrupts of its own: a Ctrl-C Python could not raise while it ran
    still ends it with 130, quietly."""
    real = cli.list_scenarios

    def listing_interrupted():
        finalizer = _Finalizer()
        del finalizer
        return real()

    monkeypatch.setattr(cli, "list_scenarios", listing_interrupted)
    assert cli.main(["list"]) == 130
    assert "Traceback" not in capsys.readouterr().err
