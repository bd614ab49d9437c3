"""Uncertainty bands: Monte Carlo over the parameters a scenario declares uncertain.

A scenario's ``[uncertainty]`` table names the parameters the sources leave open and their
distributions; each parameter sets one or more keys of the scenario file::

    [uncertainty]
    samples = 32
    seed = 1
    [uncertainty.parameters.damping]
    keys = ["links.coupler.damping.ratio", "links.rocker.damping.ratio"]
    distribution = "uniform"            # uniform (low, high) | normal (mean, std) | choice (values)
    low = "1 %"
    high = "5 %"
    unit = ""                           # how a drawn number is written back ("%", "lbf", ...)

Every sample is a periodic steady-state solve of the transfer-matrix model (one revolution, no
transient), so a band of 32 samples costs about 32 periodic solves; samples run in parallel on a
``concurrent.futures`` executor (local processes, or a Dask cluster given a scheduler address).
The band is the envelope (and the 5-95 % percentiles) of the bending strain over the crank angle,
over the samples *without* the nominal run; the nominal history is reported beside it. A
one-at-a-time sensitivity (each parameter alone at its low and high end, or at each of its
choices) ranks which parameter widens the peaks most. Records of the rig at the speed are checked
against the band of the peaks.
"""
from __future__ import annotations

import copy
import logging
import math
import re
import time
from pathlib import Path

import numpy as np

from .parallel import executor
from .runlog import run_folder, write_csv, write_json
from .scenario import ScenarioError, from_dict, load

log = logging.getLogger(__name__)
N_GRID = 360
_INDEX = re.compile(r"^(\w+)\[(\d+)\]$")


def _set(raw: dict, key: str, value) -> None:
    """Set ``a.b[0].c`` in a TOML tree; a {value, ...} table keeps its other entries."""
    node = raw
    parts = key.split(".")
    for i, part in enumerate(parts):
        m = _INDEX.match(part)
        last = i == len(parts) - 1
        if m:
            name, j = m.group(1), int(m.group(2))
            if name not in node or not isinstance(node[name], list) or j >= len(node[name]):
                raise ScenarioError(f"uncertainty key '{key}': no list item {part}")
            if last:
                node[name][j] = value
                return
            node = node[name][j]
            continue
        if last:
            if isinstance(node.get(part), dict) and "value" in node[part]:
                node[part] = dict(node[part], value=value)
            else:
                node[part] = value
            return
        if part not in node or not isinstance(node[part], dict):
            raise ScenarioError(f"uncertainty key '{key}': no table '{part}'")
        node = node[part]


def parameters(raw: dict, path: str = "<scenario>") -> tuple:
    """``(samples, seed, {name: spec})`` from the scenario's [uncertainty] table."""
    from .scenario import UREG
    u = raw.get("uncertainty")
    if not isinstance(u, dict) or not isinstance(u.get("parameters"), dict) or not u["parameters"]:
        raise ScenarioError(f"scenario '{path}': an uncertainty run needs [uncertainty.parameters.<name>] tables")
    specs = {}
    for name, d in u["parameters"].items():
        key = f"uncertainty.parameters.{name}"
        keys = d.get("keys")
        if not isinstance(keys, list) or not keys:
            raise ScenarioError(f"scenario '{path}': key '{key}.keys' must list the scenario keys it sets")
        dist = d.get("distribution")
        unit = d.get("unit", "")

        def num(k):
            if k not in d:
                raise ScenarioError(f"scenario '{path}': key '{key}.{k}' is required for a {dist} distribution")
            q = UREG.Quantity(str(d[k]).replace("^", "**"))
            return float(q.to(unit).magnitude) if unit and hasattr(q, "to") else float(getattr(q, "magnitude", q))
        if dist == "uniform":
            spec = {"distribution": dist, "low": num("low"), "high": num("high")}
            if spec["high"] < spec["low"]:
                raise ScenarioError(f"scenario '{path}': key '{key}': high below low")
        elif dist == "normal":
            spec = {"distribution": dist, "mean": num("mean"), "std": num("std")}
        elif dist == "choice":
            values = d.get("values")
            if not isinstance(values, list) or not values:
                raise ScenarioError(f"scenario '{path}': key '{key}.values' must list the choices")
            spec = {"distribution": dist, "values": values}
        else:
            raise ScenarioError(f"scenario '{path}': key '{key}.distribution' = {dist!r}: uniform, normal or choice")
        spec.update(keys=keys, unit=unit, rationale=d.get("rationale", d.get("assumption", "")))
        specs[name] = spec
    return int(u.get("samples", 32)), int(u.get("seed", 1)), specs


def _value(spec, x):
    return x if spec["distribution"] == "choice" else (f"{x!r} {spec['unit']}".strip() if spec["unit"] else x)


def draw(specs: dict, n: int, seed: int) -> list:
    """``n`` samples {name: value}: Latin hypercube for uniform parameters, normal and choice drawn
    with the seeded generator."""
    rng = np.random.default_rng(seed)
    out = [{} for _ in range(n)]
    for name, spec in specs.items():
        if spec["distribution"] == "uniform":
            u = (rng.permutation(n) + rng.random(n)) / n
            vals = spec["low"] + (spec["high"] - spec["low"]) * u
        elif spec["distribution"] == "normal":
            vals = spec["mean"] + spec["std"] * rng.standard_normal(n)
        else:
            vals = [spec["values"][i] for i in rng.integers(0, len(spec["values"]), n)]
        for s, v in zip(out, vals):
            s[name] = v
    return out


def apply(raw: dict, specs: dict, sample: dict) -> dict:
    data = copy.deepcopy(raw)
    data.pop("uncertainty", None)
    for name, x in sample.items():
        for key in specs[name]["keys"]:
            _set(data, key, _value(specs[name], float(x) if isinstance(x, (np.floating, float)) else x))
    return data


def solve_sample(raw: dict, path: str, specs: dict, sample: dict) -> dict:
    """One sample: periodic TMM solve; bending/axial per gauge on the uniform angle grid [ue]."""
    from .sweep import periodic_point_histories
    sc = from_dict(apply(raw, specs, sample), path)
    return periodic_point_histories(sc)


def run_uncertainty(scenario: str, samples: int | None = None, seed: int | None = None, workers: int | None = None,
                    scheduler: str | None = None, out: Path | None = None, record: bool = True,
                    sensitivity: bool = True, progress: bool = True, records_dir: Path | None = None) -> tuple:
    """Monte Carlo band, sensitivity ranking, record check; returns ``(folder, summary)``.
    ``progress``: a bar over the solves (auto-off when stderr is not a terminal); ``records_dir``:
    where the records checked against the band come from (default: the shipped records)."""
    sc = load(scenario)
    n_default, seed_default, specs = parameters(sc.raw, str(sc.path))
    n = samples if samples is not None else n_default
    seed = seed if seed is not None else seed_default
    if n < 2:
        raise ScenarioError("an uncertainty run needs at least 2 samples")
    folder = run_folder(f"{sc.name}-uncertainty", out)
    log.info("uncertainty of %s: %d samples; results to %s", sc.name, n, folder)
    summary = {"scenario": sc.name, "status": "incomplete", "samples": n, "seed": seed,
               "parameters": {k: {kk: vv for kk, vv in v.items() if kk != "keys"} | {"keys": v["keys"]}
                              for k, v in specs.items()}}
    write_json(folder / "summary.json", summary)
    draws = draw(specs, n, seed)
    jobs = [("nominal", {})] + [(f"sample {i}", d) for i, d in enumerate(draws)]
    if sensitivity:
        for name, spec in specs.items():
            ends = (spec["values"] if spec["distribution"] == "choice" else
                    [spec["low"], spec["high"]] if spec["distribution"] == "uniform" else
                    [spec["mean"] - 2 * spec["std"], spec["mean"] + 2 * spec["std"]])
            jobs += [(f"one-at-a-time {name}={v}", {name: v}) for v in ends]
    tic = time.perf_counter()
    results = _map(solve_sample, [(sc.raw, str(sc.path), specs, d) for _, d in jobs], workers, scheduler,
                   desc=f"uncertainty {sc.name}" if progress else None)
    labels = [j[0] for j in jobs]
    nominal = results[0]
    mc = [r for lab, r in zip(labels, results) if lab.startswith("sample") and r.get("status") == "completed"]
    failed = [lab for lab, r in zip(labels, results) if r.get("status") != "completed"]
    summary["wall_time_s"] = time.perf_counter() - tic
    summary["failed_samples"] = failed
    if nominal.get("status") != "completed" or len(mc) < 2:
        summary["status"] = "failed"
        summary["error"] = nominal.get("error") or "fewer than two samples solved"
        write_json(folder / "summary.json", summary)
        return folder, summary
    grid = nominal["angle_deg"]
    bands, rows = {}, []
    for g in nominal["gauges"]:
        H = np.array([r["gauges"][g]["bending_ue"] for r in mc])
        lo, hi = H.min(0), H.max(0)
        p5, p95 = np.percentile(H, 5, axis=0), np.percentile(H, 95, axis=0)
        nom = np.asarray(nominal["gauges"][g]["bending_ue"])
        bands[g] = {"peak_max_range_ue": [float(H.max(1).min()), float(H.max(1).max())],
                    "peak_min_range_ue": [float(H.min(1).min()), float(H.min(1).max())],
                    "nominal_max_ue": float(nom.max()), "nominal_min_ue": float(nom.min()),
                    "nominal_inside_envelope": float(np.mean((nom >= lo - 1e-9) & (nom <= hi + 1e-9)))}
        for k, a in enumerate(grid):
            rows.append({"gauge": g, "crank_angle_deg": a, "nominal_ue": nom[k], "low_ue": lo[k], "high_ue": hi[k],
                         "p5_ue": p5[k], "p95_ue": p95[k]})
    summary["band"] = bands
    if sensitivity:
        ranking = {}
        for name in specs:
            runs = [r for lab, r in zip(labels, results) if lab.startswith(f"one-at-a-time {name}=")
                    and r.get("status") == "completed"]
            spread = {}
            for g in nominal["gauges"]:
                mx = [max(r["gauges"][g]["bending_ue"]) for r in runs]
                mn = [min(r["gauges"][g]["bending_ue"]) for r in runs]
                spread[g] = float(max(np.ptp(mx), np.ptp(mn))) if runs else float("nan")
            ranking[name] = spread
        summary["sensitivity_peak_spread_ue"] = ranking
        summary["most_influential"] = {g: max(ranking, key=lambda k: ranking[k][g] if ranking[k][g] == ranking[k][g]
                                              else -1) for g in nominal["gauges"]}
    summary["records"] = _record_check(sc, bands, records_dir)
    summary["status"] = "completed" if not failed else "completed with failed samples"
    write_csv(folder / "band.csv", rows)
    summary["figures"] = [p.name for p in _plot(folder, sc.name, rows, summary["records"])]
    write_json(folder / "summary.json", summary)
    if record:
        _record(folder / "uncertainty.rrd", sc, rows, summary["records"])
    return folder, summary


def _record_check(sc, bands, records_dir=None) -> list:
    """Is each recorded peak inside the band of the predicted peaks?"""
    from .records import peaks_at, records_for
    rpm = abs(sc.drive.speed_rad_s) * 30 / math.pi
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
                out.append({"record": rec.name, "title": rec.title, "gauge": g, "peak": side, "recorded_ue": v,
                            "band_ue": [lo, hi], "inside": bool(lo <= v <= hi)})
    return out


def _map(fn, argsets, workers, scheduler, desc: str | None = None):
    """``fn(*a)`` for every argument set, in order; a bar over the finished solves when ``desc``."""
    from concurrent.futures import as_completed

    from tqdm import tqdm
    with executor(workers, scheduler) as ex:
        futures = [ex.submit(fn, *a) for a in argsets]
        with tqdm(total=len(futures), desc=desc, unit="solve", disable=None if desc else True) as bar:
            for _ in as_completed(futures):
                bar.update(1)
        return [f.result() for f in futures]


def _plot(folder, name, rows, records):
    from .figures import gauge_label, new_figure, save
    gauges = sorted({r["gauge"] for r in rows})
    fig = new_figure(figsize=(6.5 * len(gauges), 4.6), layout="constrained")
    axes = fig.subplots(1, len(gauges), squeeze=False)
    for ax, g in zip(axes[0], gauges):
        rr = [r for r in rows if r["gauge"] == g]
        a = [r["crank_angle_deg"] for r in rr]
        ax.fill_between(a, [r["low_ue"] for r in rr], [r["high_ue"] for r in rr], alpha=0.25, label="envelope")
        ax.fill_between(a, [r["p5_ue"] for r in rr], [r["p95_ue"] for r in rr], alpha=0.35, label="5-95 %")
        ax.plot(a, [r["nominal_ue"] for r in rr], "k", lw=1, label="nominal")
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
    return save(fig, folder, "band")


def _record(path, sc, rows, records) -> None:
    import rerun as rr
    import rerun.blueprint as rrb
    rec = rr.RecordingStream("flexlink-bench-uncertainty", recording_id=f"{sc.name}-uncertainty")
    rec.save(str(path))
    views = []
    for g in sorted({r["gauge"] for r in rows}):
        rr_ = [r for r in rows if r["gauge"] == g]
        mdeg = np.rint(np.array([r["crank_angle_deg"] for r in rr_]) * 1000).astype(np.int64)
        vals = np.array([[r["low_ue"], r["high_ue"], r["p5_ue"], r["p95_ue"], r["nominal_ue"]] for r in rr_])
        rec.log(f"/tmm/uncertainty/{g}", rr.SeriesLines(names=["tmm band low [µε]", "tmm band high [µε]",
                                                               "tmm 5 % [µε]", "tmm 95 % [µε]", "tmm nominal [µε]"]),
                static=True)
        rec.send_columns(f"/tmm/uncertainty/{g}", indexes=[rr.TimeColumn("crank_angle_mdeg", sequence=mdeg)],
                         columns=rr.Scalars.columns(scalars=vals))
        lines = [x for x in records if x["gauge"] == g]
        if lines:
            rec.log(f"/records/peaks/{g}", rr.SeriesLines(names=[f"{x['record']} {x['peak']}peak [µε]" for x in lines]),
                    static=True)
            rec.send_columns(f"/records/peaks/{g}", indexes=[rr.TimeColumn("crank_angle_mdeg", sequence=mdeg)],
                             columns=rr.Scalars.columns(scalars=np.tile([x["recorded_ue"] for x in lines],
                                                                         (len(mdeg), 1))))
        views.append(rrb.TimeSeriesView(name=f"{g}: band of predicted bending [µε] and recorded peaks",
                                        contents=[f"/tmm/uncertainty/{g}", f"/records/peaks/{g}"]))
    rec.send_blueprint(rrb.Blueprint(rrb.Vertical(*views), collapse_panels=True))
    rec.flush()
