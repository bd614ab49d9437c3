"""Typed data of the time step: a batch of instantaneous configurations, its load-to-response
maps, and the layout of a step's outputs.

A time step of :class:`tmm_core.TimeDomain` reads one configuration of a
:class:`ConfigurationBatch` (built by :func:`tmm_core.batches.configurations` for B crank
states) and returns an output row laid out by :class:`OutputLayout`: drive torque, then bending
and axial strain per gauge. Naming the parts here keeps the index arithmetic in one place.

Owns: the batch, its maps and the output layout. Boundaries: no solving; the factorization is
built by the callable the batch is given.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np


@dataclass(frozen=True)
class StepMaps:
    """Affine maps of B configurations from the stacked local node loads (n_dof: force [N] and
    moment [N m] per node, link frames) to the step's responses, ``response = M @ loads + m0``:

    ``Z`` (B, n_dof, n_dof), ``z0`` (B, n_dof): node displacements [m] and rotations [rad];
    ``O`` (B, n_out, n_dof), ``o0`` (B, n_out): the outputs (:class:`OutputLayout`);
    ``A`` (B, n_seg, n_dof), ``a0`` (B, n_seg): segment axial forces [N, tension +] (second-order
    step only, else None).

    Each map is stored augmented, ``Zx = [Z | z0]`` (B, n_dof, n_dof + 1), likewise ``Ox`` and
    ``Ax``; ``Z``, ``z0`` ... are views of them. The compiled factorization writes its solutions
    into ``Zx`` and ``Ax`` in place and the compiled march reads them so (one contiguous array a
    map: a revolution's maps are tens of MB, and a second copy of them cost more in first-touch
    page faults than the solves). The arrays are filled in chunks after construction."""

    Zx: np.ndarray
    Ox: np.ndarray
    Ax: np.ndarray | None = None

    @classmethod
    def empty(cls, batch: int, n_dof: int, n_out: int, n_seg: int | None = None) -> "StepMaps":
        """Uninitialised maps (``n_seg`` given: with the axial-force maps)."""
        return cls(np.empty((batch, n_dof, n_dof + 1)), np.empty((batch, n_out, n_dof + 1)),
                   None if n_seg is None else np.empty((batch, n_seg, n_dof + 1)))

    Z = property(lambda self: self.Zx[..., :-1])
    z0 = property(lambda self: self.Zx[..., -1])
    O = property(lambda self: self.Ox[..., :-1])
    o0 = property(lambda self: self.Ox[..., -1])
    A = property(lambda self: None if self.Ax is None else self.Ax[..., :-1])
    a0 = property(lambda self: None if self.Ax is None else self.Ax[..., -1])


@dataclass(frozen=True)
class StepFactors:
    """The map-free alternative to :class:`StepMaps` (:mod:`tmm_core.compiled.time_step`): the
    compiled factorization of each of B configurations, kept, on which a step solves its loads
    (memory and work linear in the segments; the maps are quadratic).

    ``layout``: ``(seg_off, rigid, angle (B, M) [rad], ends, free, gauge nodes)`` of the compiled
    structure; ``stored``: the arrays of :data:`tmm_core.compiled.time_step.STORED`, batch axis
    first; ``Ocx`` (B, n_out, ny + 1): the outputs (:class:`OutputLayout`) as an augmented affine
    map (as :class:`StepMaps`' maps), ``Ocx[k, :, :-1] @ y + Ocx[k, :, -1]`` with ``y`` the joint
    reactions [N, N m] and the gauge nodes' right-side states of a solve."""

    layout: tuple
    stored: tuple
    Ocx: np.ndarray


@dataclass(frozen=True)
class CrankStates:
    """Crank states of a batch: angle [rad], speed [rad/s], acceleration [rad/s^2], each (B,)."""

    angle: np.ndarray
    speed: np.ndarray
    accel: np.ndarray

    def at(self, k: int) -> tuple[float, float, float]:
        return float(self.angle[k]), float(self.speed[k]), float(self.accel[k])

    def take(self, k: int) -> "CrankStates":
        """Configuration ``k`` alone, as a batch of one."""
        return CrankStates(self.angle[k:k + 1], self.speed[k:k + 1], self.accel[k:k + 1])


@dataclass(frozen=True)
class ConfigurationBatch:
    """B instantaneous configurations of a :class:`tmm_core.TimeDomain` at a time step ``dt``.

    ``crank``: the crank states; ``motion``: the mechanism's rigid-body motion at them;
    ``rigid`` (B, n_dof): the rigid-body (D'Alembert and gravity) node loads, stacked local [N,
    N m]; ``drive``: the drive-torque terms (:meth:`FourBarMechanism.drive_torque_terms`);
    ``P0`` (B, n_seg) or None: the segment axial forces [N] in the field matrices;
    ``indefinite`` (B,): configurations whose step system is not positive definite at ``P0``;
    ``maps``: :class:`StepMaps` or None; ``factors``: :class:`StepFactors` or None (with neither
    the step runs Riccati load sweeps on the numpy factorization, built on first use by
    ``make_factor``). ``cache`` holds what is derived from
    the batch once (the factorization, selections of it, the compiled march's packed arrays)."""

    crank: CrankStates
    motion: Any
    rigid: np.ndarray
    drive: tuple
    P0: np.ndarray | None
    indefinite: np.ndarray
    maps: StepMaps | None
    make_factor: Callable[[], Any]
    factors: StepFactors | None = None
    cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __len__(self) -> int:
        return len(self.crank.angle)

    def factor(self):
        """The numpy factorization of the batch (built once, on first use)."""
        f = self.cache.get("factor")
        if f is None:
            f = self.cache["factor"] = self.make_factor()
        return f


@dataclass(frozen=True)
class OutputLayout:
    """Columns of a step's output row: drive torque [N m, CCW +], then per gauge (in order)
    bending and axial surface strain [-]."""

    gauges: tuple[str, ...]

    @property
    def size(self) -> int:
        return 1 + 2 * len(self.gauges)

    @staticmethod
    def torque(outs: np.ndarray) -> np.ndarray:
        return outs[..., 0]

    def bending(self, outs: np.ndarray, i: int) -> np.ndarray:
        return outs[..., 1 + 2 * i]

    def axial(self, outs: np.ndarray, i: int) -> np.ndarray:
        return outs[..., 2 + 2 * i]

    #: The axial-strain columns of every gauge (an index for a row).
    axial_columns = slice(2, None, 2)
    #: The bending-strain columns of every gauge (an index for a row).
    bending_columns = slice(1, None, 2)

    def split(self, outs: np.ndarray) -> dict:
        """``{gauge: (bending, axial)}`` of output rows ``(..., size)``."""
        return {name: (self.bending(outs, i), self.axial(outs, i)) for i, name in enumerate(self.gauges)}

    @classmethod
    def of(cls, gauges: Sequence) -> "OutputLayout":
        return cls(tuple(g.name for g in gauges))
