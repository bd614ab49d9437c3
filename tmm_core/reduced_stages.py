"""The reduced model's matrices at the stage points of a revolution, and their speed-free parts.

:class:`tmm_core.reduced_periodic.ReducedModel` needs, at every stage point of its Radau IIA
steps, the basis ``T`` and its rates, the reduced mass, damping and stiffness ``Mr, Cr, Kr``,
the rigid-body loads and the link rates (symbols as in :mod:`tmm_core.reduced_periodic`).
:func:`stage_terms` builds them for one crank history.

The linkage has one degree of freedom, so at a stage point every rate is the crank speed ``w`` or
acceleration ``al`` times an angle derivative: ``T' theta' = T1 w``, ``T'' theta'^2 + T'
theta'' = T2 w^2 + T1 al``, link ``omega = phi' w``, ``alpha = phi'' w^2 + phi' al``. Hence
``Mr`` depends on the angle only, ``Cr = C0 + w C1`` and ``Kr = K0 + w K1 + w^2 K2 + al K3``
with angle-only coefficients. :class:`StageCoefficients` keeps them for one set of stage angles
(four evaluations of :func:`stage_terms`: (w, al) = (0, 0), (1, 0), (-1, 0), (0, 1)), and
:meth:`StageCoefficients.at` combines them for a speed in a few array operations. A sweep at a
fixed number of steps per revolution has the same stage angles at every speed: its points then
skip the 0.1 s of matrix products per speed (FE rig, r = 23, 1080 stage points). The combination
equals the direct build to round-off (``tests/test_reduced.py``).

Owns: the stage matrices and their speed-free coefficients. Boundaries: the equations and their
propagation are tmm_core.reduced_periodic, the basis tmm_core.reduced.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .discretization import Discretization, HoldsModel, as_model
from .ked import rigid_body_loads


class StageTerms(NamedTuple):
    """The reduced equations' data at ``P`` stage points: basis ``T`` and its time rates ``Td``,
    ``Tdd`` (P, n, r); ``Mr, Cr, Kr`` (P, r, r); rigid-body loads ``f`` (P, n) [N, N m] in the link
    frames; link angular velocity and acceleration per DOF ``om, alpha`` (P, n) [rad/s, rad/s^2]
    (None without rotating-frame coupling); the drive torque per unit node load ``torque_map``
    (P, n) and the rigid crank's own part ``torque_offset`` (P,) [N m]; the gauges' bending and
    axial strain per unit coordinate ``strains`` (P, n_g, 2, r) (linear theory)."""

    T: np.ndarray
    Td: np.ndarray
    Tdd: np.ndarray
    Mr: np.ndarray
    Cr: np.ndarray
    Kr: np.ndarray
    f: np.ndarray
    om: np.ndarray | None
    alpha: np.ndarray | None
    torque_map: np.ndarray
    torque_offset: np.ndarray
    strains: np.ndarray


def stage_terms(model: Discretization, basis, th, w, al) -> StageTerms:
    """:class:`StageTerms` of the model ``model`` on ``basis`` at the stage
    angles ``th`` [rad] with crank speed ``w`` [rad/s] and acceleration ``al`` [rad/s^2] (arrays
    like ``th``, or scalars)."""
    b = basis
    th = np.asarray(th, dtype=float)
    w = np.broadcast_to(np.asarray(w, dtype=float), th.shape)
    al = np.broadcast_to(np.asarray(al, dtype=float), th.shape)
    x = b.angles[0] + np.mod(th - b.angles[0], 2 * np.pi)
    B = b.weights(x)                            # the basis' periodic splines at the stage points
    on_grid = lambda W, data: (W @ data.reshape(len(data), -1)).reshape(len(x), *data.shape[1:])  # noqa: E731
    T, T1, T2 = (on_grid(W, b.T) for W in B)
    Td = T1 * w[:, None, None]
    Tdd = T2 * (w**2)[:, None, None] + T1 * al[:, None, None]
    m = model.m_vec
    mech = model.mech
    motion = mech.motion(th, w, al)
    cp = model.coupling
    P = len(th)

    def per_dof(name):
        """A link rate of ``motion`` (per stage point) on every DOF of the link, (P, n)."""
        return np.concatenate([np.broadcast_to(np.reshape(getattr(motion.link(l.name), name), (-1, 1)),
                                               (P, 3 * l.n_nodes)) for l in model.links], axis=1)

    om = per_dof("omega") if cp.any else None
    alpha = per_dof("alpha") if cp.any else None
    Kl = model.K_local.toarray()
    # Batched matrix products (BLAS per stage point): einsum over (P, n, r) was 20x slower.
    TT = np.swapaxes(T, 1, 2)
    bn = model.beta_node
    iu = np.arange(0, model.n_dof, 3)

    def damp(X, p_om):
        """(D + C_K + G_c) X for X (P, n, r)."""
        out = (m * model.aM_vec)[None, :, None] * X + bn[None, :, None] * np.matmul(Kl, X)
        if cp.coriolis:
            c = 2.0 * m[None, :] * p_om
            out[:, iu] -= c[:, iu, None] * X[:, iu + 1]
            out[:, iu + 1] += c[:, iu + 1, None] * X[:, iu]
        return out

    Mr = TT @ (m[:, None] * T)
    Cr = TT @ (2.0 * m[None, :, None] * Td + damp(T, om))
    KX = m[None, :, None] * Tdd + damp(Td, om)
    if cp.centrifugal:
        KX = KX - (m[None, :] * om**2)[:, :, None] * T
    if cp.angular_acceleration:
        c = m[None, :] * alpha
        KX[:, iu] -= c[:, iu, None] * T[:, iu + 1]
        KX[:, iu + 1] += c[:, iu + 1, None] * T[:, iu]
    Kr = on_grid(B[0], b.K) + TT @ KX
    f, offset = _loads(model, motion)
    offset = np.broadcast_to(np.asarray(offset, dtype=float), th.shape)
    return StageTerms(T, Td, Tdd, Mr, Cr, Kr, f, om, alpha, B[0] @ b.torque, offset,
                      on_grid(B[0], b.strain_per_coordinate))


def _loads(model: Discretization, motion):
    """Rigid-body loads (P, n) in the link frames and the rigid crank's drive torque (P,)."""
    f = model.stack(rigid_body_loads(model.mech, motion, model.gravity, frame="local"))
    _, _, offset = model.mech.drive_torque_terms(motion, model.gravity)
    return f, offset


@dataclass(frozen=True, eq=False)
class StageCoefficients:
    """The speed-free parts of :class:`StageTerms` at the stage ``angle`` [rad] (see the module
    docstring): ``T``, ``T1``, ``T2``; ``Mr``; ``C0, C1``; ``K0, K1, K2, K3``; the link rates per
    unit speed ``om1`` (phi'), ``alpha2`` (phi'') and per unit acceleration ``alpha1`` (phi'), None
    without rotating-frame coupling; ``torque_map``; ``strains``."""

    angle: np.ndarray
    T: np.ndarray
    T1: np.ndarray
    T2: np.ndarray
    Mr: np.ndarray
    C0: np.ndarray
    C1: np.ndarray
    K0: np.ndarray
    K1: np.ndarray
    K2: np.ndarray
    K3: np.ndarray
    om1: np.ndarray | None
    alpha2: np.ndarray | None
    alpha1: np.ndarray | None
    torque_map: np.ndarray
    strains: np.ndarray

    @classmethod
    def of(cls, source: Discretization | HoldsModel, basis, th) -> "StageCoefficients":
        """Coefficients of the model ``source`` (or of the one a :class:`tmm_core.TimeDomain`
        holds) on ``basis`` at the stage angles ``th`` [rad]."""
        th = np.array(th, dtype=float)
        model = as_model(source)
        rest, fwd, back, acc = (stage_terms(model, basis, th, w, al) for w, al in ((0, 0), (1, 0), (-1, 0), (0, 1)))
        # The speed-free part is subtracted before the odd and even parts are separated.
        up, down = fwd.Kr - rest.Kr, back.Kr - rest.Kr          # K1 + K2, -K1 + K2
        return cls(th, rest.T, fwd.Td, fwd.Tdd, rest.Mr, rest.Cr, fwd.Cr - rest.Cr, rest.Kr, 0.5 * (up - down),
                   0.5 * (up + down), acc.Kr - rest.Kr, fwd.om, fwd.alpha, acc.alpha, rest.torque_map, rest.strains)

    def matches(self, th) -> bool:
        """Whether the stage angles ``th`` are these (to 1e-12 rad: at a fixed step count per
        revolution they differ between speeds by round-off only)."""
        th = np.asarray(th, dtype=float)
        return th.shape == self.angle.shape and bool(np.all(np.abs(th - self.angle) <= 1e-12))

    def at(self, model: Discretization, th, w, al) -> StageTerms:
        """:class:`StageTerms` of ``model`` at crank speed ``w`` and acceleration ``al`` per stage point; the
        rigid-body loads and the crank's drive torque are evaluated at the motion itself."""
        w = np.broadcast_to(np.asarray(w, dtype=float), self.angle.shape)
        al = np.broadcast_to(np.asarray(al, dtype=float), self.angle.shape)
        col = lambda x: x[:, None, None]  # noqa: E731
        Td = self.T1 * col(w)
        Tdd = self.T2 * col(w**2) + self.T1 * col(al)
        Cr = self.C0 + col(w) * self.C1
        Kr = self.K0 + col(w) * self.K1 + col(w**2) * self.K2 + col(al) * self.K3
        om = None if self.om1 is None else self.om1 * w[:, None]
        alpha = None if self.alpha2 is None else self.alpha2 * (w**2)[:, None] + self.alpha1 * al[:, None]
        f, offset = _loads(model, model.mech.motion(np.asarray(th, dtype=float), w, al))
        return StageTerms(self.T, Td, Tdd, self.Mr, Cr, Kr, f, om, alpha, self.torque_map,
                          np.broadcast_to(np.asarray(offset, dtype=float), self.angle.shape), self.strains)
