"""Monolithic reference for the motor tests: the rigid four-bar and the DC motor as one ODE.

Written independently of :mod:`cosim.motor` and :mod:`cosim.master`: the four-bar enters through
its equivalent-inertia equation of motion (Lagrange, one degree of freedom),

    (J_d + J(q)) q'' + J'(q) q'^2 / 2 = T_drive + Q_g(q),

with J(q) = sum m |dr_c/dq|^2 + J_c (dphi/dq)^2 from finite differences of the closed-form
*positions* (not the velocity routines the engines use), and the motor's equations written out
here again. scipy's DOP853 at rtol 1e-11 solves it.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

H_FD = 1e-5


def _mass_properties(link):
    """(mass, centre of mass x, inertia about it) summed segment by segment here (uniform rods)."""
    x = link.stations
    m_seg = link.segment_mass_per_length() * np.diff(x)
    xc = 0.5 * (x[1:] + x[:-1])
    m = float(m_seg.sum()) + sum(p.mass_kg for p in link.point_masses)
    first = float(m_seg @ xc) + sum(p.mass_kg * p.position_m for p in link.point_masses)
    com = first / m
    J = float(m_seg @ (np.diff(x) ** 2 / 12 + (xc - com) ** 2))
    J += sum(p.inertia_kg_m2 + p.mass_kg * (p.position_m - com) ** 2 for p in link.point_masses)
    return m, com, J


def _lumped_masses(link):
    """Masses at the mesh nodes: each segment's mass half to each end (Shin's lumping, the
    transfer-matrix model's mass model), plus the point masses; their rotary inertias."""
    x = link.stations
    m_seg = link.segment_mass_per_length() * np.diff(x)
    m = np.zeros(len(x))
    m[:-1] += 0.5 * m_seg
    m[1:] += 0.5 * m_seg
    J = np.zeros(len(x))
    for p in link.point_masses:
        j = int(np.argmin(np.abs(x - p.position_m)))
        m[j] += p.mass_kg
        J[j] += p.inertia_kg_m2
    return x, m, J


def equivalent_inertia(mech, q, mass_model: str = "exact"):
    """J(q) [kg m^2] from central differences of positions and link angles. ``mass_model``:
    'exact' (distributed mass, rigid bodies) or 'lumped' (node masses)."""
    q = np.asarray(q, dtype=float)
    plus, minus = mech.motion(q + H_FD), mech.motion(q - H_FD)
    J = np.zeros(q.shape)
    for link in mech.links():
        if mass_model == "exact":
            m, xc, Jc = _mass_properties(link)
            xc, m, Jc = np.array([xc]), np.array([m]), np.array([Jc])
        else:
            xc, m, Jc = _lumped_masses(link)
        lp, lm = plus.link(link.name), minus.link(link.name)
        v = (lp.point(xc)[0] - lm.point(xc)[0]) / (2 * H_FD)          # (..., k, 2)
        w = (lp.angle - lm.angle)[..., None] / (2 * H_FD)
        J += np.sum(m * np.sum(v * v, -1) + Jc * w**2, -1)
    return J


class RigidFourBarWithMotor:
    """The monolithic model. ``p``: a :class:`cosim.motor.MotorParameters` (only its numbers are
    used). J(q) and J'(q) are tabulated on a fine periodic grid and interpolated with a periodic
    cubic spline."""

    def __init__(self, mech, p, mass_model: str = "exact", n_table: int = 2048):
        from scipy.interpolate import CubicSpline
        q = np.linspace(0, 2 * math.pi, n_table + 1)
        J = equivalent_inertia(mech, q[:-1], mass_model)
        self.J = CubicSpline(q, np.r_[J, J[0]], bc_type="periodic")
        self.dJ = self.J.derivative()
        self.p = p
        self.J_drive = p.flywheel_inertia_kg_m2 + p.gear_ratio**2 * p.rotor_inertia_kg_m2

    def _voltage(self, t, w, xI):
        p = self.p
        e = float(p.setpoint(t)) - w
        v = p.kp_V_s_rad * e + xI
        hi = p.supply_voltage_V
        if v > hi:
            return hi, (0.0 if e > 0 else p.ki_V_rad * e)
        if v < 0.0:
            return 0.0, (0.0 if e < 0 else p.ki_V_rad * e)
        return v, p.ki_V_rad * e

    def drive_torque(self, w, i):
        p = self.p
        wm = p.gear_ratio * w
        return p.gear_ratio * (p.torque_constant_Nm_A * i - p.viscous_friction_Nm_s_rad * wm -
                               p.coulomb_friction_Nm * np.tanh(wm / 0.01))

    def rhs(self, t, y):
        q, w, i, xI = y
        p = self.p
        v, dxI = self._voltage(t, w, xI)
        qm = q % (2 * math.pi)
        acc = (self.drive_torque(w, i) - 0.5 * self.dJ(qm) * w * w) / (self.J_drive + self.J(qm))
        di = (v - p.resistance_ohm * i - p.back_emf_V_s_rad * p.gear_ratio * w) / p.inductance_H
        return [w, acc, di, dxI]

    def steady_start(self, q0, w0):
        """Current and integrator in equilibrium with friction at speed w0 (no linkage load)."""
        p = self.p
        wm = p.gear_ratio * w0
        i = (p.viscous_friction_Nm_s_rad * wm + p.coulomb_friction_Nm * math.tanh(wm / 0.01)) / p.torque_constant_Nm_A
        return [q0, w0, i, p.resistance_ohm * i + p.back_emf_V_s_rad * wm]

    def solve(self, t_end, y0=None, t_eval=None, scenario=None):
        """Solve to ``t_end`` [s] from ``y0`` = (angle, speed, current, integrator), by default the
        steady start at the scenario's start angle and set-point speed; samples ``t_eval``
        (default 20001 points)."""
        if y0 is None:
            y0 = self.steady_start(scenario.drive.start_angle_rad, scenario.drive.speed_rad_s)
        if t_eval is None:
            t_eval = np.linspace(0.0, t_end, 20001)
        sol = solve_ivp(self.rhs, (0.0, t_end), y0, method="DOP853", rtol=1e-11, atol=1e-11, t_eval=t_eval)
        assert sol.success, sol.message
        q, w, i, xI = sol.y
        qm = q % (2 * math.pi)
        acc = np.array([self.rhs(t, y)[1] for t, y in zip(sol.t, sol.y.T)])
        load = self.J(qm) * acc + 0.5 * self.dJ(qm) * w * w      # torque the linkage takes
        return {"t": sol.t, "angle": q, "speed": w, "current": i, "load_torque": load, "acceleration": acc}
