"""Identification: calibrate chosen declared unknowns against the records of some scenarios, then
predict held-out scenarios without ever reading their records during the fit.

``cosim identify crank_rocker_241rpm --validate crank_rocker_95rpm,crank_rocker_373rpm``:

1. **Inputs, checked before any solve**: the unknowns must be declared in every scenario's
   ``[uncertainty]`` table with the same range (default: its ``identify`` list); calibration and
   validation sets must not overlap; every calibration scenario needs a peaks record of its rig at
   its speed (``kind`` measurement or synthetic; published models are never calibrated against).
2. **Fit**: bounded least squares (``scipy.optimize.least_squares``, trust-region reflective) of
   the +/- bending peaks of every gauge, each residual ``(model - record) / sigma`` with
   ``sigma = sqrt((relative * record)^2 + absolute^2)`` (default 10 % and 5 microstrain: Table I
   gives averaged peaks of recorder traces the author calls noisy), over the continuous unknowns
   scaled to [0, 1] of their declared ranges (log for a loguniform range), from several starts.
   Discrete unknowns (a choice) are enumerated; a gauge's face and polarity only flip its sign,
   so they are enumerated as one sign per gauge. The model is :func:`cosim.unknowns.solve`.
3. **Confidence**: the covariance ``s^2 (J^T J)^-1`` of the scaled unknowns at the optimum, with
   ``s^2 = max(1, chi^2 per degree of freedom)``: the records' stated sigma, inflated when the
   model misses them by more than it (with no degree of freedom the sigma model is taken as it
   stands); mapped to each unknown's unit; an unknown at a bound of its range or in a direction
   the records do not constrain is flagged.
4. **Validation**: only after the fit, every held-out scenario is predicted at the identified
   values and its records are read. A prediction's 1-sigma propagates the covariance of the
   identified unknowns with their declared ranges as a prior (variance 1/12 of the range squared),
   so an unknown the calibration cannot see spreads the prediction over its range, not beyond;
   unknowns that are not identified keep the scenario's values and add nothing to it.
   ``validation.<scenario>.<gauge>.<peak>.error = model / record - 1``.

Output folder: ``identification.json``, ``identification.png/.svg`` (recorded against predicted
peaks with the strain over the revolution, per scenario and gauge) and ``identification.rrd``.

Owns: the identification behind ``cosim identify``: calibration, confidence, held-out validation.
Boundaries: held-out records are read only after the fit; the model run is cosim.unknowns; the
command's options are read by cosim.commands.identify and its table written by cosim.report (this module
returns the result and writes the output folder).
"""
from __future__ import annotations

import itertools
import logging
import math
import time
from pathlib import Path

import numpy as np

from tmm_core.compiled.cache import PERIODIC_COMPILE_ESTIMATE_S

from .identify_report import plot, record_rrd
from .records import peaks_at, records_for
from .run_guards import MAX_HOURS, check_study
from .run_progress import compile_notice
from .runlog import run_folder, write_json
from .scenario import ScenarioError, check_unknowns, from_dict, load
from .uncertainty import evaluate, parallel_map
from .unknowns import Settings, declared, read, solve, solve_cost, variant

log = logging.getLogger(__name__)
PEAKS = (("+", "bending_max_ue"), ("-", "bending_min_ue"))
CALIBRATION_KINDS = ("measurement", "synthetic")


class IdentificationError(ScenarioError):
    """Bad input to an identification (refused before any solve)."""


def rpm_of(sc) -> float:
    return sc.drive.speed_rpm


def record_peaks(sc, records_dir=None) -> tuple:
    """``({gauge: {"+": ue, "-": ue}}, [record descriptions])`` of the scenario's peaks records
    (measurement or synthetic) at its speed; only gauges the scenario has."""
    gauges = {g.name for g in sc.gauges}
    peaks, used = {}, []
    for rec in records_for(sc, records_dir):
        if rec.format != "peaks" or rec.kind not in CALIBRATION_KINDS:
            continue
        got = False
        for g, p in peaks_at(rec, rpm_of(sc)).items():
            if g not in gauges:
                continue
            for side, key in PEAKS:
                if p.get(key) is not None:
                    peaks.setdefault(g, {})[side] = float(p[key])
                    got = True
        if got:
            used.append({"record": rec.name, "kind": rec.kind, "title": rec.title, "path": str(rec.path)})
    return peaks, used


def _sigma(value, rel, absolute):
    return math.sqrt((rel * value) ** 2 + absolute ** 2)


def check_inputs(calibration, validation, parameters, records_dir=None) -> dict:
    """Load and check everything (no solve, no validation record read): returns the plan."""
    calibration, validation = list(calibration), list(validation or [])
    if not calibration:
        raise IdentificationError("identify: give at least one calibration scenario")
    cal = [load(s) for s in calibration]
    val = [load(s) for s in validation]

    def ident(sc):
        return str(Path(sc.path).resolve()) if sc.path else sc.name
    overlap = sorted({sc.name for sc in cal if ident(sc) in {ident(v) for v in val}})
    if overlap:
        raise IdentificationError(f"identify: {', '.join(overlap)} is in both the calibration and the validation set; "
                                  "a held-out scenario must not be calibrated on")
    if len({ident(s) for s in cal}) < len(cal) or len({ident(s) for s in val}) < len(val):
        raise IdentificationError("identify: a scenario is given twice")
    declared_by = {}
    for sc in cal + val:
        check_unknowns(sc)                      # before any fit runs (each would fail alike)
        declared_by[sc.name] = declared(sc.raw, str(sc.path or sc.name))[2]
    unknowns = declared_by[cal[0].name]
    if parameters is None:
        parameters = declared(cal[0].raw, str(cal[0].path))[3].get("identify")
        if not parameters:
            raise IdentificationError(f"identify: name the unknowns to calibrate (--parameters), or list them as "
                                      f"[uncertainty] identify = [...] in '{cal[0].path}'")
    parameters = list(dict.fromkeys(parameters))
    for name in parameters:
        for sc in cal + val:
            u = declared_by[sc.name]
            if name not in u:
                raise IdentificationError(f"identify: unknown {name!r} is not declared in [uncertainty.parameters] of "
                                          f"'{sc.path or sc.name}' (declared: {', '.join(u)})")
            if u[name].describe() != unknowns[name].describe():
                raise IdentificationError(f"identify: unknown {name!r} is declared differently in '{sc.name}' and "
                                          f"'{cal[0].name}'; an identified value must mean the same in every scenario")
    targets, used = {}, {}
    for sc in cal:
        peaks, recs = record_peaks(sc, records_dir)
        if not peaks:
            raise IdentificationError(f"identify: scenario '{sc.name}' ({sc.path}) has no peaks record (measurement or "
                                      f"synthetic) of "
                                      f"its rig {sc.rig!r} at {rpm_of(sc):.6g} rpm to calibrate against (records in "
                                      f"{records_dir or 'scenarios/records'})")
        targets[sc.name], used[sc.name] = peaks, recs
    return {"calibration": cal, "validation": val, "unknowns": unknowns, "parameters": parameters,
            "targets": targets, "records": used}


def _combos(unknowns, names, gauges) -> list:
    """Distinct discrete choices: ``[(physical {name: value}, signs {gauge: (b, a)}, labels)]``."""
    discrete = [n for n in names if unknowns[n].discrete]
    out, seen = [], set()
    for values in itertools.product(*(unknowns[n].values for n in discrete)):
        choice = dict(zip(discrete, values))
        phys = {n: v for n, v in choice.items() if not unknowns[n].measurement_only}
        meas = {n: v for n, v in choice.items() if unknowns[n].measurement_only}
        key = (tuple(sorted(phys.items(), key=str)),
               tuple(sorted(variant(_Gauges(gauges), unknowns, meas).signs.items())))
        if key not in seen:
            seen.add(key)
            out.append(choice)
    return out or [{}]


class _Gauges:
    """Stand-in scenario for the reading signs of a choice (faces relative to the gauges' own)."""

    def __init__(self, gauges):
        self.gauges, self.name, self.path = gauges, "scenario", None


def _sample(unknowns, continuous, x, choice) -> dict:
    return {**{n: unknowns[n].at(u) for n, u in zip(continuous, x)}, **choice}


class Model:
    """Peaks of the calibration scenarios at a point of the scaled unknowns, one solve per
    scenario and distinct physics (cached)."""

    def __init__(self, scenarios, unknowns, continuous, settings):
        self.scenarios, self.unknowns, self.continuous, self.settings = scenarios, unknowns, continuous, settings
        self.cache, self.solves = {}, 0

    def peaks(self, sc, x, choice) -> dict:
        v = variant(sc, self.unknowns, _sample(self.unknowns, self.continuous, x, choice))
        key = (sc.name, v.physics_key())
        if key not in self.cache:
            target = sc.with_overrides(v.overrides) if v.overrides else sc
            self.cache[key] = solve(target, v.model, self.settings)
            self.solves += 1
        res = read(self.cache[key], v.signs)
        if res.get("status") != "completed":
            raise RuntimeError(f"{sc.name}: {res.get('error')}")
        return res


def residuals(model: Model, targets: dict, x, choice, rel, absolute) -> np.ndarray:
    out = []
    for sc in model.scenarios:
        p = model.peaks(sc, x, choice)["peaks"]
        for g, sides in sorted(targets[sc.name].items()):
            for side, key in PEAKS:
                if side in sides:
                    out.append((p[g][key] - sides[side]) / _sigma(sides[side], rel, absolute))
    return np.array(out)


def fit_job(scenarios_raw, unknowns, continuous, choice, x0, targets, settings, rel, absolute, max_nfev) -> dict:
    """One bounded least-squares fit (a worker job): one choice of the discrete unknowns, one start."""
    from scipy.optimize import least_squares

    scs = [from_dict(raw, path) for raw, path in scenarios_raw]
    model = Model(scs, unknowns, continuous, settings)
    tic = time.perf_counter()
    try:
        if continuous:
            res = least_squares(lambda x: residuals(model, targets, x, choice, rel, absolute), np.asarray(x0, float),
                                bounds=(0.0, 1.0), method="trf", diff_step=1e-3, x_scale=1.0, max_nfev=max_nfev)
            x, r, jac, status = res.x, res.fun, res.jac, res.message
        else:
            x, jac, status = np.zeros(0), np.zeros((0, 0)), "no continuous unknowns"
            r = residuals(model, targets, x, choice, rel, absolute)
    except RuntimeError as exc:
        return {"choice": choice, "x0": list(x0), "status": "failed", "error": str(exc), "cost": math.inf}
    return {"choice": choice, "x0": list(x0), "status": "completed", "message": status, "x": x.tolist(),
            "fun": r.tolist(), "jac": np.asarray(jac).tolist(), "cost": float(0.5 * r @ r), "solves": model.solves,
            "wall_time_s": time.perf_counter() - tic}


def _check_cost(cal, choices: int, starts: int, solves_per_fit: int, settings, workers, max_hours) -> None:
    """Refuse an identification whose fits cannot finish (:func:`cosim.run_guards.check_study`):
    ``choices`` x ``starts`` fits, each ``solves_per_fit`` solves (scipy's ``max_nfev``, which
    leaves out the Jacobians' finite differences; fits stop well before it and reuse solves) of
    every calibration scenario (the dearest's cost)."""
    each = max((solve_cost(sc, settings) for sc in cal), key=lambda c: c["seconds"])
    check_study(cal[0], "identify", {"option": "--starts", "value": starts,
                                     "count": choices * starts * solves_per_fit * len(cal),
                                     "what": f"solves ({choices} choice(s) x {starts} start(s), at most "
                                             f"{solves_per_fit} evaluations a fit and scenario)"}, each, workers, max_hours)


def _confidence(unknowns, continuous, best, m) -> tuple:
    """Per continuous unknown: value, 1-sigma, 95 % interval, flags; and the correlation matrix."""
    x = np.array(best["x"])
    J = np.array(best["jac"]).reshape(m, len(continuous))
    r = np.array(best["fun"])
    p = len(continuous)
    dof = m - p
    s2 = max(1.0, float(r @ r / dof)) if dof > 0 else 1.0
    sv = np.linalg.svd(J, compute_uv=False) if p else np.zeros(0)
    cov = s2 * np.linalg.pinv(J.T @ J, rcond=1e-10) if p else np.zeros((0, 0))
    weak = np.zeros(p, bool)
    if p:
        _, s, Vt = np.linalg.svd(J, full_matrices=True)
        s = np.concatenate([s, np.zeros(max(0, p - len(s)))])
        for k in range(p):
            if s[k] < 1e-3 * max(s[0], 1e-300):
                weak |= np.abs(Vt[k]) > 0.3
    out = {}
    for i, n in enumerate(continuous):
        u = unknowns[n]
        su = math.sqrt(max(cov[i, i], 0.0))
        value = u.at(x[i])
        lo, hi = u.at(max(0.0, x[i] - 1.96 * su)), u.at(min(1.0, x[i] + 1.96 * su))
        out[n] = {"value": value, "unit": u.unit, "sigma": su * abs(u.dvalue_du(x[i])), "interval95": [lo, hi],
                  "scaled_value": float(x[i]), "scaled_sigma": su, "range": list(u.bounds()),
                  "at_bound": bool(x[i] < 1e-3 or x[i] > 1 - 1e-3),
                  "constrained": bool(not weak[i] and su < 0.5), "rationale": u.rationale}
    corr = None
    if p:
        d = np.sqrt(np.maximum(np.diag(cov), 1e-300))
        corr = {a: {b: float(cov[i, j] / (d[i] * d[j])) for j, b in enumerate(continuous)} for i, a in enumerate(continuous)}
    return out, corr, {"chi2": float(r @ r), "peaks": m, "unknowns": p, "dof": dof, "s2": s2,
                       "singular_values": [float(v) for v in sv]}


def _starting_points(n: int, starts: int, seed: int) -> list:
    """The fits' starts in the ``n`` scaled unknowns: mid-range, then random points (one start
    when nothing is continuous: every start would be the same fit)."""
    rng = np.random.default_rng(seed)
    x0s = [[0.5] * n] + [rng.random(n).tolist() for _ in range(max(0, starts - 1))]
    return x0s if n else x0s[:1]


def _fit_record(plan: dict, settings: Settings, sigma: tuple, fits: list) -> dict:
    """The identification's record before its outcome: the scenarios, the unknowns identified,
    the model's settings, the sigma model (relative, absolute [microstrain]) and every fit."""
    cal, val = plan["calibration"], plan["validation"]
    return {"status": "failed", "calibration_scenarios": [sc.name for sc in cal],
            "calibration_rpm": [rpm_of(sc) for sc in cal], "validation_scenarios": [sc.name for sc in val],
            "identified": plan["parameters"], "settings": {"segments": settings.segments,
                                                           "step_deg": settings.step_deg,
                                                           "tolerance": settings.tolerance,
                                                           "method": "time marching to the steady revolution "
                                                                     "(cosim.unknowns.solve)"},
            "sigma_model": {"relative": sigma[0], "absolute_ue": sigma[1]},
            "records_used": plan["records"], "fits": [{k: f.get(k) for k in ("choice", "x0", "status", "cost",
                                                                              "message", "error", "solves")}
                                                       for f in fits]}


def _identified(result: dict, plan: dict, continuous: list, best: dict, ok: list) -> None:
    """Record the best fit in ``result``: each unknown's value with its confidence (continuous) or
    its cost per value (discrete), the statistics and how each gauge is read at the best choice."""
    cal, unknowns, names = plan["calibration"], plan["unknowns"], plan["parameters"]
    params, corr, stats = _confidence(unknowns, continuous, best, len(best["fun"]))
    where = [f"{sc.name} ({rpm_of(sc):.0f} rpm)" for sc in cal]
    for n in params:
        params[n]["identified_at"] = where
    choice = best["choice"]
    for n, v in choice.items():
        alternatives = sorted({(str(f["choice"].get(n)), f["cost"]) for f in ok}, key=lambda t: t[1])
        params[n] = {"value": v, "discrete": True, "identified_at": where, "rationale": unknowns[n].rationale,
                     "best_cost_per_value": {a: c for a, c in reversed(alternatives)}}
    signs = variant(cal[0], unknowns, {n: v for n, v in choice.items() if unknowns[n].measurement_only}).signs
    result.update(status="completed", parameters=params, correlation=corr, statistics=stats,
                  best_choice=choice, wall_time_s=None,
                  reading={g.name: {"bending_sign": signs.get(g.name, (1, 1))[0], "axial_sign": signs.get(g.name, (1, 1))[1],
                                    "declared_face": g.face} for g in cal[0].gauges},
                  reading_note="a gauge's bending sign is its face times its polarity: Table I's peaks cannot tell "
                               "them apart (its axial strains are printed as magnitudes)")
    result["fixed"] = {n: "the scenario's own value" for n in unknowns if n not in names}


def _prediction_covariance(best: dict, n: int, s2: float) -> np.ndarray:
    """The predictions' covariance in the ``n`` scaled continuous unknowns: the records'
    information (the best fit's Jacobian over ``s2``) plus the declared ranges as a prior (a
    uniform range's variance, 1/12 of its width squared, in the scaled unknowns), so that an
    unknown the records leave open spreads a prediction over its range, not beyond it."""
    if not n:
        return np.zeros((0, 0))
    J = np.array(best["jac"]).reshape(len(best["fun"]), n)
    return np.linalg.inv(J.T @ J / s2 + 12.0 * np.eye(n))


def _validated(result: dict, plan: dict, preds: dict, sigma: tuple, records_dir) -> None:
    """Record in ``result`` the calibrated model against the calibration records, then (only now
    are they read) against the held-out records, and every scenario's predicted peaks."""
    cal, val = plan["calibration"], plan["validation"]
    result["calibration"] = {}
    for sc in cal:
        result["calibration"][sc.name] = compare(preds[sc.name], plan["targets"][sc.name], *sigma)
    result["validation"], result["predictions"] = {}, {}
    for sc in val:                              # only now are the held-out records read
        peaks, used = record_peaks(sc, records_dir)
        result["validation"][sc.name] = compare(preds[sc.name], peaks, *sigma)
        result["predictions"][sc.name] = {"rpm": rpm_of(sc), "records_used": used,
                                          "note": None if peaks else "no record of the rig at this speed"}
    for sc in cal + val:
        result.setdefault("predictions", {}).setdefault(sc.name, {"rpm": rpm_of(sc)})
        result["predictions"][sc.name].update(peaks=preds[sc.name]["peaks"], sigma_ue=preds[sc.name]["sigma_ue"],
                                              nominal_peaks=preds[sc.name]["nominal"]["peaks"],
                                              speed_fluctuation=preds[sc.name]["speed_fluctuation"])


def _write(folder: Path, result: dict, preds: dict, record: bool) -> None:
    """identification.json (first without, then with the figures' names), the figure and the
    recording; a figure that cannot be drawn never loses the identification."""
    write_json(folder / "identification.json", result)
    try:
        result["figures"] = [p.name for p in plot(folder, result, preds)]
    except Exception as exc:                    # a figure never loses the identification
        log.warning("identification figure not drawn: %s", exc)
    if record:
        record_rrd(folder / "identification.rrd", result, preds)
    write_json(folder / "identification.json", result)


def identify(calibration, validation=(), parameters=None, records_dir=None, out=None, settings: Settings = Settings(),
             starts: int = 3, workers=None, scheduler=None, sigma_relative: float = 0.10, sigma_absolute_ue: float = 5.0,
             max_nfev: int | None = None, seed: int = 1, record: bool = True, progress: bool = True,
             max_hours: float = MAX_HOURS) -> tuple:
    """Calibrate, then predict the held-out scenarios; returns ``(folder, result)``. ``max_hours``:
    refuse an identification estimated to take longer (before any fit starts)."""
    plan = check_inputs(calibration, validation, parameters, records_dir)
    cal, val, unknowns, names = plan["calibration"], plan["validation"], plan["unknowns"], plan["parameters"]
    continuous = [n for n in names if not unknowns[n].discrete]
    combos = _combos(unknowns, names, cal[0].gauges)
    nfev = max_nfev or 40 * (len(continuous) + 1)
    _check_cost(cal, len(combos), starts, nfev, settings, workers, max_hours)
    x0s = _starting_points(len(continuous), starts, seed)
    tag = "+".join(sc.name for sc in cal)
    folder = run_folder(f"{tag}-identify", out)
    log.info("identify %s on %s (%d choices x %d starts); results to %s", ", ".join(names), tag, len(combos),
             len(x0s), folder)
    compile_notice(PERIODIC_COMPILE_ESTIMATE_S)
    raws = [(sc.raw, str(sc.path or sc.name)) for sc in cal]
    jobs = [(raws, unknowns, continuous, c, x0, plan["targets"], settings, sigma_relative, sigma_absolute_ue,
             nfev) for c in combos for x0 in x0s]
    tic = time.perf_counter()
    fits = parallel_map(fit_job, jobs, workers, scheduler, desc="identify" if progress else None)
    ok = [f for f in fits if f["status"] == "completed"]
    sigma = (sigma_relative, sigma_absolute_ue)
    result = _fit_record(plan, settings, sigma, fits)
    if not ok:
        result["error"] = "every fit failed: " + "; ".join(str(f.get("error")) for f in fits[:3])
        write_json(folder / "identification.json", result)
        return folder, result
    best = min(ok, key=lambda f: f["cost"])
    _identified(result, plan, continuous, best, ok)
    # The calibrated model at the optimum, with its calibration residuals (solves are fast and cached).
    x = np.array(best["x"])
    sample = _sample(unknowns, continuous, x, best["choice"])
    cov = _prediction_covariance(best, len(continuous), result["statistics"]["s2"])
    preds = predict(cal + val, unknowns, continuous, x, best["choice"], cov, settings, workers, scheduler)
    _validated(result, plan, preds, sigma, records_dir)
    result["wall_time_s"] = time.perf_counter() - tic
    result["sample"] = {k: (v if isinstance(v, (str, int)) else float(v)) for k, v in sample.items()}
    _write(folder, result, preds, record)
    return folder, result


def predict(scenarios, unknowns, continuous, x, choice, cov, settings, workers=None, scheduler=None) -> dict:
    """Peaks and histories of each scenario at ``x`` (and the nominal scenario), with the 1-sigma
    of the peaks from ``cov`` (finite differences: one more solve per continuous unknown)."""
    h = 1e-3
    out = {}
    for sc in scenarios:
        pts = [_sample(unknowns, continuous, x, choice)]
        for i in range(len(continuous)):
            xi = np.array(x, float)
            xi[i] = xi[i] + h if xi[i] + h <= 1 else xi[i] - h
            pts.append(_sample(unknowns, continuous, xi, choice))
        res = evaluate(sc, unknowns, [None] + pts, settings, workers, scheduler)
        nominal, at, steps = res[0], res[1], res[2:]
        if at.get("status") != "completed":
            out[sc.name] = {"status": "failed", "error": at.get("error"), "peaks": {}, "sigma_ue": {},
                            "nominal": nominal, "speed_fluctuation": None, "gauges": {}}
            continue
        sig = {}
        for g in at["peaks"]:
            sig[g] = {}
            for side, key in PEAKS:
                if continuous and all(s.get("status") == "completed" for s in steps):
                    d = np.array([(s["peaks"][g][key] - at["peaks"][g][key]) /
                                  (h if x[i] + h <= 1 else -h) for i, s in enumerate(steps)])
                    sig[g][side] = float(math.sqrt(max(d @ cov @ d, 0.0)))
                else:
                    sig[g][side] = 0.0 if not continuous else None
        out[sc.name] = {**at, "sigma_ue": sig, "nominal": nominal}
    return out


def compare(pred: dict, peaks: dict, rel, absolute) -> dict:
    """``{gauge: {peak: {record_ue, model_ue, sigma_ue, error, normalized}}}`` (error = model / record - 1)."""
    out = {}
    for g, sides in sorted(peaks.items()):
        for side, key in PEAKS:
            if side not in sides:
                continue
            rec = sides[side]
            mod = (pred.get("peaks") or {}).get(g, {}).get(key)
            out.setdefault(g, {})[side] = {
                "record_ue": rec, "model_ue": mod, "sigma_ue": (pred.get("sigma_ue") or {}).get(g, {}).get(side),
                "error": None if mod is None else float(mod / rec - 1.0),
                "normalized": None if mod is None else float((mod - rec) / _sigma(rec, rel, absolute))}
    return out
