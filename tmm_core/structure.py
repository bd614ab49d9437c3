"""Instantaneous planar structure: members chained by transfer matrices, joined at joints.

A *member* is a link between two joints, meshed into segments (nodes 0..n along local x).
Each member is condensed to its end nodes with the Riccati transfer of
:mod:`tmm_core.riccati`; the condensed members are joined at the joints, and the small joint
system is solved for the joint displacements. The member states at every node then follow by
back-substitution.

This replaces Shin's loop-closure elimination (carrying a 7x4 matrix around the loop and
eliminating one unknown at each moment release, Eqs. 5.1-5.18) by the equivalent joint
equilibrium: the same compatibility (common translation at a joint, a free slope jump at a
revolute) and the same boundary conditions (clamped input pivot, pinned output pivot), but
with unknowns that stay well scaled for any number of segments, and for any topology (loops,
branches) without special-case algebra.

Everything broadcasts over leading batch dimensions of the :class:`LoadCase` arrays (e.g. one
entry per crank position).

The data types are :mod:`tmm_core.structure_types` (re-exported here).

Owns: the instantaneous structure: factorize once, solve many. Boundaries: no mechanism
kinematics.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .buckling import buckling_message, clamped_clamped_buckling_count
from .errors import BucklingError, InputError, SingularStructureError, require_finite
from .matrices import F_IDX, field_matrix, frame_rotation, point_matrix, rigid_element_matrix
from .riccati import ChainFactor, chain_states, factor_chain, ldl_pivots, load_column, sweep_loads

from .structure_types import (CONNECTIONS, SUPPORTS, Joint, LinearSolution, LoadCase, Member,  # noqa: F401
                              MemberResult, RigidBody, SliderJoint, Spring, Structure, constrained_joints)


def _rotation_3(angle):
    """(..., 3, 3) map of global (X, Y, theta) to a member's local (u, w, theta): the displacement
    block of the frame rotation from the global frame (angle 0) to the member frame."""
    T = frame_rotation(-np.asarray(angle, dtype=float))
    return T[..., :3, :3]


def _rotation_6(angle):
    """(..., 6, 6) block-diagonal version of :func:`_rotation_3` for both member ends."""
    R = _rotation_3(angle)
    L = np.zeros(np.shape(angle) + (6, 6))
    L[..., :3, :3] = R
    L[..., 3:, 3:] = R
    return L


def _member_geometry(member: Member, case: LoadCase):
    try:
        a = require_finite(f"joint '{member.start}' position", case.joint_positions[member.start])
        b = require_finite(f"joint '{member.end}' position", case.joint_positions[member.end])
    except KeyError as exc:
        raise InputError(f"load case: no position for joint {exc.args[0]!r}") from None
    d = b - a
    dist = np.hypot(d[..., 0], d[..., 1])
    if np.any(np.abs(dist - member.length) > 1e-9 * max(member.length, 1.0) + 1e-12):
        bad = np.max(np.abs(dist - member.length))
        raise InputError(f"member '{member.name}': length {member.length:.9g} m does not match the distance "
                         f"between joints '{member.start}' and '{member.end}' (off by up to {bad:.3g} m)")
    return np.arctan2(d[..., 1], d[..., 0]), a


def _checked(mapping, member, field, shape_tail):
    arr = mapping.get(member.name)
    if arr is None:
        return None
    arr = require_finite(f"member '{member.name}': {field}", arr)
    if arr.shape[-len(shape_tail):] != shape_tail:
        raise InputError(f"member '{member.name}': {field} must have shape (..., {', '.join(map(str, shape_tail))}), "
                         f"got {arr.shape}")
    return arr


def _member_matrices(member: Member, case: LoadCase, angle, P, beta, batch, factor=1.0):
    """Point and field matrices of a member (node loads excluded), in chain order.
    ``factor`` ``(..., n)`` scales EA and EI of the segments (effective moduli)."""
    n = member.n_segments
    R3 = _rotation_3(angle)           # global -> local for (X, Y, theta)
    K = _checked(case.node_stiffness, member, "node_stiffness", (n + 1, 3, 3))
    if K is not None and case.frame == "global":
        K = np.einsum("...ij,...njk,...lk->...nil", R3, K, R3)
    q = _checked(case.distributed_loads, member, "distributed_loads", (n, 2))
    q_loc = (np.zeros(batch + (n, 2)) if q is None
             else np.einsum("...ij,...nj->...ni", R3[..., :2, :2], q))

    L = np.asarray(member.segment_lengths)
    rigid = member.is_rigid
    points = point_matrix(np.zeros(batch + (n + 1, 3)), K)
    fields = np.broadcast_to(field_matrix(L, member.EA * factor, member.EI * factor, P, q_loc[..., 1],
                                          q_loc[..., 0], beta), batch + (n, 7, 7))
    if rigid.any():
        fields = fields.copy()
        fields[..., rigid, :, :] = rigid_element_matrix(L[rigid], beta[..., rigid])
    mats, kinds = [], []
    point_kind = "load" if K is None else "point"
    for j in range(n + 1):
        mats.append(np.broadcast_to(points[..., j, :, :], batch + (7, 7)))
        kinds.append(point_kind)
        if j < n:
            mats.append(fields[..., j, :, :])
            kinds.append("rigid" if rigid[j] else "field")
    return mats, kinds


def _batch_shape(structure: Structure, case: LoadCase):
    shapes = [np.shape(v)[:-1] for v in case.joint_positions.values()]
    for mapping, trail in ((case.node_loads, 2), (case.distributed_loads, 2), (case.node_stiffness, 3)):
        shapes += [np.shape(v)[:-trail] for v in mapping.values()]
    return np.broadcast_shapes(*shapes)


def _dof_map(structure: Structure):
    """Global DOF numbering. Returns (index per member end (6,), fixed mask, dof labels)."""
    labels, index = [], {}

    def new(key):
        index[key] = len(labels)
        labels.append(key)
        return index[key]

    rigid_at = {j.name: False for j in structure.joints}
    for m in structure.members:
        if m.start_connection == "rigid":
            rigid_at[m.start] = True
        if m.end_connection == "rigid":
            rigid_at[m.end] = True
    for b in structure.rigid_bodies:
        rigid_at[b.master] = True
    for sl in structure.sliders:
        if not rigid_at[sl.guide]:
            raise InputError(f"slider '{sl.name}': the guide joint '{sl.guide}' has no rotation (connect the guide "
                             "link rigidly there)")
    fixed = []
    for j in structure.joints:
        new((j.name, "x"))
        new((j.name, "y"))
        fixed += [j.support in ("pinned", "clamped")] * 2
        if rigid_at[j.name] or j.support in ("clamped", "sliding_clamp"):
            new((j.name, "r"))
            fixed.append(j.support in ("clamped", "sliding_clamp"))
    ends = {}
    for m in structure.members:
        idx = []
        for joint, conn, tag in ((m.start, m.start_connection, "start"), (m.end, m.end_connection, "end")):
            if conn == "rigid":
                r = index[(joint, "r")]
            else:
                r = new((m.name, tag, "r"))
                fixed.append(False)
            idx += [index[(joint, "x")], index[(joint, "y")], r]
        ends[m.name] = np.array(idx)
    return ends, np.array(fixed, dtype=bool), labels


@dataclass(frozen=True)
class MemberFactor:
    """Factorized member: chain factorization, geometry and the load columns of its matrices."""

    chain: ChainFactor
    angle: np.ndarray
    origin: np.ndarray
    axial_force: np.ndarray
    chord_rotation: np.ndarray
    base_columns: tuple       # load columns of the field matrices (distributed loads, chord offsets)
    stiffness_factor: np.ndarray | float = 1.0


@dataclass(frozen=True)
class StructureFactor:
    """Load-independent factorization of an instantaneous structure (see :func:`factorize`)."""

    structure: Structure
    case: LoadCase
    batch: tuple
    members: Mapping[str, MemberFactor]
    stiffness: np.ndarray            # (..., nd, nd) assembled joint stiffness, all DOFs
    free_inverse: np.ndarray         # (..., nf, nf) inverse of the free-DOF block
    negative_eigenvalues: np.ndarray  # (...,) inertia count of the whole structure
    condition: np.ndarray            # (...,) scaled condition number of the free-DOF block
    ends: Mapping[str, np.ndarray] = field(repr=False, default=None)
    fixed: np.ndarray = field(repr=False, default=None)
    labels: tuple = field(repr=False, default=())
    constraint: np.ndarray | None = field(repr=False, default=None)   # (..., nd, nr): raw = T reduced
    spring_load: np.ndarray | None = field(repr=False, default=None)  # (..., nd) preload term of r
    spring_forces: Mapping[str, tuple] = field(repr=False, default=None)  # {spring: (preload, axis, dofs)}


def factorize(structure: Structure, case: LoadCase, axial_force: Mapping[str, np.ndarray] | None = None,
              chord_rotation: Mapping[str, np.ndarray] | None = None, check_buckling: bool = True,
              check_singular: bool = True, cond_limit: float = 1e12,
              stiffness_factor: Mapping[str, np.ndarray] | None = None,
              field_matrices: Mapping[str, np.ndarray] | None = None,
              count_inertia: bool | None = None) -> StructureFactor:
    """Factorize the instantaneous structure for the geometry, node stiffness and distributed
    loads of ``case`` (its ``node_loads`` are ignored here; pass them to :func:`solve_factored`).

    ``axial_force`` / ``chord_rotation``: ``{member: (..., n)}``, default 0 (linear theory).
    ``stiffness_factor``: ``{member: (..., n) or scalar}`` multiplies the segments' EA and EI
    (effective moduli of damping and viscoelasticity in the time domain), default 1.
    ``field_matrices``: ``{member: (..., n, 7, 7)}`` replaces the static field matrices (the
    frequency search passes distributed-mass dynamic field matrices); the caller then accounts
    for the segments' own clamped-clamped eigenvalues.
    ``count_inertia``: count the negative eigenvalues of the stiffness (Wittrick-Williams);
    default: when some segment is compressed and ``check_buckling`` is set.
    Raises :class:`SingularStructureError` if the joint system is singular (toggle, an
    unconstrained joint) and, if ``check_buckling``, :class:`BucklingError` when the stiffness
    has negative eigenvalues (a member at or beyond a buckling load, or a dynamic stiffness
    above a natural frequency).
    """
    axial_force = axial_force or {}
    chord_rotation = chord_rotation or {}
    stiffness_factor = stiffness_factor or {}
    batch = _batch_shape(structure, case)
    ends, fixed, labels = _dof_map(structure)
    nd = len(labels)
    Kfull = np.zeros(batch + (nd, nd))
    negative = np.zeros(batch, dtype=int)
    members = {}
    for m in structure.members:
        angle, origin = _member_geometry(m, case)
        angle = np.broadcast_to(angle, batch)
        origin = np.broadcast_to(origin, batch + (2,))
        P = np.broadcast_to(np.asarray(axial_force.get(m.name, 0.0), dtype=float), batch + (m.n_segments,))
        beta = np.broadcast_to(np.asarray(chord_rotation.get(m.name, 0.0), dtype=float), batch + (m.n_segments,))
        factor = np.asarray(stiffness_factor.get(m.name, 1.0), dtype=float)
        mats, kinds = _member_matrices(m, case, angle, P, beta, batch, factor)
        override = None if field_matrices is None else field_matrices.get(m.name)
        if override is not None:
            override = np.broadcast_to(override, batch + (m.n_segments, 7, 7))
            for j in range(m.n_segments):
                mats[2 * j + 1] = override[..., j, :, :]
        count = (check_buckling and bool(np.any(P < 0))) if count_inertia is None else count_inertia
        try:    # a Riccati block that cannot be inverted: no stiffness left, or non-finite axial forces
            chain = factor_chain(mats, kinds, count_inertia=count)
        except np.linalg.LinAlgError:
            raise SingularStructureError(f"member '{m.name}': its transfer-matrix chain is singular or not finite "
                                         "(far beyond its buckling load, or non-finite axial forces)") from None
        negative = negative + chain.negative_pivots
        if override is None:
            s = P * np.asarray(m.segment_lengths) ** 2 / (m.EI * factor)
            negative = negative + np.sum(np.where(m.is_rigid, 0, clamped_clamped_buckling_count(s)), -1)
        Lam = _rotation_6(angle)
        idx = ends[m.name]
        Kfull[..., idx[:, None], idx[None, :]] += np.swapaxes(Lam, -1, -2) @ chain.stiffness @ Lam
        members[m.name] = MemberFactor(chain, angle, origin, P, beta, tuple(load_column(T) for T in mats), factor)

    spring_load, spring_forces = _add_springs(structure, case, labels, Kfull, batch)
    T = _constraint_map(structure, case, labels, fixed, batch)
    free = ~fixed
    if T is None:
        nf = int(free.sum())
        Kff = Kfull[..., free[:, None] & free[None, :]].reshape(batch + (nf, nf))
    else:
        Kff = np.swapaxes(T, -1, -2) @ Kfull @ T
        free = np.ones(Kff.shape[-1], dtype=bool)
    # The stiffness is symmetric except for rotating-frame (Coriolis, angular-acceleration) node
    # terms; its symmetric part decides stability and the inertia count, the full matrix is solved.
    Ksym = 0.5 * (Kff + np.swapaxes(Kff, -1, -2))
    d = np.sqrt(np.abs(np.diagonal(Kff, axis1=-2, axis2=-1)))
    if check_singular and np.any(d == 0.0):
        reduced = [labels[i] for i in np.flatnonzero(~fixed)] if T is None else \
            [f"reduced DOF {i}" for i in range(Kff.shape[-1])]
        dead = [reduced[i] for i in np.flatnonzero(np.any(d == 0.0, axis=tuple(range(d.ndim - 1))))]
        raise SingularStructureError(f"instantaneous structure is singular: no stiffness at DOF(s) {dead}")
    dsafe = np.where(d > 0, d, 1.0)
    Ks = Ksym / dsafe[..., :, None] / dsafe[..., None, :]
    # Inertia and conditioning from LDL^T pivots (Wittrick-Williams; as tmm_core.compiled.structure).
    piv = ldl_pivots(Ks)
    pmax = np.max(np.abs(piv), axis=-1)
    pmin = np.min(np.abs(piv), axis=-1)
    with np.errstate(divide="ignore"):
        condition = np.where(pmin > 0, pmax / pmin, np.inf)
    negative = negative + np.sum(piv < 0, axis=-1)
    if check_singular and np.any(~(condition < cond_limit)):
        worst = np.unravel_index(np.argmax(condition), batch) if batch else ()
        raise SingularStructureError(
            f"instantaneous structure is singular (scaled condition number {float(np.max(condition)):.3g}"
            f"{' at batch index ' + str(tuple(int(i) for i in worst)) if batch else ''}): a toggle position "
            "(collinear links at a revolute), an unconstrained joint, a member at its buckling load, or a "
            "speed at a natural frequency")
    if check_buckling and np.any(negative > 0):
        raise BucklingError(buckling_message(structure, {k: r.axial_force for k, r in members.items()}, negative))
    inverse = np.linalg.inv(Kff) if check_singular else np.full_like(Kff, np.nan)
    return StructureFactor(structure, case, batch, members, Kfull, inverse, negative, condition, ends, fixed,
                           tuple(labels), T, spring_load, spring_forces)


def _joint_positions(case: LoadCase, name: str):
    try:
        return np.asarray(case.joint_positions[name], dtype=float)
    except KeyError:
        raise InputError(f"load case: no position for joint {name!r}") from None


def _add_springs(structure: Structure, case: LoadCase, labels, Kfull, batch):
    """Spring stiffness k e e^T into ``Kfull`` (in place) and the preload term of the load vector."""
    if not structure.springs:
        return None, {}
    index = {lab: i for i, lab in enumerate(labels)}
    load = np.zeros(batch + (len(labels),))
    forces = {}
    for sp in structure.springs:
        d = _joint_positions(case, sp.b) - _joint_positions(case, sp.a)
        L = np.hypot(d[..., 0], d[..., 1])
        if np.any(L <= 0):
            raise InputError(f"spring '{sp.name}': joints '{sp.a}' and '{sp.b}' coincide")
        e = np.broadcast_to(d / L[..., None], batch + (2,))
        Ks = sp.k * e[..., :, None] * e[..., None, :]
        ia = [index[(sp.a, "x")], index[(sp.a, "y")]]
        ib = [index[(sp.b, "x")], index[(sp.b, "y")]]
        for i, j, sign in ((ia, ia, 1.0), (ib, ib, 1.0), (ia, ib, -1.0), (ib, ia, -1.0)):
            Kfull[..., np.ix_(i, j)[0], np.ix_(i, j)[1]] += sign * Ks
        preload = np.broadcast_to(sp.k * (L - sp.free_length), batch)
        # A stretched spring pulls a towards b: the load on a is +F e, so its term in r is -F e.
        load[..., ia] -= preload[..., None] * e
        load[..., ib] += preload[..., None] * e
        forces[sp.name] = (preload, e, np.array(ia + ib))
    return load, forces


def _constraint_map(structure: Structure, case: LoadCase, labels, fixed, batch):
    """``T (..., nd, nr)`` with raw DOFs = T @ reduced DOFs, for slider supports, rigid bodies
    and slider joints; None when the reduced DOFs are just the free raw DOFs."""
    sliding = [j for j in structure.joints if j.support in ("slider", "sliding_clamp")]
    if not (sliding or structure.rigid_bodies or structure.sliders):
        return None
    index = {lab: i for i, lab in enumerate(labels)}
    nd = len(labels)
    dependent = set()
    for j in sliding:
        dependent |= {index[(j.name, "x")], index[(j.name, "y")]}
    for b in structure.rigid_bodies:
        for sl in b.slaves:
            dependent |= {index[(sl, c)] for c in ("x", "y")}     # a vertex's own rotation stays free
    for sl in structure.sliders:
        dependent |= {index[(sl.block, c)] for c in ("x", "y", "r") if (sl.block, c) in index}
    independent = [i for i in range(nd) if not fixed[i] and i not in dependent]
    n_slide = len(sliding) + len(structure.sliders)
    nr = len(independent) + n_slide
    col = {i: k for k, i in enumerate(independent)}
    T = np.zeros(batch + (nd, nr))
    for i, k in col.items():
        T[..., i, k] = 1.0
    k = len(independent)
    for j in sliding:
        T[..., index[(j.name, "x")], k] = math.cos(j.direction)
        T[..., index[(j.name, "y")], k] = math.sin(j.direction)
        k += 1

    def follow(slave, master, rotation: bool):
        """Slave translation (and, for slider blocks, rotation) follow the master's DOFs."""
        for c in ("x", "y"):
            T[..., index[(slave, c)], col[index[(master, c)]]] = 1.0
        if (slave, "r") in index:
            if rotation:
                T[..., index[(slave, "r")], col[index[(master, "r")]]] = 1.0
            else:     # members rigidly joined at a plate vertex turn together, pinned to the plate
                T[..., index[(slave, "r")], col.setdefault(index[(slave, "r")], len(col))] = 1.0

    for b in structure.rigid_bodies:
        pm = _joint_positions(case, b.master)
        r = col[index[(b.master, "r")]]
        for sl in b.slaves:
            follow(sl, b.master, rotation=False)
            rel = np.broadcast_to(_joint_positions(case, sl) - pm, batch + (2,))
            T[..., index[(sl, "x")], r] = -rel[..., 1]      # d = d_m + theta x (r_s - r_m)
            T[..., index[(sl, "y")], r] = rel[..., 0]
    members = {m.name: m for m in structure.members}
    for sl in structure.sliders:
        m = members[sl.along]
        d = _joint_positions(case, m.end) - _joint_positions(case, m.start)
        e = np.broadcast_to(d / np.hypot(d[..., 0], d[..., 1])[..., None], batch + (2,))
        follow(sl.block, sl.guide, rotation=True)
        # A block away from its guide joint (a block moving along a guide link) rides the guide's
        # tangent there: the guide's rotation moves it through the lever block - guide.
        lever = np.broadcast_to(_joint_positions(case, sl.block) - _joint_positions(case, sl.guide), batch + (2,))
        r = col[index[(sl.guide, "r")]]
        T[..., index[(sl.block, "x")], r] -= lever[..., 1]
        T[..., index[(sl.block, "y")], r] += lever[..., 0]
        T[..., index[(sl.block, "x")], k] = e[..., 0]
        T[..., index[(sl.block, "y")], k] = e[..., 1]
        k += 1
    return T


def solve_factored(factor: StructureFactor, node_loads: Mapping[str, np.ndarray] | None = None,
                   frame: str = "global") -> "LinearSolution":
    """Solve a factorized structure for nodal loads ``{member: (..., n+1, 3)}`` (Fx, Fy, Mz) in
    the global frame, or (F_u, F_w, M) in each member's local frame with ``frame='local'``."""
    if frame not in ("global", "local"):
        raise InputError(f"frame must be 'global' or 'local', got {frame!r}")
    node_loads = node_loads or {}
    structure = factor.structure
    # Loads may carry extra batch entries that broadcast against the factor's batch (influence maps).
    batch = np.broadcast_shapes(factor.batch, *(np.shape(v)[:-2] for v in node_loads.values()))
    nd = len(factor.labels)
    free = ~factor.fixed
    rfull = np.zeros(batch + (nd,))
    sweeps = {}
    for m in structure.members:
        mf = factor.members[m.name]
        loads = _checked(node_loads, m, "node_loads", (m.n_segments + 1, 3))
        columns = list(mf.base_columns)
        if loads is not None:
            if frame == "global":
                loads = np.einsum("...ij,...nj->...ni", _rotation_3(mf.angle), loads)
            for j in range(m.n_segments + 1):
                col = np.zeros(np.broadcast_shapes(np.shape(columns[2 * j]), loads.shape[:-2] + (6,)))
                col[...] = columns[2 * j]
                col[..., F_IDX] -= loads[..., j, :]
                columns[2 * j] = col
        sw = sweep_loads(mf.chain, columns)
        sweeps[m.name] = sw
        rfull[..., factor.ends[m.name]] += np.einsum("...ji,...j->...i", _rotation_6(mf.angle), sw.load)

    if factor.spring_load is not None:
        rfull = rfull + factor.spring_load
    if factor.constraint is None:
        q = np.zeros(batch + (nd,))
        q[..., free] = -np.einsum("...ij,...j->...i", factor.free_inverse, rfull[..., free])
    else:
        T = factor.constraint
        qr = -np.einsum("...ij,...j->...i", factor.free_inverse, np.einsum("...ji,...j->...i", T, rfull))
        q = np.einsum("...ij,...j->...i", T, qr)
    reaction_full = np.einsum("...ij,...j->...i", factor.stiffness, q) + rfull

    members = {}
    for m in structure.members:
        mf = factor.members[m.name]
        zl = np.einsum("...ij,...j->...i", _rotation_6(mf.angle), q[..., factor.ends[m.name]])
        S = chain_states(mf.chain, sweeps[m.name], zl[..., :3], zl[..., 3:])
        state = S.reshape(S.shape[:-2] + (m.n_segments + 1, 2, 6))
        members[m.name] = MemberResult(m, mf.angle, mf.origin, state, mf.axial_force, mf.chord_rotation,
                                       mf.stiffness_factor)

    index = {lab: i for i, lab in enumerate(factor.labels)}
    reactions = support_reactions(structure, factor.labels, reaction_full)
    joint_disp = {j.name: np.stack([q[..., index[(j.name, "x")]], q[..., index[(j.name, "y")]]], -1)
                  for j in structure.joints}
    springs = {}
    for name, (preload, e, dofs) in (factor.spring_forces or {}).items():
        rel = q[..., dofs[2:]] - q[..., dofs[:2]]
        springs[name] = preload + structure.spring(name).k * np.sum(rel * e, -1)
    return LinearSolution(structure, factor.case, members, reactions, factor.negative_eigenvalues, joint_disp,
                          springs)


def support_reactions(structure, labels, reaction) -> dict:
    """``{supported joint: (..., 3)}``, the force x, y [N] and, at a clamp, the moment [N m] (else
    0) the supports apply, from the joint forces ``reaction (..., nd)`` of a solve whose DOFs are
    ``labels`` ((joint, "x" | "y" | "r"), as a factorization's; numpy and compiled paths)."""
    index = {lab: i for i, lab in enumerate(labels)}
    out = {}
    for j in structure.joints:
        if j.support == "free":
            continue
        r = np.zeros(reaction.shape[:-1] + (3,))
        r[..., 0] = reaction[..., index[(j.name, "x")]]
        r[..., 1] = reaction[..., index[(j.name, "y")]]
        if j.support in ("clamped", "sliding_clamp"):
            r[..., 2] = reaction[..., index[(j.name, "r")]]
        out[j.name] = r
    return out


def solve_linear(structure: Structure, case: LoadCase, axial_force: Mapping[str, np.ndarray] | None = None,
                 chord_rotation: Mapping[str, np.ndarray] | None = None, check_buckling: bool = True,
                 cond_limit: float = 1e12, stiffness_factor: Mapping[str, np.ndarray] | None = None,
                 count_inertia: bool | None = None) -> "LinearSolution":
    """Solve the instantaneous structure once: :func:`factorize` then :func:`solve_factored`."""
    factor = factorize(structure, case, axial_force, chord_rotation, check_buckling, True, cond_limit,
                       stiffness_factor, count_inertia=count_inertia)
    return solve_factored(factor, case.node_loads, frame=case.frame)
