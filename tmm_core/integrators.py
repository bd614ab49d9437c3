"""Implicit time integrators in the form the transfer-matrix time-domain analysis needs.

Each integrator writes the acceleration and velocity at the new time as
``a_{n+1} = c_a * d_{n+1} + h_a`` and ``v_{n+1} = c_v * d_{n+1} + h_v``, with scalars
``(c_a, c_v)`` fixed by the step and history vectors ``(h_a, h_v)`` from past states. A lumped
mass m then acts on the instantaneous structure as a spring ``m c_a`` to ground plus a load
``-m h_a`` (Shin's elastic-body inertial matrix, Eq. 3.47, is the Houbolt case with
``c_a = 2/dt^2``).

States are dictionaries of arrays shaped like the displacement vector.

Every integrator here is linear and acts on every degree of freedom alike: :func:`linear_maps`
reads it off as a few scalar coefficients per state array (what the compiled steps apply), and
:func:`numerical_frequency` gives the frequency and damping it gives an undamped oscillator (its
period error, which a lightly damped response near a resonance amplifies).

Owns: the implicit integrators' coefficients and updates, their linear maps and their numerical
frequency. Boundaries: no structure or loads.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_positive


@dataclass(frozen=True)
class Newmark:
    """Newmark average acceleration (beta = 1/4, gamma = 1/2): second order, no numerical damping."""

    name: str = "newmark"
    order: int = 2

    def coefficients(self, dt):
        return 4.0 / dt**2, 2.0 / dt

    def initial(self, d0, v0, a0, previous=None):
        return {"d": d0, "v": v0, "a": a0}

    def history(self, state, dt):
        d, v, a = state["d"], state["v"], state["a"]
        return -4.0 / dt**2 * d - 4.0 / dt * v - a, -2.0 / dt * d - v

    def advance(self, state, d_new, dt):
        h_a, h_v = self.history(state, dt)
        c_a, c_v = self.coefficients(dt)
        return {"d": d_new, "v": c_v * d_new + h_v, "a": c_a * d_new + h_a}


@dataclass(frozen=True)
class Houbolt:
    """Houbolt's four-point backward difference (Shin Eq. 3.41): second order, strong numerical
    damping of high frequencies. Needs the two displacements before the start; Shin starts from
    rest with all three equal to zero."""

    name: str = "houbolt"
    order: int = 2

    def coefficients(self, dt):
        return 2.0 / dt**2, 11.0 / (6.0 * dt)

    def initial(self, d0, v0, a0, previous=None):
        """``previous = (d_{-1}, d_{-2})``; without it the history is extrapolated from (d, v, a)."""
        if previous is None:
            raise InputError("Houbolt needs the displacements one and two steps before the start")
        d1, d2 = previous
        return {"d": d0, "d1": d1, "d2": d2, "v": v0, "a": a0}

    def history(self, state, dt):
        d, d1, d2 = state["d"], state["d1"], state["d2"]
        return (-5.0 * d + 4.0 * d1 - d2) / dt**2, (-18.0 * d + 9.0 * d1 - 2.0 * d2) / (6.0 * dt)

    def advance(self, state, d_new, dt):
        h_a, h_v = self.history(state, dt)
        c_a, c_v = self.coefficients(dt)
        return {"d": d_new, "d1": state["d"], "d2": state["d1"], "v": c_v * d_new + h_v, "a": c_a * d_new + h_a}


@dataclass(frozen=True)
class GeneralizedAlpha:
    """Generalized-alpha (Chung & Hulbert) in the Arnold & Bruls form: equilibrium holds exactly
    at t_{n+1} with the true acceleration, and an auxiliary acceleration ``a`` carries the
    numerical dissipation. Second order; high frequencies are damped to the spectral radius
    ``rho_inf`` per step (1 gives average-acceleration Newmark, no dissipation).

    Why it is here: with a crank-angle-dependent instantaneous structure, average-acceleration
    Newmark maps stiff modes (axial modes, heavily damped or not) to the undamped eigenvalue -1,
    and the changing configuration pumps them: on the Alexander-Lawrence four-bar at 400 rpm a
    2 deg step grows 15x per revolution and 1 deg diverges after about 10 revolutions, even with
    1 % damping. A little numerical dissipation (rho_inf = 0.9, as exudyn uses) removes this.
    """

    rho_inf: float = 0.9
    name: str = "generalized_alpha"
    order: int = 2

    def __post_init__(self):
        if not (0.0 <= self.rho_inf <= 1.0):
            raise InputError(f"generalized-alpha rho_inf must lie in [0, 1], got {self.rho_inf!r}")

    @property
    def parameters(self):
        r = self.rho_inf
        am, af = (2 * r - 1) / (r + 1), r / (r + 1)
        g = 0.5 + af - am
        return am, af, g, 0.25 * (g + 0.5) ** 2

    def coefficients(self, dt):
        am, af, g, b = self.parameters
        return (1 - am) / ((1 - af) * b * dt**2), g / (b * dt)

    def initial(self, d0, v0, a0, previous=None):
        return {"d": d0, "v": v0, "a": a0, "acc": a0}

    def _predict(self, state, dt):
        """Parts of the auxiliary acceleration and velocity that do not depend on d_{n+1}."""
        am, af, g, b = self.parameters
        d, v, a = state["d"], state["v"], state["a"]
        a_hist = (-d - dt * v - dt**2 * (0.5 - b) * a) / (b * dt**2)     # a_{n+1} = d_{n+1}/(b dt^2) + a_hist
        return a_hist, v + dt * (1 - g) * a + dt * g * a_hist

    def history(self, state, dt):
        am, af, g, b = self.parameters
        a_hist, h_v = self._predict(state, dt)
        h_a = ((1 - am) * a_hist + am * state["a"] - af * state["acc"]) / (1 - af)
        return h_a, h_v

    def advance(self, state, d_new, dt):
        am, af, g, b = self.parameters
        a_hist, h_v = self._predict(state, dt)
        a_new = d_new / (b * dt**2) + a_hist
        h_a = ((1 - am) * a_hist + am * state["a"] - af * state["acc"]) / (1 - af)
        c_a, c_v = self.coefficients(dt)
        return {"d": d_new, "v": c_v * d_new + h_v, "a": a_new, "acc": c_a * d_new + h_a}


INTEGRATORS = {"newmark": Newmark(), "houbolt": Houbolt(), "generalized_alpha": GeneralizedAlpha()}


def get_integrator(name):
    """An integrator by name ('newmark', 'houbolt', 'generalized_alpha'), or an integrator object."""
    if not isinstance(name, str):
        return name
    try:
        return INTEGRATORS[name]
    except KeyError:
        raise InputError(f"integrator must be one of {sorted(INTEGRATORS)}, got {name!r}") from None


def check_step(dt) -> float:
    return float(require_positive("time step dt_s", dt))


def linear_maps(integrator, dt: float):
    """The integrator as linear maps of its state arrays: ``(slots, Hc, Gc, ez)`` with the
    history ``h_a = sum_j Hc[0, j] x_j``, ``h_v = sum_j Hc[1, j] x_j`` and the update
    ``x_i' = ez[i] z + sum_j Gc[i, j] x_j`` for new displacements ``z``; ``slots`` names the
    state arrays (``integrator.initial``'s keys), ``dt`` [s]. The compiled steps apply them
    (:mod:`tmm_core.compiled.integrators`)."""
    one, zero = np.ones(1), np.zeros(1)
    slots = tuple(integrator.initial(zero, zero, zero, (zero, zero)).keys())

    def unit(j):
        return {s: (one if i == j else zero).copy() for i, s in enumerate(slots)}

    K = len(slots)
    Hc, Gc, ez = np.zeros((2, K)), np.zeros((K, K)), np.zeros(K)
    for j in range(K):
        h_a, h_v = integrator.history(unit(j), dt)
        Hc[0, j], Hc[1, j] = h_a[0], h_v[0]
        new = integrator.advance(unit(j), zero, dt)
        Gc[:, j] = [new[s][0] for s in slots]
    new = integrator.advance(unit(-1), one, dt)
    ez[:] = [new[s][0] for s in slots]
    return slots, Hc, Gc, ez


def numerical_frequency(integrator, omega_rad_s: float, dt: float) -> tuple[float, float]:
    """``(omega_num [rad/s], damping ratio)`` of an undamped oscillator of circular frequency
    ``omega_rad_s`` stepped by ``integrator`` at ``dt`` [s] as the time step steps a structure
    (unit mass, stiffness omega^2, the new acceleration ``c_a z + h_a``): from the principal
    (complex) eigenvalues ``exp((-xi + i) omega_num dt)`` of the step's amplification matrix. Its
    period error ``omega / omega_num - 1`` is second order in ``omega dt`` (Newmark's average
    acceleration: ``omega_num dt = 2 atan(omega dt / 2)``)."""
    _, Hc, Gc, ez = linear_maps(integrator, dt)
    c_a, _ = integrator.coefficients(dt)
    amplification = Gc - np.outer(ez, Hc[0]) / (c_a + omega_rad_s**2)
    eigenvalues = np.linalg.eigvals(amplification)
    # The principal pair is complex; the spurious roots (real, inside the unit circle) are not.
    pair = eigenvalues[np.abs(eigenvalues.imag) > 1e-12 * np.abs(eigenvalues)]
    if not len(pair):
        return 0.0, math.inf
    principal = pair[np.argmax(np.abs(pair))]
    phase = abs(float(np.angle(principal)))
    omega_num = phase / dt
    return omega_num, (-math.log(abs(principal)) / phase if phase > 0 else math.inf)
