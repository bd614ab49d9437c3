"""Python side of the compiled factorization (:mod:`tmm_core.compiled.structure`): which structures it
handles (:func:`supported`), their layout, the stacked arrays of a batch of configurations
(:func:`prepare`), the solve with its singularity and buckling checks (:func:`solve_prepared`) and
the compiled equivalents of :func:`tmm_core.structure.solve_linear` and
:func:`tmm_core.statics.solve_static` (see :mod:`tmm_core.compiled.structure` for the method and scope).

Owns: the Python side of the compiled factorization: layout, preparation, solves, the quasi-
static iteration. Boundaries: no numba code (tmm_core.compiled.structure); the numpy path
(tmm_core.structure) stays the reference.
"""
from __future__ import annotations

import concurrent.futures
import functools
import os
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from . import binding
from . import structure as structure_kernel, time_step as time_step_kernel
from ..buckling import buckling_message, clamped_clamped_buckling_count
from ..errors import BucklingError, ConvergenceError, InputError, SingularStructureError, require_finite
from .cache import numba_module
from ..matrices import frame_rotation
from ..statics import StaticSolution, change_scales, change_weights
from ..structure import LinearSolution, LoadCase, MemberResult, factorize, support_reactions


def supported(structure) -> bool:
    """Does the compiled path handle this structure (joints and members only, see
    :mod:`tmm_core.compiled.structure`)?"""
    if structure.springs or structure.rigid_bodies or structure.sliders:
        return False
    if any(j.support not in ("free", "pinned", "clamped") for j in structure.joints):
        return False
    return all(not m.is_rigid.all() for m in structure.members)


@dataclass(frozen=True)
class Layout:
    """Per-structure data of the compiled solve: segment and node offsets, segment properties,
    the joint DOFs (from :func:`tmm_core.structure.factorize` on one configuration)."""

    seg_off: np.ndarray
    node_off: np.ndarray
    L: np.ndarray
    EA: np.ndarray
    EI: np.ndarray
    rigid: np.ndarray
    ends: np.ndarray
    fixed: np.ndarray
    free: np.ndarray
    labels: tuple


_LAYOUTS: dict = {}


def layout(structure, joint_positions: Mapping[str, np.ndarray]) -> Layout:
    """The :class:`Layout` of a structure (cached per structure)."""
    try:
        return _LAYOUTS[structure]
    except (KeyError, TypeError):
        pass
    one = {k: np.asarray(v, dtype=float).reshape(-1, 2)[0] for k, v in joint_positions.items()}
    f = factorize(structure, LoadCase(one), check_buckling=False, check_singular=False, count_inertia=False)
    members = structure.members
    seg_off = np.cumsum([0] + [m.n_segments for m in members]).astype(np.int64)
    out = Layout(seg_off, seg_off + np.arange(len(members) + 1), np.concatenate([m.segment_lengths for m in members]),
                 np.concatenate([m.EA for m in members]), np.concatenate([m.EI for m in members]),
                 np.concatenate([m.is_rigid for m in members]),
                 np.array([f.ends[m.name] for m in members], dtype=np.int64), np.asarray(f.fixed),
                 np.flatnonzero(~np.asarray(f.fixed)).astype(np.int64), tuple(f.labels))
    try:
        if len(_LAYOUTS) > 32:
            _LAYOUTS.clear()
        _LAYOUTS[structure] = out
    except TypeError:
        pass
    return out


def _local_rotation(angle):
    """(..., 3, 3) global (X, Y, theta) -> member local (u, w, theta)."""
    return frame_rotation(-np.asarray(angle, dtype=float))[..., :3, :3]


def _to_local_stiffness(K, R3):
    """``R3 K R3^T`` for node stiffnesses ``K (B, n, 3, 3)`` and the rotations ``R3 (B, 1, 3, 3)``
    of :func:`_local_rotation` (about the out-of-plane axis: theta untouched), entry by entry on
    (B, n) arrays: numpy's stacked 3x3 matmuls cost 0.5 ms a member on a 360-position batch, a
    tenth of a quasi-static revolution."""
    c, s, k = R3[..., 0, 0], R3[..., 0, 1], K                # R3[:2, :2] = [[c, s], [-s, c]]
    out = np.empty(np.broadcast_shapes(K.shape, R3.shape))
    a, b, d, e = K[..., 0, 0], K[..., 0, 1], K[..., 1, 0], K[..., 1, 1]
    # [[c, s], [-s, c]] [[a, b], [d, e]] [[c, -s], [s, c]]
    ca_sd, cb_se, cd_sa, ce_sb = c * a + s * d, c * b + s * e, c * d - s * a, c * e - s * b
    out[..., 0, 0] = ca_sd * c + cb_se * s
    out[..., 0, 1] = cb_se * c - ca_sd * s
    out[..., 1, 0] = cd_sa * c + ce_sb * s
    out[..., 1, 1] = ce_sb * c - cd_sa * s
    out[..., 0, 2] = c * k[..., 0, 2] + s * k[..., 1, 2]
    out[..., 1, 2] = c * k[..., 1, 2] - s * k[..., 0, 2]
    out[..., 2, 0] = k[..., 2, 0] * c + k[..., 2, 1] * s
    out[..., 2, 1] = k[..., 2, 1] * c - k[..., 2, 0] * s
    out[..., 2, 2] = k[..., 2, 2]
    return out


@dataclass
class Prepared:
    """A structure and load case laid out for the compiled solve (everything but the axial
    forces, which change from one beam-column iteration to the next)."""

    structure: object
    case: object
    layout: Layout
    angle: np.ndarray          # (B, M)
    origin: dict               # {member: (B, 2)}
    factor: np.ndarray         # (B, S)
    factor_given: dict         # {member: bool}
    qloc: np.ndarray           # (B, S, 2)
    Kn: np.ndarray             # (B, Nn, 3, 3)
    Fn: np.ndarray             # (B, Nn, 3)


def prepare(structure, case, stiffness_factor: Mapping[str, np.ndarray] | None = None) -> Prepared:
    """Lay out a :func:`supported` structure and a one-dimensional batch of configurations
    (``case``, any frame) for the compiled solve: member angles, local node stiffness and loads."""
    stiffness_factor = stiffness_factor or {}
    members = structure.members
    jp = {k: np.asarray(v, dtype=float) for k, v in case.joint_positions.items()}
    shapes = [v.shape[:-1] for v in jp.values()]
    for mapping, trail in ((case.node_loads, 2), (case.distributed_loads, 2), (case.node_stiffness, 3)):
        shapes += [np.shape(v)[:-trail] for v in mapping.values()]
    full = np.broadcast_shapes(*shapes)
    if len(full) > 1:
        raise InputError(f"the compiled solve takes a one-dimensional batch of configurations, got {full}")
    batch = full if full else (1,)
    B = batch[0]
    lay = layout(structure, jp)
    S = int(lay.seg_off[-1])
    Nn = S + len(members)
    angle = np.empty((B, len(members)))
    origin = {}
    factor = np.empty((B, S))
    qloc = np.zeros((B, S, 2))
    Kn = np.zeros((B, Nn, 3, 3))
    Fn = np.zeros((B, Nn, 3))
    for i, m in enumerate(members):
        try:
            a0 = np.broadcast_to(require_finite(f"joint '{m.start}' position", jp[m.start]), batch + (2,))
            b0 = np.broadcast_to(require_finite(f"joint '{m.end}' position", jp[m.end]), batch + (2,))
        except KeyError as exc:
            raise InputError(f"load case: no position for joint {exc.args[0]!r}") from None
        d = b0 - a0
        dist = np.hypot(d[..., 0], d[..., 1])
        if np.any(np.abs(dist - m.length) > 1e-9 * max(m.length, 1.0) + 1e-12):
            raise InputError(f"member '{m.name}': length {m.length:.9g} m does not match the distance between "
                             f"joints '{m.start}' and '{m.end}' (off by up to {np.max(np.abs(dist - m.length)):.3g} m)")
        angle[:, i] = np.arctan2(d[..., 1], d[..., 0])
        origin[m.name] = a0
        sl = slice(lay.seg_off[i], lay.seg_off[i + 1])
        nl = slice(lay.node_off[i], lay.node_off[i + 1])
        factor[:, sl] = np.broadcast_to(np.asarray(stiffness_factor.get(m.name, 1.0), dtype=float),
                                        batch + (m.n_segments,))
        R3 = _local_rotation(angle[:, i])[:, None]          # (B, 1, 3, 3)
        K = case.node_stiffness.get(m.name)
        if K is not None:
            K = require_finite(f"member '{m.name}': node_stiffness", K)
            if case.frame == "global":
                K = _to_local_stiffness(K, R3)
            Kn[:, nl] = np.broadcast_to(K, batch + (m.n_segments + 1, 3, 3))
        F = case.node_loads.get(m.name)
        if F is not None:
            F = require_finite(f"member '{m.name}': node_loads", F)
            if case.frame == "global":
                F = F @ np.swapaxes(R3[:, 0], -1, -2)          # R3 F at every node
            Fn[:, nl] = np.broadcast_to(F, batch + (m.n_segments + 1, 3))
        q = case.distributed_loads.get(m.name)
        if q is not None:
            q = require_finite(f"member '{m.name}': distributed_loads", q)
            qloc[:, sl] = np.broadcast_to((R3[..., :2, :2] @ q[..., None])[..., 0], batch + (m.n_segments, 2))
    return Prepared(structure, case, lay, angle, origin, factor,
                    {m.name: stiffness_factor.get(m.name) is not None for m in members}, qloc, Kn, Fn)


def solve_prepared(prep: Prepared, P: np.ndarray, *, check_buckling: bool = True, cond_limit: float = 1e12,
                   count_inertia: bool | None = None, node_loads: np.ndarray | None = None,
                   compact_nodes: np.ndarray | None = None, compact_out: tuple | None = None):
    """One compiled solve of a :class:`Prepared` batch at the stacked segment axial forces
    ``P (B, S)``: ``(states (B, Nn, 2, 6), joint displacements (B, nd), joint forces (B, nd),
    inertia count (B,))``. ``node_loads (B or 1, R, Nn, 3)`` (local frame) instead of the case's
    loads: one factorization per configuration solved for R load sets; the outputs then carry
    the load-set axis after the batch axis. ``compact_nodes``: return, instead of every station
    state, ``(node displacements (B, 3 Nn, R), segment axial forces (B, S, R), right-side states
    at these nodes (B, G, 6, R))`` in the place of the states (much less memory; the load set
    last, as the columns of a map). ``compact_out``: C-contiguous arrays ``(B, 3 Nn, R)`` and
    ``(B, S, R)`` (or None) the node displacements and axial forces are written into (e.g. the
    caller's maps: no second copy). Raises :class:`SingularStructureError` and, with
    ``check_buckling``, :class:`BucklingError` (:mod:`tmm_core.compiled.structure`)."""
    # A writable copy: the kernel is compiled for writable arrays (an iteration updates P).
    P = np.array(np.broadcast_to(np.asarray(P, dtype=float), prep.factor.shape))
    s = _tension_parameter(prep, P)
    out = _run(prep, P, check_buckling, count_inertia, node_loads, compact_nodes, (0.0, 1, False),
               compact_out=compact_out)
    return _checked(prep, P, s, out, check_buckling, cond_limit)


def iterate_prepared(prep: Prepared, *, tol: float, max_iter: int, check_buckling: bool = True,
                     cond_limit: float = 1e12, count_inertia: bool | None = None):
    """The beam-column iteration of every configuration of a :class:`Prepared` batch (the loop
    of :func:`tmm_core.statics.solve_static`, each configuration to its own tolerance): the
    linear solve, its checks and the iteration in one driver call with more than one thread, else (and where the linear solve fails a
    check, to raise) one call each, the change scales from numpy. Returns ``(P (B, S) the last axial
    forces, (states, q, reaction, inertia count) of the last solve as :func:`solve_prepared`,
    solves made (B,), last relative change (B,))``. Raises :class:`ConvergenceError` where a
    configuration has a non-finite iterate or does not converge in ``max_iter`` solves."""
    lay = prep.layout
    weights = change_weights(max(m.length for m in prep.structure.members))
    recount = count_inertia is None and check_buckling
    iteration = (float(tol), int(max_iter), recount)
    B = prep.factor.shape[0]
    P = np.zeros(prep.factor.shape)
    out = None
    # The linear solve and the iteration in one driver call (on the threads, no numpy in
    # between). It declines (None) if a check of the linear solve fails, and is not
    # tried where a clamped-clamped buckling count would enter that check (s = 0 at P = 0
    # unless a stiffness is 0: see buckling.clamped_clamped_buckling_count).
    if _thread_chunks(B, B) > 1 and np.min(_tension_parameter(prep, P), initial=0.0) > -4.0 * np.pi**2:
        out = _run(prep, P, check_buckling, count_inertia, None, None, iteration, weights, cond_limit=cond_limit)
    if out is None:
        P = np.zeros(prep.factor.shape)
        linear = solve_prepared(prep, P, check_buckling=check_buckling, cond_limit=cond_limit,
                                count_inertia=count_inertia)
        start = linear[0]
        scales = np.array(change_scales([start], weights))
        left = np.arange(int(lay.seg_off[-1])) + np.repeat(np.arange(len(lay.seg_off) - 1), np.diff(lay.seg_off))
        # C order: the kernel is compiled for C-contiguous arrays (another layout compiles it again).
        P = np.ascontiguousarray(np.where(lay.rigid, 0.0, 0.5 * (start[:, left, 1, 5] + start[:, left + 1, 0, 5])))
        _tension_parameter(prep, P)
        out = _run(prep, P, check_buckling, count_inertia, None, None, iteration, weights, start, scales)
    status, iterations, last_change = out[5], out[6], out[7]
    for code, what in ((3, "produced non-finite values"), (4, f"did not converge in {max_iter} iterations")):
        if np.any(status == code):
            at = np.flatnonzero(status == code)
            raise ConvergenceError(f"beam_column iteration {what} at batch entries {at[:5].tolist()} (last relative "
                                   f"change {float(np.max(last_change[at])):.3g}, tolerance {tol:.3g})")
    # The last axial forces, checked as every solve's are.
    return P, _checked(prep, P, _tension_parameter(prep, P), out, check_buckling, cond_limit), iterations, last_change


def _run(prep, P, check_buckling, count_inertia, node_loads, compact_nodes, iteration, weights=np.ones(6),
         start=None, scales=np.ones(2), cond_limit=None, compact_out=None):
    """The compiled call: ``(states, q, reaction, negative, pivots, status, iterations,
    last_change)``; ``P`` is updated in place by an iteration (checked by the caller:
    :func:`_tension_parameter`). With ``cond_limit`` (and ``P`` zero, more than one thread):
    the linear solve, its checks and the iteration in one call, None if a check fails."""
    lay = prep.layout
    B, S = prep.factor.shape
    if not P.flags.c_contiguous:
        raise ValueError("compiled solve: the axial forces must be C-contiguous (updated in place)")
    if count_inertia is None:
        count = np.array([check_buckling and bool(np.any(P[:, lay.seg_off[i]:lay.seg_off[i + 1]] < 0))
                          for i in range(len(lay.seg_off) - 1)], dtype=np.bool_)
    else:
        count = np.full(len(lay.seg_off) - 1, bool(count_inertia))
    nd = len(lay.labels)
    Fn = prep.Fn[:, None] if node_loads is None else node_loads
    R = Fn.shape[1]
    Nn = prep.Kn.shape[1]
    if compact_nodes is None:
        states = np.empty((B, R, Nn, 2, 6))
        zout, nout, gnode, gstate = np.empty((B, 0, 0)), np.empty((B, 0, 0)), np.zeros(0, np.int64), np.empty((B, 0, 0, 6))
    else:
        states = np.empty((B, 0, Nn, 2, 6))
        gnode = np.asarray(compact_nodes, dtype=np.int64)
        zout, nout = (None, None) if compact_out is None else compact_out
        zout, nout = _output_array(zout, (B, 3 * Nn, R)), _output_array(nout, (B, S, R))
        gstate = np.empty((B, len(gnode), 6, R))
    q = np.empty((B, R, nd))
    reaction = np.empty((B, R, nd))
    negative = np.zeros((B, 2), dtype=np.int64)
    pivots = np.empty((B, 2))
    status = np.zeros(B, dtype=np.int64)
    iterations, last_change = np.ones(B, dtype=np.int64), np.zeros(B)
    solve_range, iteration_start = binding.static_solve()
    chunks = _thread_chunks(B, B * Fn.shape[1])
    linear_states = None if cond_limit is None else np.empty((B, 1, Nn, 2, 6))
    if linear_states is not None:       # written by the call (not the default's shared array)
        start, scales = linear_states[:, 0], np.zeros(2)
    # The kernel's records (tmm_core.compiled.structure.solve_range).
    segments = (structure_kernel.INV_FACT, lay.seg_off, lay.L, lay.EA, lay.EI, lay.rigid)
    configuration = (prep.factor, P, prep.qloc, prep.Kn, prep.angle)
    joints = (lay.ends, lay.free, count)
    outputs = (states, q, reaction, zout, nout, gnode, gstate)
    checks = (negative, pivots, status)
    control = (np.asarray(weights, dtype=float),
               np.empty((B, 0, 2, 6)) if start is None else np.ascontiguousarray(start),
               np.asarray(scales, dtype=float), iterations, last_change)
    if linear_states is not None:
        # The linear solve, its checks, the change scales and the initial axial forces
        # (iteration_start), then the iteration: every part of the batch on the same call.
        linear_outputs = (linear_states,) + outputs[1:]
        _in_parts(solve_range, B, chunks, segments, configuration, Fn, joints, linear_outputs, checks, (0.0, 1, False),
                  control)
        if not iteration_start(start, P, lay.seg_off, lay.L, lay.EI, prep.factor, lay.rigid, negative, pivots,
                               status, control[0], scales, float(cond_limit), bool(check_buckling)):
            return None
    _in_parts(solve_range, B, chunks, segments, configuration, Fn, joints, outputs, checks, iteration, control)
    if compact_nodes is not None:
        states = (zout, nout, gstate)
    elif node_loads is None:
        states, q, reaction = states[:, 0], q[:, 0], reaction[:, 0]
    return states, q, reaction, negative, pivots, status, iterations, last_change


def _output_array(given, shape):
    """``given`` checked as an output array of the compiled solve (C-contiguous float64 of
    ``shape``), or a new one if None."""
    if given is None:
        return np.empty(shape)
    if given.shape != shape or given.dtype != np.float64 or not given.flags.c_contiguous:
        raise ValueError(f"compiled solve: an output array must be C-contiguous float64 {shape}, got "
                         f"{given.dtype} {given.shape} (contiguous {given.flags.c_contiguous})")
    return given


#: Threads of the compiled batch solve (None: numba's thread count, the number of cores unless
#: NUMBA_NUM_THREADS says otherwise). The configurations of a batch are independent; results do
#: not depend on the thread count. Sweep workers set one thread
#: (cosim.parallel.one_thread_per_worker).
THREADS: int | None = None


def _thread_chunks(B: int, solves: int) -> int:
    """Parts of a batch of ``B`` configurations for the threads (one, without the pool, for
    fewer than 64 solves: handing a part to a thread costs tens of microseconds)."""
    threads = numba_module().config.NUMBA_NUM_THREADS if THREADS is None else max(1, int(THREADS))
    return max(1, min(B, threads if solves >= 64 else 1))


@functools.lru_cache(maxsize=None)
def _pool(threads: int) -> concurrent.futures.ThreadPoolExecutor:
    return concurrent.futures.ThreadPoolExecutor(max_workers=threads, thread_name_prefix="tmm-kernel")


# A forked child (a sweep's worker) has none of the parent's pool threads: work handed to the
# copied pool would wait forever. The child makes its own on first use.
os.register_at_fork(after_in_child=_pool.cache_clear)


def _in_parts(kernel, B: int, chunks: int, *args) -> None:
    """``kernel(b_start, b_stop, *args)`` over the configurations ``0 <= b < B`` in ``chunks``
    contiguous parts, each on a thread of the pool (the kernels release the GIL)."""
    if chunks == 1:
        kernel(0, B, *args)
        return
    parts = [(B * c // chunks, B * (c + 1) // chunks) for c in range(chunks)]
    futures = [_pool(chunks).submit(kernel, b0, b1, *args) for b0, b1 in parts]
    for future in futures:
        future.result()


def factor_prepared(prep: Prepared, P: np.ndarray, *, cond_limit: float = 1e12):
    """The compiled factorization of every configuration of a :class:`Prepared` batch at the
    stacked segment axial forces ``P (B, S)``, kept for later solves
    (:mod:`tmm_core.compiled.time_step`): ``(stored, inertia count (B,))``, ``stored`` the arrays of
    :data:`tmm_core.compiled.time_step.STORED` with the batch axis first. Raises
    :class:`SingularStructureError` as :func:`solve_prepared` (no buckling check: the caller
    reads the inertia count)."""
    P = np.array(np.broadcast_to(np.asarray(P, dtype=float), prep.factor.shape))
    s = _tension_parameter(prep, P)
    lay = prep.layout
    B = prep.factor.shape[0]
    M = len(lay.seg_off) - 1
    nd, nf = len(lay.labels), len(lay.free)
    # The chain's factors before its first deformable segment (index 2 j + 1, j its first
    # flexible segment) are kept up to that index only.
    nlead = 2 + 2 * max(int(np.argmax(~lay.rigid[lay.seg_off[i]:lay.seg_off[i + 1]])) for i in range(M))
    shapes = stored_shapes(np.diff(lay.seg_off), nd, nf, nlead)
    stored = tuple(np.zeros((B,) + shapes[k], dtype=np.int64 if k in time_step_kernel.INTEGER else float)
                   for k in time_step_kernel.STORED)
    negative = np.zeros((B, 2), dtype=np.int64)
    pivots = np.empty((B, 2))
    status = np.zeros(B, dtype=np.int64)
    factor_range, _ = binding.factored()
    segments = (structure_kernel.INV_FACT, lay.seg_off, lay.L, lay.EA, lay.EI, lay.rigid)
    configuration = (prep.factor, P, prep.qloc, prep.Kn, prep.angle)
    joints = (lay.ends, lay.free, np.ones(M, dtype=np.bool_))
    _in_parts(factor_range, B, _thread_chunks(B, B), segments, configuration, joints, (negative, pivots, status), stored)
    return stored, _checked(prep, P, s, (None, None, None, negative, pivots, status), False, cond_limit)[3]


def stored_bytes(prep: Prepared) -> float:
    """Memory of :func:`factor_prepared`'s stored factorizations of a batch [bytes]."""
    lay = prep.layout
    return prep.factor.shape[0] * stored_bytes_per_configuration(np.diff(lay.seg_off), len(lay.labels), len(lay.free))


def stored_bytes_per_configuration(member_segments, joint_dofs: int = 0, free_dofs: int = 0) -> float:
    """Memory of one configuration's stored factorization [bytes] (an upper bound: the factors
    before a member's first deformable segment counted as if it were its second)."""
    return 8.0 * sum(int(np.prod(shape)) for shape in stored_shapes(member_segments, joint_dofs, free_dofs, 4).values())


def stored_shapes(member_segments, joint_dofs: int, free_dofs: int, nlead: int) -> dict:
    """Shapes of one configuration's stored factorization (:data:`tmm_core.compiled.time_step.STORED`):
    ``member_segments`` of each member, ``nlead`` chain matrices kept before the first
    deformable segment's (its index + 1)."""
    M = len(member_segments)
    nmax = int(np.max(member_segments))         # a segment's blocks at its index
    mmax = 2 * nmax + 1                         # the chain's matrices (node, segment, node, ...)
    return {"lead": (M, nlead, 6, 6), "prefix": (M, nlead, 6, 6), "lcol": (M, 6), "B0": (M, 3, 3),
            "T220": (M, 3, 3), "SP": (M, nmax, 10), "TL": (M, nmax, 6), "Gis": (M, nmax, 3, 3),
            "Xs": (M, nmax, 3, 3), "BGis": (M, nmax, 3, 3), "HGis": (M, nmax, 3, 3), "Cs": (M, mmax + 1, 3, 3),
            "Ds": (M, mmax + 1, 3, 3), "Af": (M, 3, 3), "Bf": (M, 3, 3), "firsts": (M,),
            "Kfull": (joint_dofs, joint_dofs), "lu": (free_dofs, free_dofs), "piv": (free_dofs,)}


def _tension_parameter(prep, P):
    """``P L^2 / EI`` of every segment ``(B, S)``; refused where cosh would overflow."""
    lay = prep.layout
    s = P * lay.L**2 / (lay.EI * prep.factor)
    if np.any(s > 700.0**2):
        raise InputError(f"segment tension parameter P*L^2/EI = {float(np.max(s)):.4g} overflows cosh; "
                         "split the link into more segments")
    return s


def _checked(prep, P, s, out, check_buckling, cond_limit):
    """``(states, q, reaction, inertia count)`` of a compiled call, after its checks (singular
    structure, pivot ratio, buckling at the axial forces ``P``, tension parameters ``s``)."""
    states, q, reaction, negative, pivots, status = out[:6]
    lay = prep.layout
    if np.any(status == 1):
        raise SingularStructureError("instantaneous structure is singular: no stiffness at a joint DOF "
                                     f"(batch entries {np.flatnonzero(status == 1)[:5].tolist()})")
    with np.errstate(divide="ignore", invalid="ignore"):
        condition = np.where(pivots[:, 0] > 0, pivots[:, 1] / pivots[:, 0], np.inf)
    if np.any(status == 2) or np.any(~(condition < cond_limit)):
        worst = int(np.argmax(np.where(status == 2, np.inf, np.nan_to_num(condition, nan=np.inf))))
        raise SingularStructureError(
            f"instantaneous structure is singular (pivot ratio of the scaled joint stiffness "
            f"{float(condition[worst]):.3g} at batch index ({worst},)): a toggle position (collinear links at a "
            "revolute), an unconstrained joint, a member at its buckling load, or a speed at a natural frequency")
    total = negative[:, 0] + negative[:, 1]
    total = total + np.sum(np.where(lay.rigid, 0, clamped_clamped_buckling_count(s)), -1)
    if check_buckling and np.any(total > 0):
        raise BucklingError(buckling_message(prep.structure, {m.name: P[:, lay.seg_off[i]:lay.seg_off[i + 1]]
                                                              for i, m in enumerate(prep.structure.members)}, total))
    return states, q, reaction, total


def linear_solution(prep: Prepared, P, states, q, reaction, negative):
    """The :class:`tmm_core.structure.LinearSolution` of a :func:`solve_prepared` result."""
    lay = prep.layout
    B = prep.factor.shape[0]
    out = {}
    for i, m in enumerate(prep.structure.members):
        sl = slice(lay.seg_off[i], lay.seg_off[i + 1])
        out[m.name] = MemberResult(m, prep.angle[:, i], prep.origin[m.name], states[:, lay.node_off[i]:lay.node_off[i + 1]],
                                   P[:, sl], np.zeros((B, m.n_segments)),
                                   prep.factor[:, sl] if prep.factor_given[m.name] else 1.0)
    index = {lab: k for k, lab in enumerate(lay.labels)}
    reactions = support_reactions(prep.structure, lay.labels, reaction)
    joint_disp = {j.name: np.stack([q[:, index[(j.name, "x")]], q[:, index[(j.name, "y")]]], -1)
                  for j in prep.structure.joints}
    return LinearSolution(prep.structure, prep.case, out, reactions, negative, joint_disp, {})


def solve_linear(structure, case, axial_force: Mapping[str, np.ndarray] | None = None, *,
                 check_buckling: bool = True, cond_limit: float = 1e12,
                 stiffness_factor: Mapping[str, np.ndarray] | None = None, count_inertia: bool | None = None):
    """Compiled equivalent of :func:`tmm_core.structure.solve_linear` (small deflection, no chord
    rotation) for a :func:`supported` structure and a one-dimensional batch of configurations.
    Returns a :class:`tmm_core.structure.LinearSolution`; raises the same errors (singular
    structure, buckling), decided from the pivots of the factorization (:mod:`tmm_core.compiled.structure`)."""
    prep = prepare(structure, case, stiffness_factor)
    P = stack_segments(prep, axial_force or {})
    res = solve_prepared(prep, P, check_buckling=check_buckling, cond_limit=cond_limit, count_inertia=count_inertia)
    return linear_solution(prep, P, *res)


def stack_segments(prep: Prepared, per_member: Mapping[str, np.ndarray]) -> np.ndarray:
    """``{member: (B, n) or scalar}`` (missing: 0) as the stacked ``(B, S)`` array."""
    lay = prep.layout
    B, S = prep.factor.shape
    P = np.zeros((B, S))
    for i, m in enumerate(prep.structure.members):
        if m.name in per_member:
            P[:, lay.seg_off[i]:lay.seg_off[i + 1]] = np.broadcast_to(np.asarray(per_member[m.name], dtype=float),
                                                                      (B, m.n_segments))
    return P


def solve_static(structure, case, *, beam_column: bool = False, tol: float = 1e-10, max_iter: int = 200,
                 count_inertia: bool | None = None):
    """Compiled equivalent of :func:`tmm_core.statics.solve_static` (linear or beam-column, not
    large deflection): the same successive linear solutions, relaxation and stopping rule for
    every configuration, in one compiled call (:func:`iterate_prepared`)."""
    prep = prepare(structure, case)
    if not beam_column:
        P = np.zeros(prep.factor.shape)
        return StaticSolution(linear_solution(prep, P, *solve_prepared(prep, P, count_inertia=count_inertia)),
                              "linear", 1, 0.0)
    P, res, iterations, last_change = iterate_prepared(prep, tol=tol, max_iter=max_iter, count_inertia=count_inertia)
    return StaticSolution(linear_solution(prep, P, *res), "beam_column", int(np.max(iterations)),
                          float(np.max(last_change)))
