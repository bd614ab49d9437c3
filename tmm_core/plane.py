"""Plane vectors as arrays (..., 2): the small operations of closed-form planar kinematics.

Owns: plane-vector helpers. Boundaries: no kinematics of its own.
"""
from __future__ import annotations

import math

import numpy as np


def perp(v):
    return np.stack([-v[..., 1], v[..., 0]], -1)


def cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def dot(a, b):
    return np.sum(a * b, -1)


def rot(v, angle):
    c, s = np.cos(angle)[..., None], np.sin(angle)[..., None]
    return np.concatenate([c * v[..., :1] - s * v[..., 1:], s * v[..., :1] + c * v[..., 1:]], -1)


def angle(v):
    return np.arctan2(v[..., 1], v[..., 0])


def asin_deg(x) -> float:
    x = float(x)
    return math.degrees(math.asin(min(1.0, abs(x)))) if math.isfinite(x) else 0.0


def unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])
