"""The crank speed a drive of finite inertia lets through: one revolution of a free-wheeling
crank, as a periodic crank history for the transfer-matrix model.

Within a revolution the FE rig's motor cannot hold the crank speed (its torque is far too small
against the linkage's inertia torques; docs/validation.md, "The drive"): the crank and everything rigidly
on its shaft exchange kinetic energy with the linkage. With an inertia ``J_d`` on the crank shaft
(flywheels, pulleys, the motor's rotor seen through a stiff belt) and the rigid linkage's
reflected inertia ``J(q)`` and gravity work ``W(q)`` (:meth:`FourBarMechanism.crank_inertia`),
energy is conserved over the revolution::

    (J_d + J(q)) w(q)^2 / 2 - W(q) = E,    W' = Q_g

and ``E`` is chosen so that the revolution lasts ``2 pi / |speed|`` (the speed the rig's counter
measured is the mean speed). The history is sampled at a constant time step (the transfer-matrix
step), with ``alpha = (Q_g - J'(q) w^2 / 2) / (J_d + J(q))``.

A belt between the motor and the crank shaft makes the motor's share of ``J_d`` frequency
dependent; its two limits (belt rigid: the rotor counts; belt soft: only the crank-shaft disks)
bound the effective ``J_d``, which is how the bench declares the drive's compliance (the belt's
own torsional mode is not modelled).

Owns: the periodic crank history of a free-wheeling drive of finite inertia. Boundaries: pure
numerics, no I/O; the motor model itself is the bench's (cosim.motor).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from .errors import InputError
from .ked import CrankMotion

N_FINE = 7200


def free_wheel(mech, speed_rad_s: float, drive_inertia_kg_m2: float, steps: int, *, start_angle: float = 0.0,
               gravity=None, applied=None) -> tuple:
    """``(CrankMotion over one period (steps + 1 samples), info)`` of a crank free-wheeling with
    the inertia ``drive_inertia_kg_m2`` on its shaft at mean speed ``speed_rad_s`` (sign = direction).
    ``applied``: a mechanism with ``generalized_force(q, direction)`` (the crank torque of applied
    loads, e.g. :class:`tmm_core.pin_moments.JointLoadedFourBar`); the motor supplies their mean
    (friction's loss) as a constant torque. ``info``: ``speed_fluctuation`` ((max - min) / mean
    of the speed), ``energy_J``, ``motor_torque_Nm``."""
    if not drive_inertia_kg_m2 > 0:
        raise InputError(f"drive inertia must be positive, got {drive_inertia_kg_m2!r} kg m^2")
    if not speed_rad_s:
        raise InputError("a free-wheeling crank needs a non-zero mean speed")
    s = math.copysign(1.0, speed_rad_s)
    period = 2 * math.pi / abs(speed_rad_s)                  # one revolution at the mean speed [s]
    u = np.linspace(0.0, 2 * math.pi, N_FINE + 1)          # crank rotation from the start, in the drive's direction
    q = start_angle + s * u
    J, dJ, Qg = mech.crank_inertia(q, gravity)
    Jt = J + drive_inertia_kg_m2

    def generalized(qq, Q):
        return Q + (applied.generalized_force(qq, s) if applied is not None else 0.0)
    Q = generalized(q, Qg)
    # The motor's constant torque makes up the mean (friction's loss; zero for conservative loads).
    torque = -float(np.sum(0.5 * (Q[1:] + Q[:-1]) * np.diff(u)) / (2 * math.pi))
    # Work along the rotation (W' = (Q + T_m) dq/du = s (Q + T_m)), trapezoidal.
    W = np.concatenate([[0.0], np.cumsum(0.5 * (Q[1:] + Q[:-1] + 2 * torque) * s * np.diff(u))])
    floor = float(np.max(-W))

    def duration(E):
        w = np.sqrt(2.0 * (E + W) / Jt)
        inv = 1.0 / w
        return float(np.sum(0.5 * (inv[1:] + inv[:-1]) * np.diff(u)))

    E_rigid = 0.5 * float(np.mean(Jt)) * speed_rad_s ** 2
    lo = floor + 1e-12 * max(E_rigid, 1e-12)
    hi = max(E_rigid, lo) * 2.0
    while duration(hi) > period:
        hi *= 4.0
    if duration(lo) < period:
        raise InputError("free-wheeling crank: no energy gives the requested mean speed")
    E = brentq(lambda e: duration(e) - period, lo, hi, xtol=1e-14 * hi, rtol=1e-13)
    w = np.sqrt(2.0 * (E + W) / Jt)                             # |speed| along the rotation
    inv = 1.0 / w
    t = np.concatenate([[0.0], np.cumsum(0.5 * (inv[1:] + inv[:-1]) * np.diff(u))])
    t *= period / t[-1]                                         # remove the quadrature's last 1e-8
    tk = np.linspace(0.0, period, steps + 1)
    uk = np.interp(tk, t, u)
    qk = start_angle + s * uk
    Jk, dJk, Qk = mech.crank_inertia(qk, gravity)
    Qk = generalized(qk, Qk) + torque
    Wk = np.interp(uk, u, W)
    wk = np.sqrt(2.0 * (E + Wk) / (Jk + drive_inertia_kg_m2))
    speed = s * wk
    accel = (Qk - 0.5 * dJk * speed ** 2) / (Jk + drive_inertia_kg_m2)
    speed[-1], accel[-1] = speed[0], accel[0]
    qk[-1] = qk[0] + s * 2 * math.pi
    info = {"speed_fluctuation": float((w.max() - w.min()) / abs(speed_rad_s)), "energy_J": float(E),
            "motor_torque_Nm": s * torque,
            "speed_min_rad_s": float(w.min()), "speed_max_rad_s": float(w.max())}
    return CrankMotion(tk, qk, speed, accel), info
