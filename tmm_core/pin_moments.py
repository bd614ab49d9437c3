"""Applied moments at the pins of a four-bar: a torsional spring with a preload (gauge wires
bridging a joint) and a Coulomb friction torque, for the transfer-matrix model.

The FE thesis lists, among its causes of the mismatch with the measurement, "the gauge wires
acted as a torsional spring between coupler and output (a slow rotation gave measurable bending
strain)" and "friction moments in the journal bearings". Both are moments that two members
apply to each other at a pin. Here they are written from the *rigid-body* relative angle and
angular velocity of the two members at the pin, so they are known functions of the crank
position and enter the transfer-matrix model as applied loads through
:meth:`FourBarMechanism.external_loads` (added to the D'Alembert loads by
:func:`tmm_core.ked.rigid_body_loads`, in every engine path of the TMM: quasi-static, time
marching and the periodic solver)::

    M = moment + stiffness (phi - phi_ref) + friction tanh(omega_rel / omega_s)
    phi = angle(second member) - angle(first member),  omega_rel = d phi / dt

``+M`` acts on the first member's node at the pin and ``-M`` on the second member's (equal and
opposite: the pair is internal, the linkage's equilibrium is unchanged). Pins: ``"B"``
(crank-coupler: first = crank, second = coupler), ``"C"`` (coupler-rocker), ``"D"`` (ground-
rocker: the ground's share goes to the support). ``phi_ref`` is the mean of ``phi`` over a
revolution, so ``moment`` is the moment at the joint's mean angle (the preload) and
``stiffness`` the slope about it; ``omega_s`` smooths the friction's sign change (a fraction of
the crank speed, so the friction's shape does not depend on the speed).

The moment on a rigid crank (pin B) is carried to the drive torque. Only the transfer-matrix
model carries these moments: the exudyn and MuJoCo engines are never given this mechanism (the
bench builds it only for the fast TMM model of its bands and identification, cosim.unknowns).

Owns: moments at a four-bar's pins as TMM applied loads. Boundaries: no scenario parsing (the
bench declares them as unknowns), no I/O.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .mechanism import FourBarMechanism

JOINTS = {"B": ("crank", "coupler"), "C": ("coupler", "rocker"), "D": (None, "rocker")}
#: Friction smoothing: the tanh width as a fraction of the crank speed.
FRICTION_SMOOTHING = 0.02


@dataclass(frozen=True)
class JointMoment:
    """Moment law at one pin (see the module docstring): ``moment`` [N m] at the joint's mean
    angle, ``stiffness`` [N m/rad], Coulomb ``friction`` torque [N m]."""

    joint: str
    moment: float = 0.0
    stiffness: float = 0.0
    friction: float = 0.0

    def __post_init__(self):
        if self.joint not in JOINTS:
            raise InputError(f"joint moment: unknown joint {self.joint!r}; choose from {', '.join(JOINTS)} "
                             "(B crank-coupler, C coupler-rocker, D rocker pivot)")
        for name in ("moment", "stiffness", "friction"):
            if not np.isfinite(getattr(self, name)):
                raise InputError(f"joint moment at {self.joint}: {name} must be finite")
        if self.joint == "B" and self.stiffness:
            raise InputError("joint moment at B: no torsional spring between crank and coupler (their relative angle "
                             "turns a full revolution every turn; a spring there would wind up)")
        if self.friction < 0:
            raise InputError(f"joint moment at {self.joint}: friction must be >= 0 (a torque magnitude)")

    @property
    def active(self) -> bool:
        return bool(self.moment or self.stiffness or self.friction)


def _relative(mech, motion, joint):
    first, second = JOINTS[joint]
    s = motion.link(second)
    if first is None:
        return s.angle - mech.ground_angle, s.omega
    f = motion.link(first)
    return s.angle - f.angle, s.omega - f.omega


def mean_relative_angle(mech, joint: str, n: int = 720) -> float:
    """Mean over a revolution of the rigid-body relative angle at ``joint`` [rad] (unwrapped)."""
    mo = mech.motion(np.linspace(0.0, 2 * np.pi, n, endpoint=False), 1.0, 0.0)
    phi, _ = _relative(mech, mo, joint)
    return float(np.mean(np.unwrap(phi)))


@dataclass(frozen=True)
class JointLoadedFourBar(FourBarMechanism):
    """A :class:`FourBarMechanism` with :class:`JointMoment` laws at its pins (transfer-matrix
    model only). ``reference`` holds each joint's ``phi_ref``
    (:meth:`from_mechanism` computes it)."""

    joint_moments: tuple = ()
    reference: tuple = ()          # ((joint, phi_ref [rad]), ...)

    @classmethod
    def from_mechanism(cls, mech: FourBarMechanism, moments) -> "JointLoadedFourBar":
        if type(mech) is not FourBarMechanism and not isinstance(mech, JointLoadedFourBar):
            raise InputError(f"joint moments need a four-bar, got a {type(mech).__name__}")
        moments = tuple(m for m in moments if m.active)
        if len({m.joint for m in moments}) != len(moments):
            raise InputError("joint moments: at most one law per joint")
        reference = tuple((m.joint, mean_relative_angle(mech, m.joint)) for m in moments)
        return cls(mech.crank, mech.coupler, mech.rocker, mech.ground_m, mech.pivot, mech.ground_angle, mech.branch,
                   moments, reference)

    def _moments(self, motion):
        """``{joint: M}`` arrays over the positions of ``motion`` (+M on the first member)."""
        out = {}
        for law in self.joint_moments:
            phi, w = _relative(self, motion, law.joint)
            ref = dict(self.reference)[law.joint]
            dphi = np.mod(phi - ref + np.pi, 2 * np.pi) - np.pi
            M = law.moment + law.stiffness * dphi
            if law.friction:
                crank_w = np.abs(motion.crank.omega)
                scale = FRICTION_SMOOTHING * np.where(crank_w > 0, crank_w, 1.0)
                M = M + law.friction * np.tanh(w / scale)
            out[law.joint] = M
        return out

    def generalized_force(self, crank_angle, direction: float = 1.0):
        """Crank torque [N m] of the joint moments on the rigid linkage at ``crank_angle`` (array),
        turning in ``direction`` (+1 CCW): each pin's pair does the power ``-M dphi/dt``."""
        mo = self.motion(np.asarray(crank_angle, dtype=float), float(direction), 0.0)
        Q = np.zeros(np.shape(crank_angle))
        for joint, M in self._moments(mo).items():
            _, w = _relative(self, mo, joint)
            Q = Q - M * w / float(direction)
        return Q

    def external_loads(self, motion):
        loads = {}
        elastic = {link.name for link in self.elastic_links()}

        def add(link_name, node, M):
            if link_name not in elastic:
                return
            link = getattr(self, link_name)
            arr = loads.setdefault(link_name, np.zeros(np.shape(M) + (link.n_nodes, 3)))
            arr[..., node, 2] += M

        for joint, M in self._moments(motion).items():
            first, second = JOINTS[joint]
            # Node of each member at the pin: crank A->B (end), coupler B->C, rocker D->C.
            node = {("B", "crank"): -1, ("B", "coupler"): 0, ("C", "coupler"): -1, ("C", "rocker"): -1,
                    ("D", "rocker"): 0}
            if first is not None:
                add(first, node[(joint, first)], M)
            add(second, node[(joint, second)], -M)
        return loads

    def drive_torque_terms(self, motion, gravity=None):
        joint, arm, offset = super().drive_torque_terms(motion, gravity)
        if self.crank.rigid:
            # A moment on the rigid crank at B: the drive balances it as it balances the crank's
            # own D'Alembert loads (offset = - moment of the loads on the crank about A).
            M = self._moments(motion).get("B")
            if M is not None:
                offset = offset - M
        return joint, arm, offset
