"""The time domain's load-to-response maps from the compiled factorization
(:mod:`tmm_core.kernels_static`): every unit node load solved on one factorization per
configuration, in chunks of bounded working memory.

Owns: the compiled maps. Boundaries: the numpy maps and everything else of a configuration are
:meth:`tmm_core.TimeDomain.configurations`.
"""
from __future__ import annotations

import numpy as np

from . import structure_compiled
from .configuration_batch import StepMaps
from .mechanism import torque_from_terms
from .post import gauge_strains
from .structure import MemberResult
from .time_step import terms_at

MAP_CHUNK_BYTES = 64e6       # working memory of one chunk of the map solve


def compiled_maps(td, prep, P, motion):
    """The load-to-response maps of a :class:`tmm_core.TimeDomain` ``td`` (as the numpy path of
    :meth:`tmm_core.TimeDomain.configurations`: a :class:`StepMaps`) from one compiled factorization per configuration solved for every
    unit load; returns the maps and the inertia count ``(B,)``."""
    B = len(P)
    n = td.n_dof
    # Unit loads (stacked node vector order = the compiled node order) plus a zero column.
    unit = np.zeros((1, n + 1, n // 3, 3))
    unit[0, np.arange(n), np.arange(n) // 3, np.arange(n) % 3] = 1.0
    lay = prep.layout
    index = {lab: k for k, lab in enumerate(lay.labels)}
    supports = [(j.name, j.support) for j in td.structure.joints if j.support != "free"]
    axial = td.axial_force == "dynamic"
    maps = StepMaps.empty(B, n, td.outputs.size, len(td.segments.length) if axial else None)
    negative = np.empty(B, dtype=int)
    drive = td.mech.drive_torque_terms(motion, td.gravity)
    members = {m.name: (i, m) for i, m in enumerate(td.structure.members)}
    # The gauges read the right-side state of the node that starts their segment.
    gauge_at = []
    for g in td.gauges:
        i, m = members[g.link]
        j = int(np.clip(np.searchsorted(m.stations, g.position_m, side="right") - 1, 0, m.n_segments - 1))
        gauge_at.append(int(lay.node_off[i]) + j)
    chunk = max(1, int(MAP_CHUNK_BYTES // (8.0 * (n + 1) * (2 * n + 6 * len(td.gauges) + 8))))
    for c0 in range(0, B, chunk):
        sl = slice(c0, min(B, c0 + chunk))
        part = structure_compiled.Prepared(prep.structure, prep.case, lay, prep.angle[sl],
                                       {k: v[sl] for k, v in prep.origin.items()}, prep.factor[sl],
                                       prep.factor_given, prep.qloc[sl], prep.Kn[sl], prep.Fn[sl])
        (z, N, gstates), _, reaction, neg = structure_compiled.solve_prepared(
            part, P[sl], check_buckling=False, count_inertia=True, node_loads=unit, compact_nodes=gauge_at)
        negative[sl] = neg                                      # z: (b, n_dof, loads+1), N: (b, n_seg, loads+1)
        reactions = {}
        for name, support in supports:
            r = np.zeros(reaction.shape[:-1] + (3,))
            r[..., 0] = reaction[..., index[(name, "x")]]
            r[..., 1] = reaction[..., index[(name, "y")]]
            if support == "clamped":
                r[..., 2] = reaction[..., index[(name, "r")]]
            reactions[name] = r
        torque = torque_from_terms(reactions, *terms_at(drive, sl))          # (b, loads+1)
        g_out = []
        for k, g in enumerate(td.gauges):
            i, m = members[g.link]
            # Only the state gauge_strains reads (node j, right side) is real: a broadcast view.
            gs = np.moveaxis(gstates[:, k], 1, -1)                                    # (b, loads+1, 6)
            state = np.broadcast_to(gs[:, :, None, None, :], gs.shape[:2] + (m.n_segments + 1, 2, 6))
            res = MemberResult(m, part.angle[:, i, None], part.origin[m.name][:, None], state,
                               P[sl, None, lay.seg_off[i]:lay.seg_off[i + 1]], np.zeros((1, 1, m.n_segments)),
                               part.factor[:, None, lay.seg_off[i]:lay.seg_off[i + 1]])
            g_out.append(np.stack(gauge_strains(res, g), -1))
        outs = np.concatenate([torque[..., None]] + g_out, axis=-1) if g_out else torque[..., None]
        np.subtract(z[:, :, :-1], z[:, :, -1:], out=maps.Z[sl])
        maps.z0[sl] = z[:, :, -1]
        maps.O[sl] = np.swapaxes(outs[:, :-1] - outs[:, -1:], 1, 2)
        maps.o0[sl] = outs[:, -1]
        if axial:
            np.subtract(N[:, :, :-1], N[:, :, -1:], out=maps.A[sl])
            maps.a0[sl] = N[:, :, -1]
        del z, N, gstates
    return maps, negative
