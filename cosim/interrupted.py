"""A run cut back to what was written when a signal arrives: after the interrupt every engine
ends at the last macro step written to ``traces.csv``.

Owns: the trimming of interrupted results. Boundaries: no files, no signal handling
(:mod:`cosim.interrupts`).
"""
from __future__ import annotations

import math

import numpy as np

from tmm_core.revolution import revolutions_completed


def trim_samples(obj, t_end: float) -> None:
    """Drop the samples after ``t_end`` (an interrupted macro step that reached some engines but
    was never written) from an EngineRun or MotorTrace, in place."""
    t = getattr(obj, "t", None)
    if t is None or not len(t) or t[-1] <= t_end:
        return
    keep = np.asarray(t) <= t_end * (1 + 1e-12) + 1e-15
    n = len(t)

    def cut(x):
        if isinstance(x, np.ndarray) and x.ndim and len(x) == n:
            return x[keep]
        if isinstance(x, tuple):
            return tuple(cut(v) for v in x)
        if isinstance(x, dict):
            return {k: cut(v) for k, v in x.items()}
        return x
    for name, value in list(vars(obj).items()):
        setattr(obj, name, cut(value))


def mark_interrupted(result, written_t, failures: dict) -> None:
    """After a signal: every engine ends at the last macro step written to traces.csv (a step
    some engines finished and others did not is dropped), and an engine whose solver turned the
    interrupt into a failure (exudyn reports it as a Newton failure in a user function) is
    interrupted, not failed. ``failures``: the engines that failed in a written step."""
    for name, ch in result.channels.items():
        if ch.status == "failed" and name not in failures:
            ch.status, ch.error = "interrupted", None
        elif ch.status in ("completed", "stopped"):
            ch.status = "interrupted"
        if written_t is not None:
            trim_samples(ch.run, written_t)
            if ch.motor is not None:
                trim_samples(ch.motor, written_t)
        else:
            trim_samples(ch.run, -math.inf)
        _cut_length(ch, result.macro_step_s, written_t)
    sts = {ch.status for ch in result.channels.values()}
    result.status = "failed" if "failed" in sts else "interrupted"
    result.stop = "interrupted"
    sim_time = max((ch.sim_time_s for ch in result.channels.values()), default=0.0)
    result.t_end_s, result.sim_time_s = result.t_end_s - (result.sim_time_s - sim_time), sim_time


def _cut_length(ch, macro_step_s: float, written_t) -> None:
    """A channel's whole-run length (macro steps, simulated time [s], revolutions) cut back to
    the last macro step written (``written_t`` [s], None: none was)."""
    written = 0 if written_t is None else int(round((written_t - ch.t0) / macro_step_s))
    if ch.macro_steps <= written:
        return
    ch.macro_steps, ch.sim_time_s = written, written * macro_step_s
    a = ch.run.crank_angle
    ch.revolutions_run = revolutions_completed([ch.angle0, float(a[-1])]) if len(a) else 0.0
