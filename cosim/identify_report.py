"""Figure and rerun recording of an identification (:mod:`cosim.identify`): per scenario and
gauge, the calibrated model's bending strain over the revolution, the scenario as declared (the
nominal model), and the recorded +/- peaks, marked as calibration or held out.

Owns: the identification's figure and recording. Boundaries: no fitting.
"""
from __future__ import annotations

import numpy as np

from .figures import gauge_label, new_figure, save
from .files import clear_link
from .recording.layout import recording_id


def _rows(result):
    names = result["calibration_scenarios"] + result["validation_scenarios"]
    return sorted(names, key=lambda n: result["predictions"][n]["rpm"])


def _records(result, name):
    return (result.get("calibration", {}).get(name) or result.get("validation", {}).get(name) or {})


def plot(folder, result: dict, preds: dict) -> list:
    rows = _rows(result)
    gauges = sorted({g for n in rows for g in (preds[n].get("gauges") or {})})
    fig = new_figure(figsize=(5.2 * len(gauges), 3.0 * len(rows) + 0.8), layout="constrained")
    axes = fig.subplots(len(rows), len(gauges), squeeze=False)
    for i, name in enumerate(rows):
        pred = preds[name]
        role = "calibration" if name in result["calibration_scenarios"] else "held out"
        for j, g in enumerate(gauges):
            ax = axes[i][j]
            nom = pred["nominal"]
            if nom.get("status") == "completed":
                ax.plot(nom["angle_deg"], nom["gauges"][g]["bending_ue"], color="0.6", lw=0.8,
                        label="scenario as declared")
            if pred.get("gauges"):
                ax.plot(pred["angle_deg"], pred["gauges"][g]["bending_ue"], color="C0", lw=1.2,
                        label="identified model")
                for side, key in (("+", "bending_max_ue"), ("-", "bending_min_ue")):
                    s = (pred.get("sigma_ue") or {}).get(g, {}).get(side) or 0.0
                    ax.errorbar([365], [pred["peaks"][g][key]], yerr=[s], fmt="o", color="C0", ms=3, capsize=2)
            for side, c in (_records(result, name).get(g) or {}).items():
                err = "" if c["error"] is None else f" ({c['error']:+.0%})"
                ax.axhline(c["record_ue"], color="k", ls="--" if side == "+" else "-.", lw=1,
                           label=f"Table I {side}peak{err}")
            ax.set_title(f"{name} ({result['predictions'][name]['rpm']:.0f} rpm), {gauge_label(g)}: {role}", fontsize=9)
            ax.set_xlim(0, 372)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=6, loc="best")
            if i == len(rows) - 1:
                ax.set_xlabel("crank angle [deg] (dots: identified peaks +/- 1 sigma)")
            if j == 0:
                ax.set_ylabel("bending [µε]")
    ident = ", ".join(f"{n} = {p['value']:.3g} {p.get('unit', '')}".strip() if not p.get("discrete")
                      else f"{n} = {p['value']}" for n, p in result["parameters"].items())
    fig.suptitle(f"identified at {', '.join(result['calibration_scenarios'])}: {ident}", fontsize=9)
    return save(fig, folder, "identification")


def record_rrd(path, result: dict, preds: dict) -> None:
    import rerun as rr
    import rerun.blueprint as rrb
    rec = rr.RecordingStream("flexlink-bench-identify",
                             recording_id=recording_id("identify-" + "+".join(result["calibration_scenarios"]), path))
    rec.save(str(clear_link(path)))
    views = []
    for name in _rows(result):
        pred = preds[name]
        if not pred.get("gauges"):
            continue
        for g in pred["gauges"]:
            entity = f"/identify/{name}/{g}"
            mdeg = np.rint(np.asarray(pred["angle_deg"]) * 1000).astype(np.int64)
            cols = [pred["gauges"][g]["bending_ue"]]
            names = ["identified model bending [µε]"]
            nom = pred["nominal"]
            if nom.get("status") == "completed":
                cols.append(nom["gauges"][g]["bending_ue"])
                names.append("scenario as declared [µε]")
            for side, c in (_records(result, name).get(g) or {}).items():
                cols.append(np.full(len(mdeg), c["record_ue"]))
                names.append(f"record {side}peak [µε]")
            rec.log(entity, rr.SeriesLines(names=names), static=True)
            rec.send_columns(entity, indexes=[rr.TimeColumn("crank_angle_mdeg", sequence=mdeg)],
                             columns=rr.Scalars.columns(scalars=np.column_stack(cols)))
            role = "calibration" if name in result["calibration_scenarios"] else "held out"
            views.append(rrb.TimeSeriesView(name=f"{name} {g} ({role})", contents=[entity]))
    if views:
        rec.send_blueprint(rrb.Blueprint(rrb.Vertical(*views), collapse_panels=True))
    rec.flush()
