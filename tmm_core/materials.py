"""Dissipative material models for the time-domain analysis: damping and a standard linear solid.

Both act on the *elastic* deformation of a link in its moving frame, never on the rigid-body
motion.

Owns: damping and viscoelastic material models. Boundaries: no structure.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError, require_nonnegative, require_positive


@dataclass(frozen=True)
class Damping:
    """Rayleigh damping of one link: ``C = mass_per_s * M + stiffness_s * K``.

    ``stiffness_s`` [s] is Kelvin-Voigt (material) damping, ``sigma = E (eps + stiffness_s * eps_dot)``,
    the same form as exudyn's beam ``bendingDamping = stiffness_s * EI`` and
    ``axialDamping = stiffness_s * EA``. ``mass_per_s`` [1/s] acts on the elastic velocities of
    the lumped masses. The modal damping ratio at circular frequency w is
    ``mass_per_s / (2 w) + stiffness_s * w / 2``.
    """

    stiffness_s: float = 0.0
    mass_per_s: float = 0.0

    def __post_init__(self):
        require_nonnegative("damping stiffness_s", self.stiffness_s)
        require_nonnegative("damping mass_per_s", self.mass_per_s)

    @classmethod
    def modal(cls, ratio: float, frequency_Hz: float) -> "Damping":
        """Stiffness-proportional damping with modal ratio ``ratio`` at ``frequency_Hz``."""
        require_nonnegative("damping ratio", ratio)
        require_positive("damping reference frequency_Hz", frequency_Hz)
        return cls(stiffness_s=2.0 * ratio / (2.0 * math.pi * frequency_Hz))

    def ratio_at(self, frequency_Hz):
        """Modal damping ratio at ``frequency_Hz``."""
        w = 2.0 * np.pi * np.asarray(frequency_Hz, dtype=float)
        return self.mass_per_s / (2.0 * w) + self.stiffness_s * w / 2.0

    @property
    def is_zero(self) -> bool:
        return self.stiffness_s == 0.0 and self.mass_per_s == 0.0


@dataclass(frozen=True)
class StandardLinearSolid:
    """Three-parameter viscoelastic solid (Zener), in Maxwell-arm form.

    ``sigma = E_inf * eps + q`` with ``q_dot + q / tau = (E_0 - E_inf) * eps_dot``: relaxation
    modulus ``E(t) = E_inf + (E_0 - E_inf) exp(-t/tau)``, instantaneous modulus ``E_0``, relaxed
    modulus ``E_inf``, relaxation time ``tau``. Equivalent to Wang's spring ``G1 = E_0`` in series
    with a Kelvin unit (Wang 1984): ``E_inf = G1 G2 / (G1 + G2)``, ``tau = eta / (G1 + G2)``.
    """

    instantaneous_modulus_Pa: float
    relaxed_modulus_Pa: float
    relaxation_time_s: float

    def __post_init__(self):
        require_positive("viscoelastic instantaneous_modulus_Pa", self.instantaneous_modulus_Pa)
        require_positive("viscoelastic relaxed_modulus_Pa", self.relaxed_modulus_Pa)
        require_positive("viscoelastic relaxation_time_s", self.relaxation_time_s)
        if self.relaxed_modulus_Pa >= self.instantaneous_modulus_Pa:
            raise InputError(f"viscoelastic relaxed_modulus_Pa ({self.relaxed_modulus_Pa!r}) must be below "
                             f"instantaneous_modulus_Pa ({self.instantaneous_modulus_Pa!r})")

    @property
    def maxwell_modulus_Pa(self) -> float:
        return self.instantaneous_modulus_Pa - self.relaxed_modulus_Pa

    @property
    def retardation_time_s(self) -> float:
        """Time constant of creep under constant stress: ``tau * E_0 / E_inf``."""
        return self.relaxation_time_s * self.instantaneous_modulus_Pa / self.relaxed_modulus_Pa

    def relaxation_modulus(self, t):
        return self.relaxed_modulus_Pa + self.maxwell_modulus_Pa * np.exp(-np.asarray(t, dtype=float) / self.relaxation_time_s)

    def creep_compliance(self, t):
        """Strain per unit stress under a stress step at t = 0 [1/Pa]."""
        t = np.asarray(t, dtype=float)
        J0, Jinf = 1.0 / self.instantaneous_modulus_Pa, 1.0 / self.relaxed_modulus_Pa
        return Jinf - (Jinf - J0) * np.exp(-t / self.retardation_time_s)

    def step_coefficients(self, dt: float):
        """``(decay, g)`` of the exact update for a strain linear in time over the step:
        ``q_{n+1} = decay * q_n + g * (E_0 - E_inf) * (eps_{n+1} - eps_n)``."""
        require_positive("time step", dt)
        decay = math.exp(-dt / self.relaxation_time_s)
        return decay, self.relaxation_time_s / dt * (1.0 - decay)

    def storage_loss(self, omega):
        """Storage and loss moduli at circular frequency ``omega`` [rad/s]."""
        wt = np.asarray(omega, dtype=float) * self.relaxation_time_s
        E1 = self.maxwell_modulus_Pa
        return self.relaxed_modulus_Pa + E1 * wt**2 / (1 + wt**2), E1 * wt / (1 + wt**2)
