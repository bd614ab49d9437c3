"""Exceptions raised by the transfer-matrix core.

Every error names the offending field and its value, so a user can find the bad input
without a traceback. All derive from ``ValueError`` so callers that only care about
"bad input" can catch one type.

Owns: the exception types: bad input versus hard problems. Boundaries: no logic.
"""
from __future__ import annotations

import numpy as np


class TMMError(ValueError):
    """Base class of all transfer-matrix core errors."""


class InputError(TMMError):
    """A parameter is missing, non-finite, or outside its physical range."""


class AssemblyError(TMMError):
    """A linkage cannot be assembled (or is at a toggle) at the requested crank angle."""


class SingularStructureError(TMMError):
    """The instantaneous structure has no unique static solution."""


class BucklingError(SingularStructureError):
    """A member carries a compressive force at or beyond its buckling load."""


class DynamicStabilityError(TMMError):
    """The dynamic system of a time step (stiffness with axial forces plus inertia) is not
    positive definite: the structure buckles even with its inertia."""


class ConvergenceError(TMMError):
    """An iteration (beam-column, large deflection) did not converge."""


def _fmt(value) -> str:
    arr = np.asarray(value)
    if arr.ndim == 0:
        return repr(float(arr)) if np.issubdtype(arr.dtype, np.number) else repr(value)
    bad = arr[~np.isfinite(arr)] if np.issubdtype(arr.dtype, np.number) else arr
    return f"array of shape {arr.shape} (e.g. {bad.flat[0] if bad.size else arr.flat[0]!r})"


def require_positive(name: str, value) -> np.ndarray:
    """Return ``value`` as a float array; raise :class:`InputError` unless every entry is finite and > 0."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise InputError(f"{name} must be positive and finite, got {_fmt(value)}")
    return arr


def require_finite(name: str, value) -> np.ndarray:
    """Return ``value`` as a float array; raise :class:`InputError` if any entry is NaN or infinite."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {_fmt(value)}")
    return arr


def require_nonnegative(name: str, value) -> np.ndarray:
    """Return ``value`` as a float array; raise :class:`InputError` unless every entry is finite and >= 0."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
        raise InputError(f"{name} must be non-negative and finite, got {_fmt(value)}")
    return arr
