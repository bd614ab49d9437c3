"""Figures of a run folder: strain against crank angle per gauge (``strains.png``/``.svg``).

Drawn with matplotlib's object API (``Figure``, no pyplot): no global backend is switched, so a
run started from a Jupyter notebook keeps the notebook's inline plots. SVG files keep their text
as text (``svg.fonttype = 'none'``), so labels stay editable in Inkscape or Illustrator.

Readable names: gauges are written as "coupler, mid-span" rather than ``coupler_mid``
(:func:`gauge_label`), records by their source and table (``Record.title``).

Owns: the run's strain figures and the shared PNG+SVG writer. Boundaries: no data reading beyond
the run's tables it is given.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np

from .files import clear_link
from .records import RECORD_DIR, history_over_angle, peaks_at, records_for, shipped_records
from .results import RunData, load_run

log = logging.getLogger(__name__)

POSITIONS = {"mid": "mid-span", "midspan": "mid-span", "quarter": "quarter-span", "third": "third-span",
             "root": "root", "tip": "tip", "end": "end", "start": "start"}
ENGINE_COLORS = {"tmm": "C0", "exudyn": "C1", "mujoco": "C2"}
RECORD_COLOR = "k"


def gauge_label(name: str) -> str:
    """``"coupler_mid"`` -> ``"coupler, mid-span"``; ``"rocker_q1"`` -> ``"rocker, q1"``; a name
    without a position part is returned with its underscores as spaces."""
    link, _, pos = str(name).rpartition("_")
    if not link:
        return str(name).replace("_", " ")
    return f"{link.replace('_', ' ')}, {POSITIONS.get(pos, pos.replace('_', ' '))}"


def new_figure(**kwargs):
    """A matplotlib Figure with an Agg canvas, independent of pyplot's state, laid out by
    constrained layout unless ``layout`` says otherwise (:func:`save` relies on it)."""
    from matplotlib.figure import Figure
    kwargs.setdefault("layout", "constrained")
    return Figure(**kwargs)


def save(fig, folder, stem: str, dpi: int = 130) -> list:
    """``<stem>.png`` and ``<stem>.svg`` (text kept as text) in ``folder``; returns the paths."""
    import matplotlib
    paths = []
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        for ext in ("png", "svg"):
            path = Path(folder) / f"{stem}.{ext}"
            # No bbox_inches="tight": the figures are laid out by constrained layout, which
            # already keeps the legends and notes beside the axes inside the canvas; "tight"
            # drew every figure twice more (0.5 s of a TMM run's 4 s).
            fig.savefig(clear_link(path), dpi=dpi)
            paths.append(path)
    return paths


def record_histories(scenario, directory=None) -> dict:
    """History records of the scenario's rig at its speed, over crank angle:
    ``{gauge: [(title, angle_deg (n,), bending_ue (n,))]}`` (for :func:`plot_strains`)."""
    out = {}
    for rec in records_for(scenario, directory):
        if rec.format != "history" or rec.index[1] != "deg":
            continue
        hist = history_over_angle(rec)
        for g, series in hist.items():
            if g != "angle_rad" and "bending_ue" in series:
                out.setdefault(g, []).append((rec.title, np.degrees(hist["angle_rad"]), series["bending_ue"]))
    return out


def peaks_by_speed(rig: str | None, rpm_min: float, rpm_max: float, directory=None) -> list:
    """Recorded bending peaks of a rig at every speed in [rpm_min, rpm_max] (for sweep figures):
    ``[{"rpm", "gauge", "bending_max_ue", "bending_min_ue", "record", "title", "kind"}]`` from
    peaks records (each printed speed) and history records over crank angle (their extremes)."""
    if not rig:
        return []
    out = []
    for rec in shipped_records(RECORD_DIR if directory is None else directory):
        if rec.rig != rig:
            continue
        if rec.format == "peaks":
            speeds = sorted({float(r["rpm"]) for r in rec.rows if rpm_min - 0.5 <= r["rpm"] <= rpm_max + 0.5})
            for rpm in speeds:
                for g, p in peaks_at(rec, rpm).items():
                    out.append({"rpm": rpm, "gauge": g, "bending_max_ue": p.get("bending_max_ue"),
                                "bending_min_ue": p.get("bending_min_ue"), "record": rec.name, "title": rec.title,
                                "kind": rec.kind})
        elif rec.format == "history" and rec.index and rec.index[1] == "deg" and rec.speed_rpm is not None \
                and rpm_min - 0.5 <= rec.speed_rpm <= rpm_max + 0.5:
            for g, series in history_over_angle(rec).items():
                if g != "angle_rad" and "bending_ue" in series:
                    out.append({"rpm": rec.speed_rpm, "gauge": g, "bending_max_ue": float(series["bending_ue"].max()),
                                "bending_min_ue": float(series["bending_ue"].min()), "record": rec.name,
                                "title": rec.title, "kind": rec.kind})
    return out


def _engine_note(e: dict) -> str:
    """'' for a steady engine, else why its curve is a transient (or failed)."""
    if e.get("status") not in (None, "completed"):
        return f"{e.get('status', '').upper()}"
    if e.get("steady") is False:
        change = e.get("revolution_change")
        return "NOT STEADY" + ("" if change is None else f", revolutions differ by {100 * change:.2g} %")
    return ""


def plot_strains(run, histories: dict | None = None, folder=None) -> list:
    """``strains.png`` and ``strains.svg``: bending (solid) and axial (dashed) strain [µε] of each
    engine's last revolution against the crank angle [deg], one axis per gauge; records of the
    summary as horizontal lines (peaks) and ``histories`` as curves; an engine that is not steady
    is labelled so in the legend and in red on the axis. ``run``: a :class:`cosim.results.RunData`
    or a run folder. Returns the written paths."""
    run = run if isinstance(run, RunData) else load_run(run)
    folder = Path(folder or run.folder)
    summary, histories = run.summary, histories or {}
    last = run.last_revolution()
    strains = last[last["quantity"].isin(["bending", "axial"])] if len(last) else last
    # The engines' gauges: a record of a gauge the scenario does not have has nothing to compare with.
    gauges = run.gauges
    if not gauges:
        raise ValueError(f"{run.folder}: no gauge strains to draw")
    engines_summary = summary.get("engines") or {}
    fig = new_figure(figsize=(9, 3.3 * len(gauges) + 0.6), layout="constrained")
    axes = fig.subplots(len(gauges), 1, squeeze=False)[:, 0]
    unsteady = [e for e in run.engines if _engine_note(engines_summary.get(e, {}))]
    # Engines the run asked for that left no trace (unavailable, failed at set-up) are named too.
    missing = [f"{e} ({d.get('status', '?')})" for e, d in engines_summary.items() if e not in run.engines]
    side = "\n".join(([f"not steady (a transient):\n{', '.join(unsteady)}"] if unsteady else []) +
                      ([f"no result: {', '.join(missing)}"] if missing else []))
    for ax, g in zip(axes, gauges):
        for engine in run.engines:
            note = _engine_note(engines_summary.get(engine, {}))
            color = ENGINE_COLORS.get(engine, None)
            for quantity, style in (("bending", "-"), ("axial", "--")):
                sel = strains[(strains["engine"] == engine) & (strains["gauge"] == g) &
                              (strains["quantity"] == quantity)].sort_values("crank_angle_deg")
                if not len(sel):
                    continue
                label = f"{engine} {quantity}" + (f" ({note})" if note else "")
                ax.plot(sel["crank_angle_deg"], sel["value"], style, color=color, lw=1.4 if quantity == "bending"
                        else 0.9, label=label)
        for title, angle_deg, bending in histories.get(g, []):
            order = np.argsort(np.mod(angle_deg, 360.0))
            ax.plot(np.mod(angle_deg, 360.0)[order], np.asarray(bending)[order], ":", color=RECORD_COLOR, lw=1.8,
                    marker="o" if len(angle_deg) < 40 else None, ms=3, label=f"{title} bending")
        history_titles = {h[0] for h in histories.get(g, [])}
        for k, rec in enumerate((summary.get("records") or {}).get(g, [])):
            title = rec.get("title") or rec.get("label", "record")
            if rec.get("format") == "history" or title in history_titles:
                continue                 # drawn as a curve above
            for key, sign, ls in (("bending_max_ue", "+", (0, (5, 2))), ("bending_min_ue", "-", (0, (5, 2, 1, 2)))):
                v = rec.get(key)
                if v is None:
                    continue
                ax.axhline(v, color=str(min(0.2 * k, 0.6)) if k else RECORD_COLOR, ls=ls, lw=1.0,
                           label=f"{title} {sign}peak bending {v:.0f} µε")
        if side:                 # beside the plot, under the legend: never on top of a curve
            ax.text(1.01, 0.0, side, transform=ax.transAxes, color="C3", fontsize=8, va="bottom", ha="left",
                    fontweight="bold")
        ax.set_xlim(0, 360)
        ax.set_xticks(np.arange(0, 361, 45))
        ax.set_xlabel("crank angle [deg]")
        ax.set_ylabel("strain [µε]")
        ax.set_title(f"{gauge_label(g)}: bending (solid) and axial (dashed)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    fig.suptitle(f"{summary.get('scenario', run.folder.name)}: last revolution of each engine"
                 + ("" if summary.get("status") == "completed" else f" (run {summary.get('status')})"))
    return save(fig, folder, "strains")


def write_run_figures(folder, scenario=None, records_dir=None) -> list:
    """The figures of a finished ``cosim run`` folder (what :func:`cosim.runs.run_scenario` calls).
    History records are looked up for the scenario when it is given."""
    histories = record_histories(scenario, records_dir) if scenario is not None else None
    if scenario is not None:
        # Only the last revolutions are drawn: read only them (memory flat in the run's length).
        folder = load_run(folder, tail_s=4 * scenario.revolution_period_s)
    return plot_strains(folder, histories)


def peak_markers(ax, peaks: list, series_colors: dict | None = None) -> None:
    """Recorded peaks against speed on a sweep axis: ``peaks`` as from
    :func:`peaks_by_speed` (rpm, gauge, bending_max_ue, bending_min_ue, title)."""
    series_colors = series_colors or {}
    shown = set()
    for p in peaks:
        for key, marker, sign in (("bending_max_ue", "^", "+"), ("bending_min_ue", "v", "-")):
            v = p.get(key)
            if v is None or not math.isfinite(v):
                continue
            label = f"{p['title']}, {gauge_label(p['gauge'])} {sign}peak"
            ax.plot([p["rpm"]], [v], marker, ms=7, mfc="none", mew=1.5,
                    color=series_colors.get(p["gauge"], RECORD_COLOR),
                    label=None if label in shown else label, zorder=5)
            shown.add(label)
