"""What guards a run: its cost estimated and refused before anything is allocated, and results
no rig would show flagged after it.

Owns: the cost estimate and its limits, the plausibility notes. Boundaries: no run logic
(cosim.run calls these); the measured per-step costs below are the only timing constants.
"""
from __future__ import annotations

import logging
import math

from .master import InputError
from .scenario import Scenario

log = logging.getLogger(__name__)

#: A run whose estimated wall time exceeds this is refused before anything is allocated
#: (``RunOptions.max_hours``, ``cosim run --max-hours``).
MAX_HOURS = 2.0
#: A run whose traces would not fit in this much memory is refused (not raisable: the traces
#: of every engine's step are held until the run ends).
MAX_MEMORY_BYTES = 4e9
#: Measured wall time per internal step on one core (FE rig at 373 rpm): the transfer-matrix
#: engine's numpy path 1.5 ms with 24 mesh segments, growing as segments**1.7 (its batched
#: factorizations); exudyn 1 ms plus 25 us per node; MuJoCo 1 ms.
_TMM_STEP_S, _TMM_SEGMENTS, _TMM_EXPONENT = 1.5e-3, 24, 1.7
#: The transfer-matrix engine's compiled march (a structure of joints and members, numba, a
#: revolution's stored factorizations within the time domain's memory budget): 12 us plus 0.5 us
#: per segment a step (measured 18-45 us at 16-64 segments, 4-6 second-order iterations a step),
#: and 5 ms of Python per macro step (a motor-driven step's configurations are factorized per
#: macro step: 4.7 ms measured; prescribed runs group ~10 deg in one).
_TMM_COMPILED_STEP_S, _TMM_COMPILED_SEGMENT_S, _TMM_MACRO_S = 1.2e-5, 5e-7, 5e-3
_EXUDYN_STEP_S, _EXUDYN_NODE_S, _MUJOCO_STEP_S = 1e-3, 2.5e-5, 1e-3


def estimate_cost(sc: Scenario, engines, duration_s: float, macro_step_s: float) -> dict:
    """What a run of ``duration_s`` costs, per engine and in all, before anything is allocated:
    ``{engine: {steps, size, seconds, bytes}, "seconds", "bytes", "text"}`` (size: mesh segments
    for the TMM, nodes for exudyn, links for MuJoCo; bytes: the traces held in memory)."""
    try:
        links = list(sc.mechanism.links())
        segments = sum(int(link.total_segments) for link in links)
    except Exception:                # a mechanism without links() (none today): its size is unknown
        links, segments = [], _TMM_SEGMENTS
    n_links = max(1, len(links))
    out, total_s, total_b, parts = {}, 0.0, 0.0, []
    for e in engines:
        steps = duration_s / sc.engine_step_s(e)
        if e == "tmm":
            size, per = segments, _tmm_step_s(sc, segments, duration_s / max(macro_step_s, 1e-300) / steps)
            nodes, what = segments + n_links, "segments"
        elif e == "exudyn":
            nodes = n_links * (sc.exudyn.elements + 1)
            size, per, what = nodes, _EXUDYN_STEP_S + _EXUDYN_NODE_S * nodes, "nodes"
        else:
            nodes = n_links * 9
            size, per, what = n_links, _MUJOCO_STEP_S, "links"
        # each sample: time, angle, speed, torque, the gauges' two strains, every node's (x, y)
        sample_bytes = 8 * (4 + 2 * len(sc.gauges) + 2 * nodes)
        seconds, nbytes = steps * per, steps * sample_bytes
        out[e] = {"steps": steps, "size": size, "seconds": seconds, "bytes": nbytes}
        total_s, total_b = total_s + seconds, total_b + nbytes
        parts.append(f"{e} {steps:.3g} steps x {size} {what}")
    out["macro_steps"] = duration_s / macro_step_s
    out["seconds"], out["bytes"] = total_s, total_b
    out["text"] = (f"{'; '.join(parts)}: about {duration_text(total_s)} and {total_b / 1e9:.3g} GB of traces "
                   f"over {duration_s:.4g} s simulated")
    return out


def _tmm_step_s(sc: Scenario, segments: int, macro_per_step: float) -> float:
    """Wall time per step of the transfer-matrix engine [s]: its compiled march where the structure
    qualifies and a revolution's stored factorizations fit the time domain's memory budget (the
    engine's own test, :meth:`tmm_core.TimeDomain.configurations`), else the numpy path."""
    try:
        from tmm_core import kernels, structure_compiled, transient
        budget = transient.MAX_STEP_DATA_BYTES
        per_revolution = 2 * math.pi / abs(sc.drive.speed_rad_s) / sc.engine_step_s("tmm")
        structure = sc.mechanism.structure()
        compiled = (kernels.AVAILABLE and structure_compiled.supported(structure)
                    and per_revolution * structure_compiled.stored_bytes_per_configuration(
                        [m.n_segments for m in structure.members]) <= budget)
    except Exception:                # no crank speed, no structure: the numpy path's estimate
        compiled = False
    if compiled:
        return _TMM_COMPILED_STEP_S + _TMM_COMPILED_SEGMENT_S * segments + _TMM_MACRO_S * macro_per_step
    return _TMM_STEP_S * max(1.0, segments / _TMM_SEGMENTS) ** _TMM_EXPONENT


def check_cost(sc: Scenario, engines, duration_s: float, macro_step_s: float, max_hours: float = MAX_HOURS) -> dict:
    """:func:`estimate_cost`, refused with :class:`InputError` (the estimate and the setting that
    would change it) when it exceeds ``max_hours`` of wall time or :data:`MAX_MEMORY_BYTES`."""
    cost = estimate_cost(sc, engines, duration_s, macro_step_s)
    worst = max(engines, key=lambda e: cost[e]["seconds"])
    hint = (f"a coarser solver.{worst}.step, fewer {'segments' if worst == 'tmm' else 'elements'}, or fewer "
            "revolutions (--revolutions, output.max_revolutions)")
    if not cost["bytes"] <= MAX_MEMORY_BYTES:
        raise InputError(f"scenario '{sc.path or sc.name}': refused before it started: {cost['text']}, beyond the "
                         f"{MAX_MEMORY_BYTES / 1e9:g} GB a run may hold; use {hint}")
    if not cost["seconds"] <= max_hours * 3600:
        raise InputError(f"scenario '{sc.path or sc.name}': refused before it started: {cost['text']}, beyond the "
                         f"limit of {max_hours:g} h; use {hint}, or raise the limit with --max-hours")
    return cost


def duration_text(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.3g} s"
    if seconds < 2 * 3600:
        return f"{seconds / 60:.3g} min"
    if seconds < 3 * 86400:
        return f"{seconds / 3600:.3g} h"
    return f"{seconds / 86400:.3g} days"


#: Without a yield strength in the file, a strain beyond this is reported as implausible (the
#: yield strain of the aluminium alloys and steels linkages are made of is 0.2-0.5 %).
PLAUSIBLE_STRAIN = 5e-3


def plausibility_notes(sc: Scenario, summary: dict) -> list:
    """Warnings about results no rig would show: a strain beyond the material's yield (its
    ``yield_strength``, else :data:`PLAUSIBLE_STRAIN`). Whether a resonance is ringing it up is
    the run's physics flags' (:mod:`cosim.physics_flags`), which then check the linkage's own
    natural frequencies."""
    gauges = {g.name: g for g in sc.gauges}
    links = {}
    try:
        links = {link.name: link for link in sc.mechanism.links()}
    except Exception:
        pass
    out = []
    for engine, e in summary["engines"].items():
        for g, stats in (e.get("gauges") or {}).items():
            peak = max(abs(stats.get("bending_max_ue") or 0), abs(stats.get("bending_min_ue") or 0)) * 1e-6
            link = links.get(getattr(gauges.get(g), "link", None))
            mat = getattr(link, "material", None)
            ys = getattr(mat, "yield_strength_Pa", None)
            limit, what = ((ys / mat.E_Pa, f"the yield strength of {mat.name}") if ys and mat is not None
                           else (PLAUSIBLE_STRAIN, "the yield strain of structural metals"))
            if peak > limit:
                out.append(f"implausible: {engine} at {g} reaches {peak * 1e6:.0f} µε, beyond {what} "
                           f"({limit * 1e6:.0f} µε): the linkage would yield; "
                           + ("the result is not steady either (a transient or a resonance)"
                              if not e.get("steady") else "check the scenario"))
                break
    return out
