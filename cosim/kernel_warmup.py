"""A first run's transfer-matrix kernels, compiled beside it.

On a machine whose numba cache is cold, the compiled backend first compiles its kernels: about
:data:`tmm_core.compiled.cache.COMPILE_ESTIMATE_S` on a 2-core machine, during which the run
shows nothing. A run whose transfer-matrix engine would take less than
:data:`NUMPY_FIRST_RUN_LIMIT_S` in numpy (the reference backend, held equal to the compiled one
to 1e-12 by the tests) runs in numpy instead,
while a second process compiles the kernels into the cache for the next runs; the answer comes
first, then the run waits for the compilation to end (saying so; Ctrl-C skips it), so that no
process outlives the run and the next run finds the cache warm.

The second process is ``python -m cosim.kernel_warmup <run folder>/scenario.resolved.toml``: a
few macro steps of a prescribed run of the same scenario (the file's ``[input]``) with the
compiled backend, which compiles the kernels such a
run calls (the static solve, the load-to-response maps, the march) with the run's own types.

Owns: the choice (:func:`first_run_in_numpy`), the second process (:class:`KernelWarmup`) and its
entry point (:func:`main`). Boundaries: the cache and its estimate are tmm_core.compiled.cache's;
the run itself is cosim.runs'.
"""
from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tmm_core.backend import choose_backend
from tmm_core.compiled.cache import COMPILE_ESTIMATE_S, cache_is_cold

from .engines import make_engine
from .master import run_prescribed
from .children import stop_process
from .run_guards import tmm_numpy_seconds
from .scenario import Scenario, load

log = logging.getLogger(__name__)

#: The warm-up run's length [revolutions]: a few macro steps reach every kernel of the march.
WARMUP_REVOLUTIONS = 0.02
#: How much lower than the run's the warm-up's scheduling priority is (``os.nice``).
WARMUP_NICENESS = 10
#: The longest numpy run [s] (its estimate for the run's planned length) that a first run makes
#: rather than waiting for the compilation. Longer than the compilation itself
#: (:data:`tmm_core.compiled.cache.COMPILE_ESTIMATE_S`): the two run side by side on two cores,
#: so a numpy run that takes its whole planned length ends at most this minus the compilation
#: later than a compiled one, while an until-steady run usually stops far sooner (the FE rig's
#: default run: planned 40 revolutions, estimated 43 s; its table printed after about 5 s).
NUMPY_FIRST_RUN_LIMIT_S = 50.0


def first_run_in_numpy(sc: Scenario, engines, duration_s: float) -> bool:
    """Whether a run of ``duration_s`` [s] simulated with ``engines`` runs its transfer-matrix
    engine in numpy while the kernels compile beside it: numba is installed, its cache is cold,
    and the numpy path's estimate for the run's whole planned length
    (:func:`cosim.run_guards.tmm_numpy_seconds`) is within :data:`NUMPY_FIRST_RUN_LIMIT_S`."""
    return ("tmm" in engines and choose_backend(None) == "compiled" and cache_is_cold()
            and tmm_numpy_seconds(sc, duration_s) <= NUMPY_FIRST_RUN_LIMIT_S)


class KernelWarmup:
    """The second process compiling the kernels (:func:`start`), awaited by :meth:`finish` or
    stopped by :meth:`stop`."""

    def __init__(self, process: subprocess.Popen, errors, started: float):
        self.process = process
        self.errors = errors          # its standard error, read if it fails
        self.started = started        # time.monotonic() at its start [s]

    @classmethod
    def start(cls, scenario_file: Path) -> KernelWarmup:
        """Start compiling the kernels a prescribed run of ``scenario_file`` uses, and say so."""
        log.info("first run on this machine: the transfer-matrix kernels are compiling in a second process for the "
                 "next runs (about %.0f s); meanwhile this run's transfer-matrix engine runs in numpy (the reference "
                 "backend: the same results, slower per step)", COMPILE_ESTIMATE_S)
        errors = tempfile.TemporaryFile()
        process = subprocess.Popen([sys.executable, "-m", "cosim.kernel_warmup", str(scenario_file)],
                                   stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=errors)
        return cls(process, errors, time.monotonic())

    def finish(self) -> str:
        """Wait for the compilation to end, saying how long it may take; Ctrl-C stops it. Returns
        the note for the run's summary."""
        if self.process.poll() is None:
            left = max(1.0, COMPILE_ESTIMATE_S - (time.monotonic() - self.started))
            log.info("finishing the transfer-matrix kernels' compilation for the next runs (about %.0f s left; "
                     "Ctrl-C skips it, and the next run compiles them then)", left)
            try:
                self.process.wait()
            except KeyboardInterrupt:
                self.stop()
                return "the transfer-matrix kernels' compilation was skipped (Ctrl-C): the next run compiles them"
        code = self.process.returncode
        self.errors.seek(0)
        lines = self.errors.read().decode(errors="replace").strip().splitlines()
        self.errors.close()
        if code != 0:
            reason = lines[-1] if lines else f"exit status {code}"
            log.warning("compiling the transfer-matrix kernels failed (%s): the next run compiles them itself", reason)
            return f"compiling the transfer-matrix kernels beside the run failed ({reason})"
        log.info("the transfer-matrix kernels are compiled: the next runs load them from numba's cache")
        return ("first run on this machine: the transfer-matrix engine ran in numpy (the reference backend) while "
                "its compiled kernels were compiled beside it for the next runs")

    def stop(self) -> None:
        """Stop the compilation (the run ended early or failed)."""
        stop_process(self.process, grace_s=5.0)
        self.errors.close()


def main(argv: list[str] | None = None) -> int:
    """Compile the kernels of a prescribed run of the scenario a run folder's
    ``scenario.resolved.toml`` (``argv[0]``) records (overrides included: :func:`cosim.scenario.load`
    reads its ``[input]``): a few macro steps of it through the transfer-matrix engine with the
    compiled backend."""
    args = sys.argv[1:] if argv is None else argv
    # The run beside it first: the warm-up and its helper processes (which inherit this) yield
    # the cores to the run's own engines, so its table comes sooner; alone, they lose nothing.
    os.nice(WARMUP_NICENESS)
    run_prescribed(make_engine("tmm", backend="compiled"), load(Path(args[0])), revolutions=WARMUP_REVOLUTIONS)
    return 0


if __name__ == "__main__":
    sys.exit(main())
