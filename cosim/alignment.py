"""Place a record on a run's time and crank-angle axes.

A record is a history over time, a history over one crank revolution, or constant peaks
(:mod:`cosim.records`); a run has its engines' (time, crank angle) samples. To draw a record
beside the engines, every record sample needs both coordinates:

* a time history gets the crank angle of the run's crank at that time (:func:`angle_at`);
* a one-revolution angle history is repeated over every revolution the run covers
  (:func:`repeat_revolution`) and gets the time at which the run's crank passed each angle
  (:func:`time_at`);
* outside the run's samples, or where its crank history is not monotone, the scenario's nominal
  speed continues it.

Pure numpy; used by the recording (:mod:`cosim.recording.writer`).

Owns: placing a record on a run's time and crank-angle axes. Boundaries: no scoring
(cosim.compare) and no file reading (cosim.records).
"""
from __future__ import annotations

import math

import numpy as np

from .scenario_types import revolution_period_s


def angle_at(t, t_hist, a_hist, speed: float, start_angle: float) -> np.ndarray:
    """Crank angle [rad] at times ``t`` [s] on the run's crank (``t_hist``, ``a_hist`` sorted by
    time), continued at the nominal ``speed`` outside it."""
    t = np.asarray(t, dtype=float)
    if len(t_hist) < 2:
        return start_angle + speed * t
    a = np.interp(t, t_hist, a_hist)
    a = np.where(t < t_hist[0], a_hist[0] + speed * (t - t_hist[0]), a)
    return np.where(t > t_hist[-1], a_hist[-1] + speed * (t - t_hist[-1]), a)


def time_at(angle, t_hist, a_hist, speed: float, start_angle: float) -> np.ndarray:
    """Time [s] at which the run's crank passes ``angle`` [rad]; the nominal speed where the
    crank history is missing or not monotone (a crank that stops or turns back has no unique
    time for an angle)."""
    angle = np.asarray(angle, dtype=float)
    d = np.diff(a_hist)
    if len(a_hist) < 2 or not d.any() or not (np.all(d >= 0) or np.all(d <= 0)):
        return (angle - start_angle) / speed
    order = np.argsort(a_hist)
    a_sorted, t_sorted = np.asarray(a_hist)[order], np.asarray(t_hist)[order]
    t = np.interp(angle, a_sorted, t_sorted)
    lo, hi = a_sorted[0], a_sorted[-1]
    t = np.where(angle < lo, t_sorted[0] + (angle - lo) / speed, t)
    return np.where(angle > hi, t_sorted[-1] + (angle - hi) / speed, t)


def repeat_revolution(angle, values, a_lo: float, a_hi: float) -> tuple:
    """One revolution of samples (``angle`` [rad], ``values`` (k, m)) repeated every 2 pi over
    [a_lo, a_hi], sorted by angle: (angles, values)."""
    a = np.asarray(angle, dtype=float)
    values = np.asarray(values, dtype=float)
    k = np.arange(math.floor((a_lo - a.max()) / (2 * math.pi)), math.ceil((a_hi - a.min()) / (2 * math.pi)) + 1)
    angles = (a[None, :] + 2 * math.pi * k[:, None]).ravel()
    vals = np.tile(values, (len(k), 1))
    keep = (angles >= a_lo - 1e-12) & (angles <= a_hi + 1e-12)
    angles, vals = angles[keep], vals[keep]
    order = np.argsort(angles, kind="stable")
    return angles[order], vals[order]


def extent(histories, speed: float, start_angle: float) -> tuple:
    """(t_lo, t_hi, a_lo, a_hi) over every (t, angle) array pair in ``histories``; one nominal
    revolution from the start when there is none."""
    histories = [(np.asarray(t), np.asarray(a)) for t, a in histories if np.size(t)]
    if histories:
        t_all = np.concatenate([t for t, _ in histories])
        a_all = np.concatenate([a for _, a in histories])
        return float(t_all.min()), float(t_all.max()), float(a_all.min()), float(a_all.max())
    end = start_angle + math.copysign(2 * math.pi, speed)
    return 0.0, revolution_period_s(speed), min(start_angle, end), max(start_angle, end)
