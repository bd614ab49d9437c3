"""What a time step of a model (:class:`tmm_core.discretization.Discretization`) reads of a batch
of configurations, besides its loads: the load-to-response maps
(:class:`tmm_core.configuration_batch.StepMaps`) from the compiled factorization
(:mod:`tmm_core.compiled.structure`: every unit node load solved on one factorization per
configuration, in chunks of bounded working memory) or from the numpy one, or the stored compiled
factorizations with the outputs' functionals (:class:`tmm_core.configuration_batch.StepFactors`,
:mod:`tmm_core.compiled.time_step`).

Owns: the step's maps and stored factorizations, and the selection of configurations of a
batch's factor and drive-torque terms. Boundaries: which of them a batch gets, and everything
else of a configuration, is :func:`tmm_core.batches.configurations`.
"""
from __future__ import annotations

import contextlib
import dataclasses

import numpy as np

from .compiled import statics as compiled_statics
from .configuration_batch import StepFactors, StepMaps
from .discretization import Discretization
from .ked import segment_forces
from .mechanism import torque_from_terms
from .post import gauge_strains
from .structure import MemberResult, solve_factored, support_reactions

MAP_CHUNK_BYTES = 64e6       # working memory of one chunk of the map solve


def compiled_maps(model: Discretization, prep, P, drive):
    """The load-to-response maps of ``model`` (as the numpy path of
    :func:`tmm_core.batches.configurations`: a :class:`StepMaps`) from one compiled
    factorization per configuration solved for every unit load (``drive``: the batch's
    :meth:`drive_torque_terms`, as :func:`numpy_maps`); returns the maps and the inertia count
    ``(B,)``. Its arrays get no huge-page advice (:func:`without_huge_page_advice`)."""
    with without_huge_page_advice():
        return _compiled_maps(model, prep, P, drive)


@contextlib.contextmanager
def without_huge_page_advice():
    """numpy's transparent-huge-page advice (MADV_HUGEPAGE on arrays of 4 MB and more) off for
    the arrays allocated inside, restored after. Where the kernel's THP defrag setting is
    'madvise' (common), a fault in such an array compacts memory synchronously when no huge page
    is free (numpy issue 31590): after other processes had run, the maps' solve of the FE rig at
    373 rpm took 30-35 ms instead of 11-15 in about a third of fresh processes, its set-up 54 ms
    median against 40 ms without the advice (the set-up's arrays are written once, by two
    threads). A no-op where numpy has no such switch."""
    core = getattr(np, "_core", None) or np.core
    toggle = getattr(core.multiarray, "_set_madvise_hugepage", None)
    if toggle is None:
        yield
        return
    previous = toggle(False)
    try:
        yield
    finally:
        toggle(previous)


def _compiled_maps(model: Discretization, prep, P, drive):
    B = len(P)
    n = model.n_dof
    # Unit loads (stacked node vector order = the compiled node order) plus a zero column.
    unit = np.zeros((1, n + 1, n // 3, 3))
    unit[0, np.arange(n), np.arange(n) // 3, np.arange(n) % 3] = 1.0
    lay = prep.layout
    axial = model.axial_force == "dynamic"
    maps = StepMaps.empty(B, n, model.outputs.size, len(model.segments.length) if axial else None)
    negative = np.empty(B, dtype=int)
    gauge_at = gauge_nodes(model, lay)
    chunk = max(1, int(MAP_CHUNK_BYTES // (8.0 * (n + 1) * (2 * n + 6 * len(gauge_at) + 8))))
    for c0 in range(0, B, chunk):
        sl = slice(c0, min(B, c0 + chunk))
        part = compiled_statics.Prepared(prep.structure, prep.case, lay, prep.angle[sl],
                                       {k: v[sl] for k, v in prep.origin.items()}, prep.factor[sl],
                                       prep.factor_given, prep.qloc[sl], prep.Kn[sl], prep.Fn[sl])
        # The responses to the unit loads and to the zero load (the last column), written into
        # the augmented maps (z: (b, n_dof, loads+1), N: (b, n_seg, loads+1)), then made relative.
        (z, N, gstates), _, reaction, neg = compiled_statics.solve_prepared(
            part, P[sl], check_buckling=False, count_inertia=True, node_loads=unit, compact_nodes=gauge_at,
            compact_out=(maps.Zx[sl], maps.Ax[sl] if axial else None))
        negative[sl] = neg
        _relative(z)
        # The outputs: their affine functionals of the joint forces and gauge states, applied.
        y = np.concatenate([np.swapaxes(reaction, 1, 2), gstates.reshape(len(neg), -1, n + 1)], axis=1)
        _relative(y)
        Ocx = output_functionals(model, part, P[sl], sl, drive, len(lay.labels), len(gauge_at))
        np.matmul(Ocx[:, :, :-1], y, out=maps.Ox[sl])
        maps.Ox[sl, :, -1] += Ocx[:, :, -1]
        if axial:
            _relative(N)
        del z, N, gstates
    return maps, negative


def _relative(x):
    """Responses ``x (b, m, loads + 1)`` to the unit loads made relative to the last column's, the
    response to zero load, in place. The time domain's cases carry no loads of their own (the
    step applies them through the maps), so that column is zero and the subtraction is skipped:
    ~1.3 ms of Alexander-Lawrence's set-up (360 configurations), a no-op in value."""
    if np.any(x[:, :, -1]):
        x[:, :, :-1] -= x[:, :, -1:]


def compiled_factors(model: Discretization, prep, P, drive):
    """The map-free alternative: every configuration's compiled factorization kept
    (:func:`tmm_core.compiled.statics.factor_prepared`) and the outputs' affine functionals of
    the joint reactions and gauge states (their coefficients: the outputs of unit inputs;
    ``drive`` as :func:`compiled_maps`); returns a :class:`StepFactors` and the inertia count
    ``(B,)``."""
    B = len(P)
    lay = prep.layout
    stored, negative = compiled_statics.factor_prepared(prep, P)
    gauge_at = gauge_nodes(model, lay)
    Ocx = output_functionals(model, prep, P, slice(0, B), drive, len(lay.labels), len(gauge_at))
    layout = (lay.seg_off, lay.rigid, np.ascontiguousarray(prep.angle), lay.ends, lay.free,
              np.asarray(gauge_at, dtype=np.int64))
    return StepFactors(layout, stored, Ocx), negative


def output_functionals(model: Discretization, part, P, sl, drive, nd, G):
    """The outputs (:class:`tmm_core.configuration_batch.OutputLayout`) of the configurations
    ``sl`` of a batch (``part``: their :class:`compiled_statics.Prepared`, ``P (b, S)`` their
    axial forces) as affine functionals of a solution's ``y``, its joint forces ``(nd,)`` [N, N m]
    then the right-side states ``(G, 6)`` at the gauge nodes (:func:`gauge_nodes`: two a gauge):
    augmented ``(b, n_out, ny + 1)`` (``outputs = Ocx[:, :, :-1] @ y + Ocx[:, :, -1]``). The drive
    torque reads only the joint forces and gauge k only its own states, so each is evaluated on
    its own unit inputs and zero (nd + 1, and 7 a gauge) and the other coefficients are zero:
    evaluating every output on all ny + 1 inputs cost the Watt six-bar's set-up ~7 ms of its ~30
    at 360 configurations."""
    b = len(P)
    lay = part.layout
    Ocx = np.zeros((b, model.outputs.size, nd + 6 * G + 1))
    rows = np.moveaxis(Ocx, 1, -1)                                       # a view, (b, ny + 1, n_out)
    unit = np.vstack([np.eye(nd), np.zeros((1, nd))])                 # nd unit joint forces and zero
    reactions = support_reactions(model.structure, lay.labels, np.broadcast_to(unit, (b, nd + 1, nd)))
    _affine_rows(model.outputs.torque(rows), slice(0, nd), torque_from_terms(reactions, *terms_at(drive, sl)))
    members = {m.name: (i, m) for i, m in enumerate(model.structure.members)}
    unit = np.vstack([np.eye(6), np.zeros((1, 6))])                     # a gauge state's 6 units and zero
    for k, g in enumerate(model.gauges):
        i, m = members[g.link]
        # gauge_strains reads only the state of node j, right side: a broadcast view elsewhere.
        state = np.broadcast_to(unit[None, :, None, None, :], (b, 7, m.n_segments + 1, 2, 6))
        seg = slice(lay.seg_off[i], lay.seg_off[i + 1])
        res = MemberResult(m, part.angle[:, i, None], part.origin[m.name][:, None], state, P[:, None, seg],
                           np.zeros((1, 1, m.n_segments)), part.factor[:, None, seg])
        first = nd + 12 * k
        bending, _ = gauge_strains(res, g)
        _affine_rows(model.outputs.bending(rows, k), slice(first, first + 6), bending)
        # The axial strain: each of its two segments' axial force (component 5 of the state at the
        # node that starts it) over that segment's stiffness, weighted; no offset.
        axial = model.outputs.axial(rows, k)
        for c, (j, w) in enumerate(zip(*model.gauge_axial_sampling(k))):
            EA = m.materials[j].E_Pa * m.sections[j].area_m2
            axial[:, first + 6 * c + 5] += w / (EA * part.factor[:, lay.seg_off[i] + j])
    return Ocx


def _affine_rows(out, cols, values):
    """Write one output's affine functional into ``out (b, ny + 1)``: its coefficients on the
    inputs ``cols`` from ``values (b, k + 1)``, the output of each unit input then of zero."""
    out[:, cols] = values[:, :-1] - values[:, -1:]
    out[:, -1] = values[:, -1]


def gauge_nodes(model: Discretization, lay) -> list:
    """The compiled nodes whose right-side states the outputs read, two a gauge of ``model``: the
    node that starts the gauge's segment (its bending strain and the first segment of its axial
    strain) and the node that starts the second segment of its axial strain
    (:func:`tmm_core.discretization.axial_sampling`)."""
    members = {m.name: i for i, m in enumerate(model.structure.members)}
    return [int(lay.node_off[members[g.link]]) + j
            for k, g in enumerate(model.gauges) for j in model.gauge_axial_sampling(k)[0]]


def numpy_maps(model: Discretization, factor, drive):
    """The load-to-response maps (:class:`StepMaps`) of ``model`` from
    its numpy factorization ``factor`` of B configurations (batch (B, 1)): every unit node load
    solved by Riccati sweeps (:func:`tmm_core.structure.solve_factored`), in chunks."""
    B = factor.batch[0]
    unit = {}
    for link in model.links:
        n1 = link.n_nodes
        U = np.zeros((model.n_dof, n1, 3))
        off = model.offsets[link.name]
        U[off:off + 3 * n1].reshape(n1, 3, n1, 3)[np.arange(n1), :, np.arange(n1), :] = np.eye(3)
        unit[link.name] = U
    # Unit loads plus one zero-load column (the response to gravity and other base loads).
    unit = {k: np.concatenate([v, np.zeros((1,) + v.shape[1:])])[None] for k, v in unit.items()}
    # Solved in chunks of configurations: the station states of every unit load take about
    # 32 n_dof^2 bytes per configuration (0.5 GB for a revolution at 0.5 deg, 16 segments per link).
    chunk = max(1, int(MAP_CHUNK_BYTES // (32.0 * model.n_dof ** 2)))
    n_out = model.outputs.size
    axial = model.axial_force == "dynamic"
    maps = StepMaps.empty(B, model.n_dof, n_out, len(model.segments.length) if axial else None)
    for c0 in range(0, B, chunk):
        sl = slice(c0, min(B, c0 + chunk))
        sol = solve_factored(factor if (sl.start, sl.stop) == (0, B) else select(factor, sl), unit, frame="local")
        z = np.concatenate([sol.members[l.name].state[..., 0, :3].reshape(sl.stop - sl.start, model.n_dof + 1, -1)
                            for l in model.links], axis=-1)                 # (b, loads+1, n_dof)
        torque = torque_from_terms(sol.reactions, *terms_at(drive, sl))   # (b, loads+1)
        g_out = [np.stack(gauge_strains(sol.members[g.link], g, axial_sampling=model.gauge_axial_sampling(k)), -1)
                 for k, g in enumerate(model.gauges)]
        outs = np.concatenate([torque[..., None]] + g_out, axis=-1) if g_out else torque[..., None]
        maps.Z[sl] = np.swapaxes(z[:, :-1] - z[:, -1:], 1, 2)
        maps.z0[sl] = z[:, -1]
        maps.O[sl] = np.swapaxes(outs[:, :-1] - outs[:, -1:], 1, 2)
        maps.o0[sl] = outs[:, -1]
        if axial:
            N = np.concatenate([segment_forces(sol.members[l.name]) for l in model.links], axis=-1)
            maps.A[sl] = np.swapaxes(N[:, :-1] - N[:, -1:], 1, 2)
            maps.a0[sl] = N[:, -1]
        del sol
    return maps


def terms_at(terms, k):
    """Drive-torque terms of configuration ``k`` (an index or a slice) of a batch."""
    joint, arm, offset = terms
    if arm is None:
        return terms
    return joint, arm[k], np.asarray(offset)[k]


def select(factor, k):
    """Configuration ``k`` (an index or a slice) of a factor with batch (B, 1): views, no copies."""
    sl = k if isinstance(k, slice) else slice(k, k + 1)
    n = len(range(*sl.indices(factor.batch[0])))

    def take(x):
        if isinstance(x, np.ndarray) and x.ndim >= 2 and x.shape[0] == factor.batch[0] and x.shape[1] == 1:
            return x[sl]
        if isinstance(x, tuple):
            return tuple(take(v) for v in x)
        if isinstance(x, list):
            return [take(v) for v in x]
        if isinstance(x, dict):
            return {kk: take(v) for kk, v in x.items()}
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return dataclasses.replace(x, **{f.name: take(getattr(x, f.name)) for f in dataclasses.fields(x)
                                            if f.name not in ("structure", "case")})
        return x

    out = take(factor)
    return dataclasses.replace(out, batch=(n, 1))
