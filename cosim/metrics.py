"""Post-processing of engine runs: revolution windows by crank angle and the steady-state check.

A revolution is measured on the crank angle the engine itself reports (cumulative, either
direction), not on the clock, so that the same definition holds at a prescribed speed and under
a motor whose speed fluctuates. The *revolution change* of a run is the largest difference
between its last revolution and the one before, at equal crank angle, relative to the last
revolution's peak-to-peak, over the drive torque and every gauge's bending strain. A run is
*steady* when that change is below the tolerance (default 0.5 %).

Owns: these definitions. Must not touch: engines, files, the recording.
"""
from __future__ import annotations

import math

import numpy as np

STEADY_TOLERANCE = 5e-3     # last two revolutions agree to 0.5 % of their peak-to-peak


def _phase(angle) -> np.ndarray:
    """Crank angle travelled back from the last sample [rad] (<= 0, increasing with time)."""
    a = np.asarray(angle, dtype=float)
    direction = 1.0 if a[-1] >= a[0] else -1.0
    return direction * (a - a[-1])


def revolutions_completed(angle) -> float:
    """Crank revolutions travelled by the samples (``angle`` [rad], cumulative)."""
    a = np.asarray(angle, dtype=float)
    return float(abs(a[-1] - a[0]) / (2 * math.pi)) if len(a) > 1 else 0.0


def last_revolution(angle) -> np.ndarray:
    """Boolean mask of the samples in the last crank revolution."""
    if len(angle) == 0:
        return np.zeros(0, dtype=bool)
    return _phase(angle) > -2 * math.pi * (1 - 1e-12)


def revolution_change(angle, signals) -> float:
    """Largest change between the last and the previous revolution of the ``signals`` (arrays
    over the same samples as ``angle``), relative to each signal's peak-to-peak over the last
    revolution; NaN with less than two revolutions."""
    a = np.asarray(angle, dtype=float)
    if revolutions_completed(a) < 2 * (1 - 1e-9):
        return float("nan")
    ph = _phase(a)
    last = ph > -2 * math.pi * (1 - 1e-12)
    prev = (~last) & (ph > -4 * math.pi * (1 + 1e-12))
    worst = 0.0
    for x in signals:
        x = np.asarray(x, dtype=float)
        xl, xp = x[last], np.interp(ph[last] - 2 * math.pi, ph[prev], x[prev])
        span = float(np.ptp(xl))
        if span <= 0.0 or not np.isfinite(span):
            continue
        worst = max(worst, float(np.max(np.abs(xl - xp))) / span)
    return worst


def run_change(run) -> float:
    """:func:`revolution_change` of an engine run (drive torque and gauge bending strains)."""
    if len(run.t) == 0:
        return float("nan")
    signals = [run.drive_torque] + [bending for bending, _ in run.gauges.values()]
    return revolution_change(run.crank_angle, [s for s in signals if np.all(np.isfinite(s))])


class SteadyWatch:
    """Follows engines macro step by macro step and tells when each one is steady. Keeps only
    the last three revolutions of each engine (memory bounded in run length)."""

    def __init__(self, tolerance: float = STEADY_TOLERANCE, min_revolutions: float = 2.0):
        self.tolerance = tolerance
        self.min_revolutions = min_revolutions
        self._chunks = {}           # engine -> [(angle, torque, [bending, ...]), ...]
        self._start = {}            # engine -> first crank angle [rad]
        self.change = {}            # engine -> revolution change at the last check

    def add(self, engine: str, out) -> None:
        """Record one macro step's :class:`cosim.engines.base.EngineOutput`."""
        if len(out.t) == 0:
            return
        chunks = self._chunks.setdefault(engine, [])
        self._start.setdefault(engine, float(out.crank_angle[0]))
        chunks.append((np.asarray(out.crank_angle, float), np.asarray(out.drive_torque, float),
                       [np.asarray(b, float) for b, _ in out.gauges.values()]))
        while len(chunks) > 1 and abs(chunks[-1][0][-1] - chunks[1][0][0]) > 6 * math.pi:
            chunks.pop(0)

    def revolutions(self, engine: str) -> float:
        chunks = self._chunks.get(engine)
        return abs(chunks[-1][0][-1] - self._start[engine]) / (2 * math.pi) if chunks else 0.0

    def steady(self, engine: str) -> bool:
        """True when the engine has run ``min_revolutions`` and its last two revolutions agree."""
        if self.revolutions(engine) < max(2.0, self.min_revolutions) - 1e-9:
            return False
        chunks = self._chunks[engine]
        angle = np.concatenate([c[0] for c in chunks])
        signals = [np.concatenate([c[1] for c in chunks])]
        signals += [np.concatenate([c[2][i] for c in chunks]) for i in range(len(chunks[0][2]))]
        self.change[engine] = revolution_change(angle, [x for x in signals if np.all(np.isfinite(x))])
        return self.change[engine] < self.tolerance
