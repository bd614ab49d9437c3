"""Interface signals of the co-simulation between macro steps: values extrapolated from the last
macro-step ends, the crank motion extrapolated or interpolated through samples, and the rigid
linkage's reflected inertia tabulated over a revolution (the interface Jacobian).

Owns: those signals. Boundaries: no engines, no motor; :mod:`cosim.master` drives them.
"""
from __future__ import annotations

import math

import numpy as np


def extrapolate(history, t, order: int):
    """Value at times ``t`` from ``history`` = [(t_i, x_i), ...] at the last macro-step ends:
    the last value (order 0) or the line through the last two (order 1)."""
    t_a, x_a = history[-1]
    if order == 0 or len(history) < 2:
        return np.full(np.shape(t), x_a, dtype=float) if np.ndim(t) else float(x_a)
    t_p, x_p = history[-2]
    return x_a + (x_a - x_p) / (t_a - t_p) * (np.asarray(t, dtype=float) - t_a)


def crank_extrapolation(t_a, angle, speed, accel):
    """Crank motion from the state at ``t_a`` with constant acceleration: (angle, speed, accel)(t)."""
    def motion(t):
        tau = np.asarray(t, dtype=float) - t_a
        return angle + speed * tau + 0.5 * accel * tau**2, speed + accel * tau, np.full(np.shape(tau), float(accel))
    return motion


def crank_interpolation(t, angle, speed, accel=None):
    """Crank motion through samples: angle cubic Hermite (consistent with the speeds), speed and
    acceleration piecewise linear (the acceleration from the Hermite spline if not given)."""
    # Imported here: scipy.interpolate takes 0.8 s to import (it pulls in scipy.optimize), and
    # only a motor-driven run's coupling needs it; a prescribed run's start-up does not pay it.
    from scipy.interpolate import CubicHermiteSpline
    spline = CubicHermiteSpline(t, angle, speed)

    def motion(tq):
        tq = np.asarray(tq, dtype=float)
        a = np.interp(tq, t, accel) if accel is not None else spline(tq, 2)
        return spline(tq), np.interp(tq, t, speed), a
    return motion


def linear_interpolation(t, x):
    """``x(tq)`` interpolated linearly through the samples ``(t, x)``."""
    return lambda tq: np.interp(tq, t, x)


class ReflectedInertia:
    """The rigid linkage's reflected inertia J_r(q) [kg m^2] (interface Jacobian), tabulated over
    a revolution and interpolated linearly (scalar calls stay in pure Python: the motor's
    integrator calls it at every stage)."""

    def __init__(self, inertia, n: int = 1440):
        self.n, self.dq = n, 2 * math.pi / n
        J = inertia(np.arange(n) * self.dq)
        self.table = np.r_[J, J[0]]
        self.values = self.table.tolist()
        self.max = float(J.max())

    def __call__(self, angle):
        if np.ndim(angle):
            x = np.mod(np.asarray(angle, dtype=float), 2 * math.pi) / self.dq
            return np.interp(x, np.arange(self.n + 1), self.table)
        x = (float(angle) % (2 * math.pi)) / self.dq
        k = min(int(x), self.n - 1)
        f = x - k
        return self.values[k] * (1.0 - f) + self.values[k + 1] * f
