"""One crank revolution: its window in a crank history, the change from one revolution to the
next, and one revolution of factorized configurations re-used by every revolution of a march.

A revolution is measured on the crank angle (cumulative, either direction), not on the clock, so
that the same definition holds at a prescribed speed and under a motor whose speed fluctuates.
The *revolution change* of a set of signals is the largest difference between the last
revolution and the one before, at equal crank angle, relative to each signal's peak-to-peak over
the last revolution. A march is *steady* when it falls below a tolerance.

Owns: the last revolution's window, the revolution change (on any crank samples, and on two
revolutions sampled at the same crank angles), :class:`Revolution` (the configurations of one
revolution at a constant speed, which the time domain and the bench's engine both march on) and
the march of a periodic crank history to its steady revolution. Boundaries: no I/O; the
configurations are :func:`tmm_core.batches.configurations`'.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .batches import configurations
from .configuration_batch import ConfigurationBatch
from .discretization import Discretization
from .march import begin

#: Crank angle [rad] within which a step's crank state matches a configuration of a revolution.
ANGLE_MATCH_RAD = 1e-9


def phase(angle) -> np.ndarray:
    """Crank angle travelled back from the last sample [rad] (<= 0, increasing with time)."""
    a = np.asarray(angle, dtype=float)
    direction = 1.0 if a[-1] >= a[0] else -1.0
    return direction * (a - a[-1])


def revolutions_completed(angle) -> float:
    """Crank revolutions travelled by the samples (``angle`` [rad], cumulative)."""
    a = np.asarray(angle, dtype=float)
    return float(abs(a[-1] - a[0]) / (2 * math.pi)) if len(a) > 1 else 0.0


def last_revolution(angle) -> np.ndarray:
    """Boolean mask of the samples in the last crank revolution: those whose crank angle lies
    less than one revolution back from the last sample's (``angle`` [rad], cumulative). This is
    the one definition of the last revolution's window (the extremes, the scores, the figures and
    the steady-state comparison all use it)."""
    if len(angle) == 0:
        return np.zeros(0, dtype=bool)
    return phase(angle) > -2 * math.pi * (1 - 1e-12)


def revolution_change(angle, signals) -> float:
    """Largest change between the last and the previous revolution of the ``signals`` (arrays
    over the same samples as ``angle`` [rad]), at equal crank angle, relative to each signal's
    peak-to-peak over the last revolution (:func:`last_revolution`); NaN with less than two
    revolutions. The crank angle must increase monotonically in the direction of rotation."""
    a = np.asarray(angle, dtype=float)
    if revolutions_completed(a) < 2 * (1 - 1e-9):
        return float("nan")
    ph = phase(a)
    last = last_revolution(a)
    # The previous revolution at the last one's crank angles is interpolated over *all* samples:
    # the angle one revolution before the window's first (last) sample lies between a sample of
    # the revolution before the previous one and one of the previous (of the previous and one of
    # the last). Interpolating in the previous revolution's samples alone clamps those queries to
    # its end values, which in a motor run (samples uniform in time, not in angle, so none falls
    # on the window's edge) differ by a sample's worth of the signal's slope.
    query = ph[last] - 2 * math.pi
    worst = 0.0
    for x in signals:
        x = np.asarray(x, dtype=float)
        xl, xp = x[last], np.interp(query, ph, x)
        span = float(np.ptp(xl))
        if span <= 0.0 or not np.isfinite(span):
            continue
        worst = max(worst, float(np.max(np.abs(xl - xp))) / span)
    return worst


def aligned_change(last: np.ndarray, previous: np.ndarray) -> float:
    """:func:`revolution_change` of two revolutions sampled at the same crank angles: ``last``
    and ``previous`` are (N, n_signals) rows of the same steps of a revolution; the largest
    difference relative to each signal's peak-to-peak over ``last`` (a constant signal counts
    with a peak-to-peak of 1e-300, so any change of it is large)."""
    span = np.maximum(np.ptp(last, axis=0), 1e-300)
    return float(np.max(np.max(np.abs(last - previous), axis=0) / span))


@dataclass(frozen=True)
class Revolution:
    """One revolution of factorized configurations: ``steps`` configurations at crank ``angles``
    [rad] (steps, ), the crank ``speeds`` [rad/s] and ``accelerations`` [rad/s^2] they were built
    at, and the :class:`tmm_core.configuration_batch.ConfigurationBatch` a march steps on. Step
    ``k`` of a periodic crank history is configuration ``k mod steps``."""

    steps: int
    angles: np.ndarray
    speeds: np.ndarray
    accelerations: np.ndarray
    batch: ConfigurationBatch

    @classmethod
    def build(cls, model: Discretization, angles, speeds, accelerations, dt: float) -> "Revolution":
        """The configurations of ``model`` at one revolution's crank states (arrays of equal
        length, step ``dt`` [s])."""
        angles, speeds, accelerations = (np.array(x, dtype=float) for x in (angles, speeds, accelerations))
        batch = configurations(model, angles, speeds, accelerations, dt)
        return cls(len(angles), angles, speeds, accelerations, batch)

    def indices(self, steps, angle, speed, accel) -> np.ndarray:
        """The configuration of each of the march's ``steps`` (step numbers counted from the
        revolution's first configuration) whose crank state (``angle`` [rad], ``speed``
        [rad/s], ``accel`` [rad/s^2], arrays over the steps) is the one it was built at, else -1."""
        idx = np.asarray(steps, dtype=np.int64) % self.steps
        d = (angle - self.angles[idx] + math.pi) % (2 * math.pi) - math.pi
        same = (np.abs(d) < ANGLE_MATCH_RAD) & (speed == self.speeds[idx]) & (accel == self.accelerations[idx])
        return np.where(same, idx, -1)


def march_to_steady(model: Discretization, crank, tolerance: float, max_revolutions: int) -> tuple:
    """March ``model`` through the periodic crank history ``crank`` (a
    :class:`tmm_core.ked.CrankMotion` of one period, N + 1 samples, whose speed may fluctuate) from
    its quasi-static state, re-using one :class:`Revolution`, until two revolutions agree to
    ``tolerance`` (:func:`aligned_change`): ``(outputs of the last revolution (N, n_out),
    revolutions marched, change)``. Raises FloatingPointError if the march becomes non-finite."""
    N = len(crank.t) - 1
    revolution = Revolution.build(model, crank.angle[:N], crank.speed[:N], crank.acceleration[:N], crank.dt)
    march = begin(model, crank.dt, crank.angle[0], crank.speed[0], crank.acceleration[0], start="quasi_static")
    idx = np.arange(1, N + 1) % N
    previous, change = None, math.inf
    for rev in range(1, max_revolutions + 1):
        _, outs = march.step_many(revolution.batch, idx, record_z=False)
        if not np.all(np.isfinite(outs)):
            raise FloatingPointError("the march became non-finite")
        if previous is not None:
            change = aligned_change(outs, previous)
            if change < tolerance:
                return outs, rev, change
        previous = outs
    return outs, max_revolutions, change
