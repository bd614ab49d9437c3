"""Uncertainty bands over a scenario's declared unknowns, a global sensitivity ranking, and
whether each recorded peak lies inside the band.

The unknowns are declared in the scenario's ``[uncertainty]`` table (format and the three kinds
of keys: :mod:`cosim.unknowns`)::

    [uncertainty]
    samples = 24                 # Latin hypercube samples of the band
    seed = 1
    morris_trajectories = 8      # Morris screening: trajectories of (unknowns + 1) runs each
    [uncertainty.parameters.damping]
    keys = ["links.coupler.damping.ratio", "links.rocker.damping.ratio"]
    distribution = "uniform"     # uniform | loguniform (low, high) | normal (mean, std) | choice (values)
    low = "1 %"
    high = "15 %"
    unit = "%"
    rationale = "why this range"

Every run is the transfer-matrix model marched to its steady revolution (:func:`cosim.unknowns.solve`,
4 segments at 0.5 deg); runs that differ only in how the gauges read (face, polarity) share one
solve. Runs go to a ``concurrent.futures`` executor (local processes or a Dask cluster).

* **Band**: the envelope (and the 5-95 % percentiles of the Latin hypercube samples) of the bending
  strain over the crank angle, over every sample (Latin hypercube and Morris design, the nominal
  run excluded), and the range of each +/- peak. The nominal run is the scenario as written, not a
  sample: where its values lie outside the declared ranges (a prescribed constant crank speed is
  an infinite drive inertia, outside any declared ``model.drive_inertia`` range) or at their
  edges (no gravity, no wire moment, no friction), a finite sample does not come near it and the
  nominal curve leaves the envelope. That is the design, not an error; :func:`nominal_note` says
  so on the figure and in ``summary.json``.
* **Sensitivity**: Morris elementary effects (SALib) of every +/- bending peak per gauge; ``mu*``
  is given as the change of the peak over the unknown's whole range [microstrain] (for a choice:
  between its values), and the unknowns are ranked by their mean normalized ``mu*``.
* **Records**: each recorded +/- peak of the rig at the speed, inside or outside the band of
  that peak.

Owns: ``cosim uncertainty``: the band, the Morris ranking, records inside or outside. Does not:
the unknowns and the model run are cosim.unknowns.
"""
from __future__ import annotations

import logging
import textwrap
import time
from pathlib import Path

import numpy as np

from tmm_core.compiled.cache import PERIODIC_COMPILE_ESTIMATE_S

from .figures import gauge_label, new_figure, save
from .parallel import executor
from .records import peaks_at, records_for
from .run_guards import MAX_HOURS, check_study
from .run_progress import compile_notice
from .runlog import run_folder, write_csv, write_json
from .scenario import ScenarioError, check_unknowns, load
from .unknowns import Settings, declared, read, solve_cost, solve_job, variant

log = logging.getLogger(__name__)
PEAKS = (("+", "bending_max_ue"), ("-", "bending_min_ue"))


def parameters(raw: dict, path: str = "<scenario>") -> tuple:
    """``(samples, seed, {name: description})`` of the declared unknowns (see :func:`cosim.unknowns.declared`)."""
    n, seed, unknowns, _ = declared(raw, path)
    return n, seed, {k: u.describe() for k, u in unknowns.items()}


def nominal_note(unknowns: dict) -> str:
    """Why the nominal curve may leave the envelope (shown under the band figure, kept in
    ``summary.json``): it is the scenario as written, not a sample."""
    note = ("nominal: the scenario as written, not one of the samples; the envelope is the range of the "
            "samples, so the nominal leaves it where its values lie outside or at the edge of the declared ranges")
    inertia = [name for name, u in unknowns.items() if "model.drive_inertia" in u.keys]
    if inertia:
        note += (f" (here: it turns the crank at a constant speed, an infinite drive inertia, outside the declared "
                 f"'{inertia[0]}' range)")
    return note


def draw(unknowns: dict, n: int, seed: int) -> list:
    """``n`` Latin hypercube samples ``{name: value}`` (each unknown's range split in ``n``
    strata; a normal unknown through its quantiles, a choice through equal shares)."""
    rng = np.random.default_rng(seed)
    out = [{} for _ in range(n)]
    for name, u in unknowns.items():
        q = (rng.permutation(n) + rng.random(n)) / n
        for s, x in zip(out, q):
            s[name] = u.at(x)
    return out


def morris_design(unknowns: dict, trajectories: int, seed: int) -> tuple:
    """``(problem, X (runs, unknowns) in [0, 1], samples)``: a Morris design of ``trajectories``
    trajectories on 4 levels (SALib)."""
    from SALib.sample import morris
    names = list(unknowns)
    problem = {"num_vars": len(names), "names": names, "bounds": [[0.0, 1.0]] * len(names)}
    X = morris.sample(problem, N=trajectories, num_levels=4, seed=seed)
    return problem, X, [{n: unknowns[n].at(x) for n, x in zip(names, row)} for row in X]


def evaluate(sc, unknowns: dict, samples: list, settings: Settings = Settings(), workers=None, scheduler=None,
             desc: str | None = None) -> list:
    """The model read at every sample (``None`` as a sample: the scenario as it is): one solve per
    distinct physics, the gauge readings applied per sample."""
    variants = [variant(sc, unknowns, s or {}) for s in samples]
    jobs, index = [], {}
    for v in variants:
        key = v.physics_key()
        if key not in index:
            index[key] = len(jobs)
            jobs.append((sc.raw, str(sc.path or sc.name), v.overrides, v.model, settings))
    log.debug("%d runs, %d distinct solves", len(samples), len(jobs))
    results = parallel_map(solve_job, jobs, workers, scheduler, desc=desc)
    return [read(results[index[v.physics_key()]], v.signs) for v in variants]


def morris_ranking(problem, X, outputs: list, unknowns: dict, gauges, seed: int = 1) -> dict:
    """Morris ``mu*`` per gauge and peak (as the change over the unknown's range [ue]) and the
    ranking by mean normalized ``mu*``; trajectories with a failed run are left out."""
    from SALib.analyze import morris
    D = problem["num_vars"]
    ok = np.array([o.get("status") == "completed" for o in outputs]).reshape(-1, D + 1).all(1)
    if not ok.any():
        return {"method": "morris", "error": "no complete trajectory"}
    rows = np.repeat(ok, D + 1)
    Xk = X[rows]
    good = [o for o, r in zip(outputs, rows) if r]
    delta = 4 / (2 * (4 - 1))
    mu, score = {}, np.zeros(D)
    for g in gauges:
        mu[g] = {}
        for peak, key in PEAKS:
            Y = np.array([o["peaks"][g][key] for o in good])
            res = morris.analyze(problem, Xk, Y, num_levels=4, seed=seed)
            scale = np.array([delta if unknowns[n].discrete else 1.0 for n in problem["names"]])
            m = np.asarray(res["mu_star"], float) * scale
            mu[g][peak] = {n: float(v) for n, v in zip(problem["names"], m)}
            if m.max() > 0:
                score += m / m.max()
    score /= max(len(gauges) * len(PEAKS), 1)
    order = np.argsort(-score)
    return {"method": "morris", "trajectories_used": int(ok.sum()), "trajectories": int(len(ok)),
            "mu_star_ue": mu, "ranking": [{"unknown": problem["names"][i], "score": float(score[i])} for i in order]}


def run_uncertainty(scenario: str, samples: int | None = None, seed: int | None = None, workers: int | None = None,
                    scheduler: str | None = None, out: Path | None = None, record: bool = True,
                    sensitivity: bool = True, progress: bool = True, records_dir: Path | None = None,
                    trajectories: int | None = None, settings: Settings = Settings(),
                    max_hours: float = MAX_HOURS) -> tuple:
    """Band, Morris ranking, record check; returns ``(folder, summary)``. ``progress``: a bar
    over the solves (auto-off when stderr is not a terminal); ``records_dir``: where the records
    checked against the band come from (default: the shipped records); ``max_hours``: refuse a
    run estimated to take longer (:func:`cosim.run_guards.check_study`, before any solve)."""
    sc = load(scenario)
    check_unknowns(sc)                          # before any sample runs (each would fail alike)
    n_default, seed_default, unknowns, options = declared(sc.raw, str(sc.path))
    n = samples if samples is not None else n_default
    seed = seed if seed is not None else seed_default
    r = trajectories if trajectories is not None else int(options.get("morris_trajectories", 8))
    if n < 2:
        raise ScenarioError("an uncertainty run needs at least 2 samples")
    if sensitivity and r < 2:
        raise ScenarioError("a Morris ranking needs at least 2 trajectories")
    # Each sample and each of a trajectory's k + 1 points is a solve, and so is the nominal.
    option, value = ("--samples", n) if samples is not None else ("uncertainty.samples", n)
    check_study(sc, "uncertainty", {"option": option, "value": value,
                                    "count": 1 + n + (r * (len(unknowns) + 1) if sensitivity else 0),
                                    "what": "solves (samples, Morris trajectories, the nominal)"},
                solve_cost(sc, settings), workers, max_hours)
    folder = run_folder(f"{sc.name}-uncertainty", out)
    log.info("uncertainty of %s: %d samples%s; results to %s", sc.name, n,
             f" + Morris {r} trajectories" if sensitivity else "", folder)
    compile_notice(PERIODIC_COMPILE_ESTIMATE_S)
    summary = {"scenario": sc.name, "status": "incomplete", "samples": n, "seed": seed,
               "model": {"engine": "tmm", "segments": settings.segments, "step_deg": settings.step_deg,
                         "method": "time marching to the steady revolution"},
               "parameters": {k: u.describe() for k, u in unknowns.items()}}
    write_json(folder / "summary.json", summary)
    lhs = draw(unknowns, n, seed)
    design = morris_design(unknowns, r, seed) if sensitivity else (None, None, [])
    runs = [None] + lhs + design[2]
    tic = time.perf_counter()
    try:
        results = evaluate(sc, unknowns, runs, settings, workers, scheduler,
                           desc=f"uncertainty {sc.name}" if progress else None)
    except KeyboardInterrupt:
        summary["status"] = "interrupted"        # the samples are lost with the workers: nothing to keep
        write_json(folder / "summary.json", summary)
        raise
    nominal, mc, mo = results[0], results[1:1 + n], results[1 + n:]
    summary["wall_time_s"] = time.perf_counter() - tic
    summary["failed_samples"] = [f"sample {i}: {x.get('error')}" for i, x in enumerate(mc + mo)
                                 if x.get("status") != "completed"]
    every = [x for x in mc + mo if x.get("status") == "completed"]
    if nominal.get("status") != "completed" or len(every) < 2:
        summary["status"] = "failed"
        summary["error"] = nominal.get("error") or "fewer than two samples solved"
        write_json(folder / "summary.json", summary)
        return folder, summary
    summary.update(band_summary(nominal, every, [x for x in mc if x.get("status") == "completed"]))
    summary["nominal_note"] = nominal_note(unknowns)
    rows = summary.pop("_rows")
    if sensitivity:
        summary["sensitivity"] = morris_ranking(design[0], design[1], mo, unknowns, list(nominal["gauges"]), seed)
        rank = summary["sensitivity"].get("mu_star_ue", {})
        summary["most_influential"] = {g: max(((k, sum(p[k] for p in rank[g].values())) for k in unknowns),
                                              key=lambda kv: kv[1])[0] for g in rank}
    summary["records"] = record_check(sc, summary["band"], records_dir)
    summary["status"] = "completed" if not summary["failed_samples"] else "completed with failed samples"
    write_csv(folder / "band.csv", rows)
    summary["figures"] = [p.name for p in plot_band(folder, sc.name, rows, summary["records"],
                                                    summary["nominal_note"])]
    write_json(folder / "summary.json", summary)
    if record:
        _record(folder / "uncertainty.rrd", sc, rows, summary["records"])
    return folder, summary


def band_summary(nominal: dict, runs: list, random_runs: list) -> dict:
    """``{"band": {gauge: peak ranges, nominal}, "_rows": the band over crank angle}``."""
    grid = nominal["angle_deg"]
    bands, rows = {}, []
    for g in nominal["gauges"]:
        H = np.array([x["gauges"][g]["bending_ue"] for x in runs])
        R = np.array([x["gauges"][g]["bending_ue"] for x in random_runs]) if len(random_runs) >= 2 else H
        lo, hi = H.min(0), H.max(0)
        p5, p95 = np.percentile(R, 5, axis=0), np.percentile(R, 95, axis=0)
        nom = np.asarray(nominal["gauges"][g]["bending_ue"])
        mx = np.array([x["peaks"][g]["bending_max_ue"] for x in runs])
        mn = np.array([x["peaks"][g]["bending_min_ue"] for x in runs])
        bands[g] = {"peak_max_range_ue": [float(mx.min()), float(mx.max())],
                    "peak_min_range_ue": [float(mn.min()), float(mn.max())],
                    "nominal_max_ue": nominal["peaks"][g]["bending_max_ue"],
                    "nominal_min_ue": nominal["peaks"][g]["bending_min_ue"],
                    "nominal_inside_envelope": float(np.mean((nom >= lo - 1e-9) & (nom <= hi + 1e-9)))}
        for k, a in enumerate(grid):
            rows.append({"gauge": g, "crank_angle_deg": a, "nominal_ue": nom[k], "low_ue": lo[k], "high_ue": hi[k],
                         "p5_ue": p5[k], "p95_ue": p95[k]})
    return {"band": bands, "_rows": rows}


def record_check(sc, bands, records_dir=None) -> list:
    """Is each recorded +/- bending peak inside the band of the predicted peaks?"""
    rpm = sc.drive.speed_rpm
    out = []
    for rec in records_for(sc, records_dir):
        if rec.format != "peaks":
            continue
        for g, p in peaks_at(rec, rpm).items():
            if g not in bands:
                continue
            b = bands[g]
            for side, rng_key, val_key in (("+", "peak_max_range_ue", "bending_max_ue"),
                                           ("-", "peak_min_range_ue", "bending_min_ue")):
                v = p.get(val_key)
                if v is None:
                    continue
                lo, hi = b[rng_key]
                out.append({"record": rec.name, "title": rec.title, "kind": rec.kind, "gauge": g, "peak": side,
                            "recorded_ue": v, "band_ue": [lo, hi], "inside": bool(lo <= v <= hi),
                            "outside_by": 0.0 if lo <= v <= hi else float(v / (hi if v > hi else lo) - 1.0)})
    return out


def parallel_map(fn, argsets, workers, scheduler, desc: str | None = None):
    """``fn(*a)`` for every argument set, in order, on ``workers`` local processes or a Dask
    ``scheduler`` (:func:`cosim.parallel.executor`); a bar over the finished solves when ``desc``.
    Shared by the band (here) and the identification (:mod:`cosim.identify`)."""
    from concurrent.futures import as_completed

    from tqdm import tqdm
    with executor(workers, scheduler) as ex:
        futures = [ex.submit(fn, *a) for a in argsets]
        with tqdm(total=len(futures), desc=desc, unit="solve", disable=None if desc else True) as bar:
            for _ in as_completed(futures):
                bar.update(1)
        return [f.result() for f in futures]


def plot_band(folder, name, rows, records, note: str = ""):
    """``band.png`` and ``band.svg``: per gauge the envelope and 5-95 % band of the samples' bending
    strain [µε] over the crank angle [deg], the nominal curve, the recorded peaks; ``note`` (see
    :func:`nominal_note`) under the panels."""
    gauges = sorted({r["gauge"] for r in rows})
    fig = new_figure(figsize=(6.5 * len(gauges), 4.6), layout="constrained")
    axes = fig.subplots(1, len(gauges), squeeze=False)
    for ax, g in zip(axes[0], gauges):
        rr = [r for r in rows if r["gauge"] == g]
        a = [r["crank_angle_deg"] for r in rr]
        ax.fill_between(a, [r["low_ue"] for r in rr], [r["high_ue"] for r in rr], alpha=0.25,
                        label="envelope of the samples")
        ax.fill_between(a, [r["p5_ue"] for r in rr], [r["p95_ue"] for r in rr], alpha=0.35, label="5-95 %")
        ax.plot(a, [r["nominal_ue"] for r in rr], "k", lw=1, label="nominal (scenario as written, not a sample)")
        for rec in records:
            if rec["gauge"] == g:
                ax.axhline(rec["recorded_ue"], ls="--" if rec["peak"] == "+" else "-.", color="C3",
                           label=f"{rec.get('title') or rec['record']} {rec['peak']}peak "
                                 f"({'inside' if rec['inside'] else 'outside'} the band)")
        ax.set_title(f"{name}: {gauge_label(g)}, bending")
        ax.set_xlabel("crank angle [deg]")
        ax.set_ylabel("bending strain [µε]")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2)   # under the axis, off the band
        ax.grid(alpha=0.3)
    if note:
        fig.supxlabel(textwrap.fill(note, 110 * len(gauges)), fontsize=7)      # ~110 characters a panel
    return save(fig, folder, "band")


def _record(path, sc, rows, records) -> None:
    """The band over crank angle with the recorded peaks as 2D charts in rerun
    (:func:`cosim.recording.summaries.uncertainty_recording`)."""
    from .recording.summaries import uncertainty_recording
    uncertainty_recording(path, sc.name, rows, records)
