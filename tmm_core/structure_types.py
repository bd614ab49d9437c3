"""The data of an instantaneous planar structure: joints, springs, rigid bodies, slider joints,
members, the structure, its load case and its solution (frozen dataclasses, SI units; arrays
broadcast over leading batch dimensions).

Owns: the structure's data types and their checks. Boundaries: no factorization or solving
(:mod:`tmm_core.structure`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .errors import InputError, require_finite, require_positive
from .sections import Material, Section


SUPPORTS = ("free", "pinned", "clamped", "slider", "sliding_clamp")
CONNECTIONS = ("pin", "rigid")


@dataclass(frozen=True)
class Joint:
    """A joint. ``support``: 'free'; 'pinned' (translation fixed); 'clamped' (all fixed);
    'slider' (translation free only along ``direction``, rotation free: a pinned slider block);
    'sliding_clamp' (as 'slider' with the rotation fixed). ``direction`` [rad] from global X."""

    name: str
    support: str = "free"
    direction: float = 0.0

    def __post_init__(self):
        if self.support not in SUPPORTS:
            raise InputError(f"joint '{self.name}': support must be one of {SUPPORTS}, got {self.support!r}")
        require_finite(f"joint '{self.name}': direction", self.direction)


@dataclass(frozen=True)
class Spring:
    """A translational spring between joints ``a`` and ``b`` (a ground anchor is a pinned joint):
    stiffness ``k`` [N/m], free length [m]. Its force acts along the rigid-body axis a-b: the
    preload k (L - free_length) from the configuration plus k times the relative elastic
    displacement along the axis (Shin §3.3.4.3, Eqs. 3.23-3.26; small deflection: the axis does
    not turn)."""

    name: str
    a: str
    b: str
    k: float
    free_length: float

    def __post_init__(self):
        require_positive(f"spring '{self.name}': k", self.k)
        require_finite(f"spring '{self.name}': free_length", self.free_length)
        if self.a == self.b:
            raise InputError(f"spring '{self.name}': both ends are joint '{self.a}'")


@dataclass(frozen=True)
class RigidBody:
    """A rigid plate: the ``slaves`` joints (its vertices) translate with the ``master`` joint (its
    centroid) by the small-rotation kinematics d_s = d_m + theta_m k x (r_s - r_m). Members meet
    the plate at its vertices through revolutes (members rigidly connected at a vertex turn
    together, not with the plate); a member welded to the plate connects rigidly to the master.
    Shin models plates as rigid elements from the centroid to the vertices; this constraint is the
    same rigid body without an infinite stiffness in the system."""

    name: str
    master: str
    slaves: tuple

    def __post_init__(self):
        if not self.slaves:
            raise InputError(f"rigid body '{self.name}': needs at least one slave joint")
        if self.master in self.slaves:
            raise InputError(f"rigid body '{self.name}': master '{self.master}' is also a slave")


@dataclass(frozen=True)
class SliderJoint:
    """A block at joint ``block`` sliding along a link through joint ``guide``: the block's
    displacement equals the guide point's plus a free slide along the member ``along`` (its
    rigid-body axis), and the block turns with the guide (Shin's sliding joint, sub-loop cases 2
    and 4). The guide joint must carry a rotation (a member rigidly connected there). A block away
    from the guide joint (a block that has moved along a guide link, :mod:`tmm_core.linkage`) rides
    the guide's tangent at the guide joint: the guide's rotation moves it through the lever arm
    (the guide link's bending between the guide joint and the block is neglected)."""

    name: str
    block: str
    guide: str
    along: str


def constrained_joints(structure) -> set:
    """Joints whose displacement is given by a constraint (rigid-body slaves, slider blocks)."""
    out = set()
    for b in structure.rigid_bodies:
        out |= set(b.slaves)
    for s in structure.sliders:
        out.add(s.block)
    return out


@dataclass(frozen=True)
class Member:
    """A member (link) from joint ``start`` to joint ``end``, meshed into segments.

    ``segment_lengths`` [m] run from the start joint; ``sections`` and ``materials`` hold one
    entry per segment. ``start_connection`` / ``end_connection``: 'pin' (revolute: the member
    end rotates freely, its moment is zero) or 'rigid' (welded to the joint's rotation).
    ``rigid_segments`` marks segments treated as rigid elements (plates).
    """

    name: str
    start: str
    end: str
    segment_lengths: tuple
    sections: tuple
    materials: tuple
    start_connection: str = "pin"
    end_connection: str = "pin"
    rigid_segments: tuple = ()

    def __post_init__(self):
        n = len(self.segment_lengths)
        if n == 0:
            raise InputError(f"member '{self.name}': needs at least one segment")
        require_positive(f"member '{self.name}': segment_lengths", self.segment_lengths)
        if len(self.sections) != n or len(self.materials) != n:
            raise InputError(f"member '{self.name}': {n} segments but {len(self.sections)} sections "
                             f"and {len(self.materials)} materials")
        for conn, val in (("start_connection", self.start_connection), ("end_connection", self.end_connection)):
            if val not in CONNECTIONS:
                raise InputError(f"member '{self.name}': {conn} must be one of {CONNECTIONS}, got {val!r}")
        if self.start == self.end:
            raise InputError(f"member '{self.name}': start and end joint are both '{self.start}'")
        if self.rigid_segments and len(self.rigid_segments) != n:
            raise InputError(f"member '{self.name}': rigid_segments needs {n} flags")

    @classmethod
    def uniform(cls, name: str, start: str, end: str, length: float, n_segments: int,
                section: Section, material: Material, **kw) -> "Member":
        """A prismatic member of ``length`` [m] split into ``n_segments`` equal segments."""
        require_positive(f"member '{name}': length", length)
        if int(n_segments) != n_segments or n_segments < 1:
            raise InputError(f"member '{name}': n_segments must be a positive integer, got {n_segments!r}")
        n = int(n_segments)
        return cls(name, start, end, (length / n,) * n, (section,) * n, (material,) * n, **kw)

    @property
    def n_segments(self) -> int:
        return len(self.segment_lengths)

    @property
    def length(self) -> float:
        return float(np.sum(self.segment_lengths))

    @property
    def stations(self) -> np.ndarray:
        """Node coordinates along local x [m], shape (n+1,)."""
        return np.concatenate([[0.0], np.cumsum(self.segment_lengths)])

    @property
    def EA(self) -> np.ndarray:
        return np.array([m.E_Pa * s.area_m2 for s, m in zip(self.sections, self.materials)])

    @property
    def EI(self) -> np.ndarray:
        return np.array([m.E_Pa * s.inertia_m4 for s, m in zip(self.sections, self.materials)])

    @property
    def is_rigid(self) -> np.ndarray:
        return np.array(self.rigid_segments if self.rigid_segments else (False,) * self.n_segments, dtype=bool)


@dataclass(frozen=True)
class Structure:
    """Topology of an instantaneous structure: joints and members, plus optional springs,
    rigid bodies (plates) and slider joints."""

    joints: tuple
    members: tuple
    springs: tuple = ()
    rigid_bodies: tuple = ()
    sliders: tuple = ()

    def __post_init__(self):
        names = [j.name for j in self.joints]
        if len(set(names)) != len(names):
            raise InputError(f"structure: duplicate joint names in {names}")
        mnames = [m.name for m in self.members]
        if len(set(mnames)) != len(mnames):
            raise InputError(f"structure: duplicate member names in {mnames}")
        for m in self.members:
            for end in (m.start, m.end):
                if end not in names:
                    raise InputError(f"member '{m.name}': refers to unknown joint '{end}' (joints: {names})")
        for sp in self.springs:
            for end in (sp.a, sp.b):
                if end not in names:
                    raise InputError(f"spring '{sp.name}': refers to unknown joint '{end}' (joints: {names})")
        for b in self.rigid_bodies:
            for j in (b.master,) + tuple(b.slaves):
                if j not in names:
                    raise InputError(f"rigid body '{b.name}': refers to unknown joint '{j}' (joints: {names})")
        for sl in self.sliders:
            for j in (sl.block, sl.guide):
                if j not in names:
                    raise InputError(f"slider '{sl.name}': refers to unknown joint '{j}' (joints: {names})")
            if sl.along not in mnames:
                raise InputError(f"slider '{sl.name}': refers to unknown member '{sl.along}' (members: {mnames})")
        dependent = constrained_joints(self)
        for b in self.rigid_bodies:
            if b.master in dependent:
                raise InputError(f"rigid body '{b.name}': its master '{b.master}' is itself constrained")
        for sl in self.sliders:
            if sl.guide in dependent:
                raise InputError(f"slider '{sl.name}': its guide '{sl.guide}' is itself constrained")
        for j in self.joints:
            if j.name in dependent and j.support != "free":
                raise InputError(f"joint '{j.name}': a constrained joint cannot also be supported ({j.support})")
        used = ({m.start for m in self.members} | {m.end for m in self.members} | {sp.a for sp in self.springs} |
                {sp.b for sp in self.springs} | {b.master for b in self.rigid_bodies} | dependent)
        for j in self.joints:
            if j.name not in used:
                raise InputError(f"joint '{j.name}': nothing (member, spring, plate) is attached to it")

    def joint(self, name: str) -> Joint:
        return next(j for j in self.joints if j.name == name)

    def member(self, name: str) -> Member:
        for m in self.members:
            if m.name == name:
                return m
        raise InputError(f"structure: unknown member '{name}' (members: {[m.name for m in self.members]})")

    def spring(self, name: str) -> Spring:
        for sp in self.springs:
            if sp.name == name:
                return sp
        raise InputError(f"structure: unknown spring '{name}' (springs: {[sp.name for sp in self.springs]})")


@dataclass(frozen=True)
class LoadCase:
    """Configuration and loads of a structure, SI, batch-broadcast.

    joint_positions : ``{joint: (..., 2)}`` undeformed joint coordinates [m]; they fix each
        member's angle and must match its length.
    node_loads : ``{member: (..., n+1, 3)}`` external (Fx, Fy, Mz) at the member's nodes [N, N, N m].
    distributed_loads : ``{member: (..., n, 2)}`` (qx, qy) per unit undeformed length [N/m],
        always global components.
    node_stiffness : ``{member: (..., n+1, 3, 3)}`` stiffness to ground at the nodes, acting on
        (X, Y, theta) displacements [N/m, N m/rad]; a spring exerts ``-K d``. It need not be
        symmetric (Coriolis terms of the time-domain analysis).
    frame : 'global' (default) or 'local': the frame of ``node_loads`` and ``node_stiffness``;
        'local' means each member's own frame, (u, w, theta) and (F_u, F_w, M).
    """

    joint_positions: Mapping[str, np.ndarray]
    node_loads: Mapping[str, np.ndarray] = field(default_factory=dict)
    distributed_loads: Mapping[str, np.ndarray] = field(default_factory=dict)
    node_stiffness: Mapping[str, np.ndarray] = field(default_factory=dict)
    frame: str = "global"

    def __post_init__(self):
        if self.frame not in ("global", "local"):
            raise InputError(f"load case frame must be 'global' or 'local', got {self.frame!r}")


@dataclass(frozen=True)
class MemberResult:
    """States of one member. ``state`` has shape ``(..., n+1, 2, 6)``: node, [left, right] side,
    ``(u, w, theta, M, V, N)`` in the member's local frame (see :mod:`tmm_core.matrices`)."""

    member: Member
    angle: np.ndarray          # (...,) member angle from global X [rad]
    origin: np.ndarray         # (..., 2) undeformed start joint position [m]
    state: np.ndarray
    axial_force: np.ndarray    # (..., n) segment axial force used in the field matrices [N]
    chord_rotation: np.ndarray  # (..., n) segment chord rotation used [rad]
    stiffness_factor: np.ndarray | float = 1.0  # multiplier of EA and EI used (effective moduli)

    u = property(lambda self: self.state[..., 0, 0], doc="axial displacement [m], (..., n+1)")
    w = property(lambda self: self.state[..., 0, 1], doc="transverse displacement [m], (..., n+1)")
    theta = property(lambda self: self.state[..., 0, 2], doc="rotation [rad], (..., n+1)")
    M = property(lambda self: self.state[..., 3], doc="bending moment [N m], (..., n+1, 2) left/right")
    V = property(lambda self: self.state[..., 4], doc="transverse force [N], (..., n+1, 2) left/right")
    N = property(lambda self: self.state[..., 5], doc="axial force [N], (..., n+1, 2) left/right")

    @property
    def rotation(self) -> np.ndarray:
        """Rotation matrix local -> global, (..., 2, 2)."""
        c, s = np.cos(self.angle), np.sin(self.angle)
        return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)

    @property
    def node_positions(self) -> np.ndarray:
        """Undeformed (rigid-body) global node positions [m], (..., n+1, 2)."""
        x = self.member.stations
        e = np.stack([np.cos(self.angle), np.sin(self.angle)], -1)
        return self.origin[..., None, :] + x[:, None] * e[..., None, :]

    @property
    def displacement(self) -> np.ndarray:
        """Global elastic displacement (dX, dY) of the nodes [m], (..., n+1, 2)."""
        d = self.state[..., 0, :2]
        return np.einsum("...ij,...nj->...ni", self.rotation, d)

    @property
    def internal_force_global(self) -> np.ndarray:
        """Internal force (Fx, Fy) on the positive face, global components [N], (..., n+1, 2, 2)."""
        f = np.stack([self.N, self.V], -1)
        return np.einsum("...ij,...nsj->...nsi", self.rotation, f)


@dataclass(frozen=True)
class LinearSolution:
    """One linear solve of the instantaneous structure."""

    structure: Structure
    case: LoadCase
    members: Mapping[str, MemberResult]
    reactions: Mapping[str, np.ndarray]   # {joint: (..., 3)} force/moment applied by ground [N, N, N m]
    negative_eigenvalues: np.ndarray      # (...,) stiffness inertia count (0 when stable)
    joint_displacement: Mapping[str, np.ndarray]  # {joint: (..., 2)} global [m]
    spring_forces: Mapping[str, np.ndarray] = field(default_factory=dict)  # {spring: (...,)} tension [N]
