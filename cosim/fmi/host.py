"""An FMU's binary in a process of its own, behind FMPy's ``FMU2Slave`` methods.

Why: an FMU's binary shares the importing process. PythonFMU's (0.7) runs the model in the
importing interpreter and leaves it corrupted (crashes in the garbage collector after a run, a
second instance that cannot find its model class: PythonFMU's open issue 228), and any FMU that
crashes takes the master down with it. The bench's FMU drive therefore hosts the FMU in a child
process (a fresh interpreter, ``python -m cosim.fmi.host``: nothing of the master's state is
inherited) and talks to it over its stdin/stdout (pickled requests and answers; the child's own
prints go to stderr): one round trip per call, and one per engine sample with
:meth:`FmuProcess.step` (inputs set, the step, outputs read). FMU states (fmi2GetFMUstate) stay
in the child, named by an integer.

Owns: ``FmuProcess`` and the child's loop. Boundaries: FMPy is imported only in the child.
"""
from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

from tmm_core import TMMError


class FmuHostError(TMMError):
    """The FMU's process failed a call or died; the message names the FMU and the call."""


class FmuProcess:
    """FMPy's ``FMU2Slave`` for the FMU ``path`` in a child process. Methods are forwarded by
    name (``instantiate``, ``setReal``, ``doStep``, ...); ``getFMUState`` returns an integer that
    ``setFMUState``/``freeFMUState`` take."""

    def __init__(self, path: str, guid: str, model_identifier: str):
        self.path = path
        root = str(Path(__file__).resolve().parents[2])          # the bench's packages, for the child
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
        self.process = subprocess.Popen([sys.executable, "-m", "cosim.fmi.host", path, guid, model_identifier],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env)
        self._call("ready")

    def _call(self, name: str, *args):
        try:
            pickle.dump((name, args), self.process.stdin)
            self.process.stdin.flush()
            ok, value = pickle.load(self.process.stdout)
        except (EOFError, OSError, pickle.UnpicklingError):
            code = self.process.poll()
            raise FmuHostError(f"FMU '{self.path}': its process ended during {name} (exit code {code})") from None
        if not ok:
            raise FmuHostError(f"FMU '{self.path}': {name} failed ({value})")
        return value

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        return lambda *args: self._call(name, *args)

    def step(self, t: float, h: float, inputs: list, values: list, outputs: list) -> list:
        """Set the real ``inputs`` (value references) to ``values``, step from ``t`` by ``h``
        [s], return the real ``outputs``: one round trip."""
        return self._call("step", t, h, inputs, values, outputs)

    def close(self) -> None:
        """End the child (it exits without tearing the FMU down, which may crash it)."""
        if self.process.poll() is None:
            try:
                pickle.dump(("close", ()), self.process.stdin)
                self.process.stdin.flush()
            except OSError:
                pass
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            stream.close()


def serve(path: str, guid: str, model_identifier: str) -> None:
    """The child's loop: load the FMU, answer ``(name, args)`` requests with ``(ok, value)``."""
    # The protocol keeps the original stdout; anything printed (the FMU's model too) goes to stderr.
    out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    inp = sys.stdin.buffer
    from fmpy import extract
    from fmpy.fmi2 import FMU2Slave
    try:
        fmu, error = FMU2Slave(guid=guid, unzipDirectory=extract(path), modelIdentifier=model_identifier,
                               instanceName="drive"), None
    except Exception as exc:          # a binary that does not load: said on every request
        fmu, error = None, f"loading its binary failed ({type(exc).__name__}: {exc})"
    states, counter = {}, [0]

    def step(t, h, inputs, values, outputs):
        fmu.setReal(inputs, values)
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        return list(fmu.getReal(outputs))

    def get_state():
        counter[0] += 1
        states[counter[0]] = fmu.getFMUState()
        return counter[0]

    special = {"ready": lambda: True, "step": step, "getFMUState": get_state,
               "setFMUState": lambda k: fmu.setFMUState(states[k]),
               "freeFMUState": lambda k: fmu.freeFMUState(states.pop(k))}
    def send(answer):
        pickle.dump(answer, out)
        out.flush()

    while True:
        try:
            name, args = pickle.load(inp)
        except EOFError:
            os._exit(0)
        if name == "close":
            os._exit(0)              # no teardown: a PythonFMU binary may crash in it
        if error is not None:
            send((False, error))
            continue
        try:
            value = special[name](*args) if name in special else getattr(fmu, name)(*args)
            if value is not None and not isinstance(value, (bool, int, float, list)):
                value = list(value) if hasattr(value, "__len__") else None
            send((True, value))
        except Exception as exc:      # an FMI error of any kind goes back to the master
            send((False, f"{type(exc).__name__}: {exc}"))


if __name__ == "__main__":
    serve(*sys.argv[1:4])
