"""Matched accuracy for the side-by-side benchmark (``tests.benchmarks.bench``).

For one rig and engine, under a prescribed crank at the rig's speed:

* the engine's *converged answer*: the steady-state peak-to-peak of every gauge's bending strain
  [microstrain] at its reference setting;
* a grid of settings around the scenario's own default, each run until steady, and the *cheapest
  setting* within the tolerance of that answer (``cheapest_setting``);
* every setting's peak-to-peak difference from *exudyn's* converged answer (``vs_exudyn``), so the
  engines are matched against one answer as well as against their own.

The grids are relative to the scenario's ``[solver.<engine>]`` defaults, so one rule fits the
four-bars at 95-400 rpm and the six-bar (the defaults are within 1 % of a run refined once in
every direction: tests/benchmarks/defaults_check.py, tests/test_default_settings.py). With a
default of n segments (elements) and a step h:

* tmm, exudyn: {n/2, n, 2n} x {2h, h, h/2}; the converged answer at (2n, h/2), the refinement
  defaults_check uses (the grid's finest corner is that answer, so it is not in the grid);
* mujoco (rigid links: no segment count): {4h, 2h, h}; the converged answer at h/2;
* ``quick``: the default and its coarser neighbours only, {(n, h), (n/2, h), (n, 2h)} ({2h, h}).

Each run ends when its last two revolutions agree within the scenario's ``output.steady_tolerance``
(drive torque and bending waveforms, as ``tmm_core.revolution.revolution_change``), checked at revolution
boundaries so the check costs nothing per step, or after ``max_revolutions``.
"""
from __future__ import annotations

import math
import time

import numpy as np

COUNT = {"tmm": "segments", "exudyn": "elements"}      # the engine's discretisation count key, if any


# -- settings -----------------------------------------------------------------------------------
def _step_of(raw_step, step_s: float) -> tuple:
    """(value, unit) of a scenario step: its own crank-angle or time form (a step in degrees keeps
    dividing the macro step when scaled by 2), or the typed step in seconds."""
    if isinstance(raw_step, dict):
        raw_step = raw_step.get("value")
    if isinstance(raw_step, str) and len(raw_step.split()) == 2:
        value, unit = raw_step.split()
        return float(value), unit
    return float(step_s), "s"


def default_setting(rig: str, engine: str) -> dict:
    """The scenario's own setting of ``engine``: {"segments"/"elements": n, "step": "<h> deg|s"}."""
    from cosim.scenario import load
    sc = load(rig)
    raw = (sc.raw.get("solver") or {}).get(engine) or {}
    value, unit = _step_of(raw.get("step"), sc.engine_step_s(engine))
    out = {}
    if engine in COUNT:
        out[COUNT[engine]] = int(getattr(getattr(sc, engine), COUNT[engine]))
    out["step"] = f"{value:g} {unit}"
    return out


def scaled(setting: dict, count: float = 1.0, step: float = 1.0) -> dict:
    """``setting`` with its count times ``count`` (at least 1) and its step times ``step``."""
    out = dict(setting)
    for key in ("segments", "elements"):
        if key in out:
            out[key] = max(1, int(round(out[key] * count)))
    value, unit = out["step"].split()
    out["step"] = f"{float(value) * step:g} {unit}"
    return out


def grid_for(rig: str, engine: str, quick: bool = False) -> tuple:
    """(grid, reference) around the scenario's default (module docstring)."""
    d = default_setting(rig, engine)
    if engine == "mujoco":
        grid = [scaled(d, step=s) for s in ((2, 1) if quick else (4, 2, 1))]
    else:
        pairs = [(1, 1), (0.5, 1), (1, 2)] if quick else [(c, s) for c in (0.5, 1, 2) for s in (2, 1, 0.5)
                                                              if (c, s) != (2, 0.5)]
        grid = [scaled(d, c, s) for c, s in pairs]
    return grid, scaled(d, 2, 0.5)


def _fineness(value):
    """Sort key of one setting value: a count (segments, elements) is finer when larger, a step
    ("1 deg", "2e-4 s", or a number) finer when smaller."""
    if isinstance(value, (int, np.integer)):
        return float(value)
    return -float(str(value).split()[0])


def at_least_as_fine(a: dict, b: dict) -> bool:
    """Is setting ``a`` at least as fine as ``b`` in every parameter?"""
    return a.keys() == b.keys() and all(_fineness(a[k]) >= _fineness(b[k]) for k in b)


def relative_errors(metrics: dict, reference: dict) -> dict:
    """{gauge: metrics/reference - 1} (dimensionless) over the reference's gauges."""
    return {g: float(metrics[g] / reference[g] - 1.0) for g in reference}


def cheapest_setting(results: list, reference: dict, tol: float = 0.01):
    """The cheapest result within ``tol`` (relative, every metric) of the reference whose finer
    settings in the grid are all within ``tol`` as well: a coarse setting that lands close by
    chance (a near-resonant response is not monotone in the step) does not count as converged.

    ``results``: [{"setting", "metrics": {name: value}, "cost": seconds}, ...]; ``reference``: one
    such entry (the converged answer); a result with a non-finite cost (failed, or never steady)
    is never chosen, and as a finer setting it disqualifies the coarser ones. Returns (result or
    None, [relative errors per result])."""
    errors = [max(abs(e) for e in relative_errors(r["metrics"], reference["metrics"]).values()) for r in results]
    ok = [bool(e <= tol) and bool(np.isfinite(r["cost"])) for r, e in zip(results, errors)]
    passing = [(r["cost"], i) for i, r in enumerate(results)
               if ok[i] and all(ok[j] for j, f in enumerate(results) if at_least_as_fine(f["setting"], r["setting"]))]
    if not passing:
        return None, errors
    return results[min(passing)[1]], errors


# -- one run ------------------------------------------------------------------------------------
def timed(method, total: list):
    """``method`` wrapped to add its wall time [s] to ``total[0]`` on every call."""
    def call(*args, **kw):
        tic = time.perf_counter()
        try:
            return method(*args, **kw)
        finally:
            total[0] += time.perf_counter() - tic
    return call


def scenario_for(rig: str, engine: str, setting: dict):
    """The rig with one engine's solver setting; the macro step is that engine's own step (one
    engine alone exchanges nothing, the step must divide the macro step, and in prescribed mode
    the master groups steps to ~10 deg of crank angle per call)."""
    from cosim.scenario import load
    overrides = {f"solver.{engine}.{k}": v for k, v in setting.items()}
    if "step" in setting:
        overrides["coupling.macro_step"] = setting["step"]
    return load(rig).with_overrides(overrides)


def window_ptp(t, gauges: dict, t0: float, t1: float) -> dict:
    """Peak-to-peak bending strain [microstrain] of every gauge over the samples in (t0, t1]."""
    sel = (t > t0) & (t <= t1)
    return {g: float(np.ptp(b[sel]) * 1e6) for g, (b, _) in gauges.items()}


def run_setting(rig: str, engine: str, setting: dict, max_revolutions: float, cap_s: float | None = None) -> dict:
    """One run of ``engine`` at ``setting``, until steady, ``max_revolutions`` or ``cap_s`` seconds
    of wall time (checked at revolution boundaries: a setting off the engine's fast path, e.g. a
    TMM model whose load maps exceed their memory budget, can march ~100x slower).

    Returns {"metrics": p-p per gauge over the last revolution [microstrain], "wall_s": engine
    time [s] (set-up included), "setup_s": the engine's reset [s] (model building, or the TMM's
    factorization of a revolution and its quasi-static start), "sim_s": simulated time [s],
    "revolutions": revolutions run, "steady": bool, "revolutions_to_steady": the revolution whose
    waveforms agree with the previous one (None if never), "steady_change": relative p-p change
    between the last two revolutions (NaN below two), "capped": stopped at ``cap_s``}."""
    from cosim.engines import EngineError, make_engine
    from cosim.master import CoSimulation
    from tmm_core.revolution import revolution_change
    sc = scenario_for(rig, engine, setting)
    eng = make_engine(engine)
    setup = [0.0]
    eng.reset = timed(eng.reset, setup)
    T = sc.revolution_period_s
    chunks, state = [], {"next": 2, "steady_at": None, "capped": False}
    start = time.perf_counter()

    def watch(step):
        # At each completed revolution (from the second on), compare its waveforms with the previous.
        out = step.outputs.get(engine)
        if out is None:
            return False
        out = out[0] if isinstance(out, tuple) else out
        chunks.append(out)
        if step.t < state["next"] * T * (1 - 1e-9):
            return False
        state["next"] = math.floor(step.t / T * (1 + 1e-9)) + 1
        if cap_s is not None and time.perf_counter() - start > cap_s:
            state["capped"] = True
            return True
        angle = np.concatenate([c.crank_angle for c in chunks])
        signals = [np.concatenate([c.drive_torque for c in chunks])]
        signals += [np.concatenate([c.gauges[g][0] for c in chunks]) for g in chunks[0].gauges]
        if revolution_change(angle, [x for x in signals if np.all(np.isfinite(x))]) < sc.output.steady_tolerance:
            state["steady_at"] = int(round(step.t / T))
            return True
        return False
    res = CoSimulation(sc, {engine: eng}, mode="prescribed").run(revolutions=max_revolutions, callback=watch,
                                                                until_steady=False)
    ch = res[engine]
    if ch.status == "failed":
        raise EngineError(ch.error)
    run = ch.run
    t_end = float(run.t[-1])
    Tw = T * (1 + 1e-9)
    ptp = window_ptp(run.t, run.gauges, t_end - Tw, t_end)
    change = float("nan")
    if t_end >= 2 * T * (1 - 1e-9):
        before = window_ptp(run.t, run.gauges, t_end - 2 * Tw, t_end - Tw)
        change = max(abs(before[g] / ptp[g] - 1.0) for g in ptp)
    return {"metrics": ptp, "wall_s": run.wall_time_s, "setup_s": setup[0], "sim_s": t_end,
            "revolutions": t_end / T, "steady": state["steady_at"] is not None,
            "revolutions_to_steady": state["steady_at"], "steady_change": change, "capped": state["capped"]}


def accuracy_runs(rig: str, engine: str, grid: list, reference: dict, max_revolutions: float,
                  cap_s: float | None = None) -> dict:
    """The reference and every grid setting, in one process (their costs rank the settings; each
    chosen setting is timed again in fresh processes), each run capped at ``cap_s`` seconds. A
    setting that fails is recorded."""
    def one(setting):
        try:
            return {"setting": setting, **run_setting(rig, engine, setting, max_revolutions, cap_s)}
        except Exception as exc:          # an unstable step or a refused model: not a candidate
            return {"setting": setting, "error": f"{type(exc).__name__}: {exc}"}
    return {"reference": one(reference), "grid": [one(s) for s in grid]}


def choose(runs: dict, tol: float, tiny: bool) -> dict:
    """The matched-accuracy result of ``accuracy_runs``: the grid with each setting's error
    against the engine's converged answer, and the chosen setting (or why there is none)."""
    ref = runs["reference"]
    if "error" in ref:
        return {"reference": ref, "grid": runs["grid"], "chosen": None,
                "error": f"reference run failed: {ref['error']}"}
    if not tiny and not ref["steady"]:
        # No converged steady-state answer, so matched accuracy is undefined for this engine.
        return {"reference": ref, "grid": runs["grid"], "chosen": None,
                "error": f"reference run not steady after {ref['revolutions']:.3g} revolutions "
                         f"(p-p changed {ref['steady_change']:.3g} between its last two"
                         f"{'; stopped at the run cap' if ref.get('capped') else ''})"}
    results = []
    for r in runs["grid"]:
        if "error" in r:
            results.append(dict(r, metrics={g: float("nan") for g in ref["metrics"]}, cost=float("inf")))
        else:
            # A setting still drifting (or never periodic) is not a candidate, however close it lands.
            results.append(dict(r, cost=r["wall_s"] if (tiny or r["steady"]) else float("inf")))
    best, errors = cheapest_setting(results, ref, tol)
    grid = [dict(r, error_vs_reference=e) for r, e in zip(results, errors)]
    return {"reference": ref, "grid": grid, "chosen": None if best is None else
            {"setting": best["setting"], "metrics": best["metrics"],
             "error_vs_reference": errors[results.index(best)],
             "revolutions_to_steady": best.get("revolutions_to_steady")}}


def vs_exudyn(block: dict) -> dict:
    """Each engine's chosen setting and converged answer against exudyn's converged answer:
    {engine: {"chosen": {gauge: relative p-p difference}, "chosen_max": largest |difference|,
    "converged": ..., "converged_max": ...}} (dimensionless); {} without exudyn's answer."""
    ex = block.get("exudyn")
    ref = ex.get("reference") if isinstance(ex, dict) else None
    if not ref or "metrics" not in ref:
        return {}
    out = {}
    for engine, b in block.items():
        if engine not in ("tmm", "exudyn", "mujoco") or not isinstance(b, dict):
            continue
        row = {"exudyn_converged_steady": bool(ref.get("steady"))}
        for key, src in (("chosen", b.get("chosen")), ("converged", b.get("reference"))):
            if src and "metrics" in src:
                d = relative_errors(src["metrics"], ref["metrics"])
                row[key], row[f"{key}_max"] = d, max(abs(x) for x in d.values())
        out[engine] = row
    return out
