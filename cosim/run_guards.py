"""What guards a run: its cost estimated and refused before anything is allocated, and results
no rig would show flagged after it.

Owns: the cost estimate and its limits, the plausibility notes. Boundaries: no run logic
(cosim.runs calls these); the measured per-step costs below are the only timing constants.
"""
from __future__ import annotations

import logging
import os

from .defaults import MAX_HOURS
from .master import InputError
from .scenario import Scenario

log = logging.getLogger(__name__)

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
    ``{engine: {steps, size, seconds, bytes, setup_bytes}, "seconds", "bytes", "setup_bytes", "text"}``
    (size: mesh segments for the TMM, nodes for exudyn, links for MuJoCo; bytes: the traces held
    in memory plus what the set-up allocates, :func:`tmm_setup_bytes`)."""
    links, segments = _mesh(sc)
    n_links = max(1, len(links))
    out, total_s, total_b, total_setup, parts = {}, 0.0, 0.0, 0.0, []
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
        setup = tmm_setup_bytes(sc, segments, n_links) if e == "tmm" else 0.0
        seconds, nbytes = steps * per, steps * sample_bytes + setup
        out[e] = {"steps": steps, "size": size, "seconds": seconds, "bytes": nbytes, "setup_bytes": setup}
        total_s, total_b, total_setup = total_s + seconds, total_b + nbytes, total_setup + setup
        parts.append(f"{e} {steps:.3g} steps x {size} {what}" + (f", {len(sc.gauges)} gauges" if setup else ""))
    out["macro_steps"] = duration_s / macro_step_s
    out["seconds"], out["bytes"], out["setup_bytes"] = total_s, total_b, total_setup
    held = f" (traces {(total_b - total_setup) / 1e9:.3g} GB, set-up {total_setup / 1e9:.3g} GB)" if total_setup else ""
    out["text"] = (f"{'; '.join(parts)}: about {duration_text(total_s)} and {total_b / 1e9:.3g} GB{held} of memory "
                   f"over {duration_s:.4g} s simulated")
    return out


def tmm_setup_bytes(sc: Scenario, segments: int, n_links: int) -> float:
    """Memory the transfer-matrix engine's set-up allocates for a revolution of stored
    configurations [bytes] that its memory budget (``tmm_core.discretization.MAX_STEP_DATA_BYTES``)
    does not bound: per configuration the outputs (drive torque, two strains a gauge) as affine
    functionals of the joint forces and every gauge's 6 states
    (``tmm_core.step_data.output_functionals``, ``(1 + 2G) x (joint forces + 6G + 1)`` doubles) and
    the outputs' maps (``(1 + 2G) x (DOFs + 1)``). It grows as the gauges squared: 10,000 gauges
    at 0.5 deg asked for 6.29 TiB."""
    try:
        per_revolution = sc.revolution_period_s / sc.engine_step_s("tmm")
    except Exception:                # no crank speed: no revolution is stored
        return 0.0
    gauges = len(sc.gauges)
    outputs = 1 + 2 * gauges
    # ~3 force components a joint (n_links + 1 joints at most), 3 DOFs a node (segments + links)
    joint_forces, dofs = 3 * (n_links + 1), 3 * (segments + n_links)
    return 8.0 * per_revolution * outputs * (joint_forces + 6 * gauges + 1 + dofs + 1)


def _tmm_step_s(sc: Scenario, segments: int, macro_per_step: float) -> float:
    """Wall time per step of the transfer-matrix engine [s]: its compiled march where the structure
    qualifies and a revolution's stored factorizations fit the time domain's memory budget (the
    engine's own test, :meth:`tmm_core.TimeDomain.configurations`), else the numpy path."""
    try:
        from tmm_core import backend, discretization
        from tmm_core.compiled import statics as compiled_statics
        budget = discretization.MAX_STEP_DATA_BYTES
        per_revolution = sc.revolution_period_s / sc.engine_step_s("tmm")
        structure = sc.mechanism.structure()
        compiled = (backend.choose_backend(None) == "compiled" and compiled_statics.supported(structure)
                    and per_revolution * compiled_statics.stored_bytes_per_configuration(
                        [m.n_segments for m in structure.members]) <= budget)
    except Exception:                # no crank speed, no structure: the numpy path's estimate
        compiled = False
    if compiled:
        return _TMM_COMPILED_STEP_S + _TMM_COMPILED_SEGMENT_S * segments + _TMM_MACRO_S * macro_per_step
    return _numpy_step_s(segments)


def tmm_numpy_seconds(sc: Scenario, duration_s: float) -> float:
    """Wall time [s] of the transfer-matrix engine's numpy path over ``duration_s`` simulated (the
    measured per-step cost above; 1.2 ms a step was measured on the FE rig's prescribed run, its
    set-up 0.1 s)."""
    return duration_s / sc.engine_step_s("tmm") * _numpy_step_s(_mesh(sc)[1])


def _mesh(sc: Scenario) -> tuple:
    """``(links, segments)``: the mechanism's links and their mesh segments in all."""
    try:
        links = list(sc.mechanism.links())
        return links, sum(int(link.total_segments) for link in links)
    except Exception:                # a mechanism without links() (none today): its size is unknown
        return [], _TMM_SEGMENTS


def _numpy_step_s(segments: int) -> float:
    """Wall time per step [s] of the transfer-matrix engine's numpy path with ``segments`` in all."""
    return _TMM_STEP_S * max(1.0, segments / _TMM_SEGMENTS) ** _TMM_EXPONENT


def check_cost(sc: Scenario, engines, duration_s: float, macro_step_s: float, max_hours: float = MAX_HOURS) -> dict:
    """:func:`estimate_cost`, refused with :class:`InputError` (the estimate and the setting that
    would change it) when it exceeds ``max_hours`` of wall time or :data:`MAX_MEMORY_BYTES`."""
    cost = estimate_cost(sc, engines, duration_s, macro_step_s)
    worst = max(engines, key=lambda e: cost[e]["seconds"])
    hint = (f"a coarser solver.{worst}.step, fewer {'segments' if worst == 'tmm' else 'elements'}, or fewer "
            "revolutions (--revolutions, output.max_revolutions)")
    if cost["setup_bytes"] > cost["bytes"] / 2:
        hint = f"fewer gauges ([gauges] has {len(sc.gauges)}) or a coarser solver.tmm.step"
    if not cost["bytes"] <= MAX_MEMORY_BYTES:
        raise InputError(f"scenario '{sc.path or sc.name}': refused before it started: {cost['text']}, beyond the "
                         f"{MAX_MEMORY_BYTES / 1e9:g} GB a run may hold; use {hint}")
    if not cost["seconds"] <= max_hours * 3600:
        raise InputError(f"scenario '{sc.path or sc.name}': refused before it started: {cost['text']}, beyond the "
                         f"limit of {max_hours:g} h; use {hint}, or raise the limit with --max-hours")
    return cost


def check_study(sc: Scenario, command: str, solves: dict, each: dict, workers: int | None,
                max_hours: float = MAX_HOURS) -> dict:
    """The cost of ``cosim <command>``, refused like :func:`check_cost` before any work starts.
    ``solves``: ``{"option": the option or key that sets their number, "value": its value,
    "count": the solves, "what": what one is}``; ``each``: one solve's :func:`estimate_cost` (an
    upper bound where it runs until steady). The solves share ``workers`` processes (default: the
    cores): the wall time is count x each / workers, the memory each's times the solves at once."""
    count = float(solves["count"])
    at_once = max(1.0, min(count, float(workers or os.cpu_count() or 1)))
    seconds, nbytes = count * each["seconds"] / at_once, each["bytes"] * at_once
    text = (f"{count:.3g} {solves['what']} of ({each['text']}) on {at_once:.0f} worker(s): about "
            f"{duration_text(seconds)} and {nbytes / 1e9:.3g} GB")
    head = (f"scenario '{sc.path or sc.name}': cosim {command} refused before it started "
            f"({solves['option']} = {solves['value']!r}): {text}")
    if not nbytes <= MAX_MEMORY_BYTES:
        raise InputError(f"{head}, beyond the {MAX_MEMORY_BYTES / 1e9:g} GB a command may hold; lower "
                         f"{solves['option']}, use fewer workers (--workers) or fewer gauges")
    if not seconds <= max_hours * 3600:
        raise InputError(f"{head}, beyond the limit of {max_hours:g} h; lower {solves['option']}, or raise the "
                         "limit with --max-hours")
    return {"seconds": seconds, "bytes": nbytes, "text": text}


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
