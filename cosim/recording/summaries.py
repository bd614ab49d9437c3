"""The sweep and uncertainty recordings: their results as 2D charts (:mod:`cosim.recording.charts`).

``sweep.rrd``: per gauge the +/- peak bending strain of every engine against crank speed [rpm]
(+peak in the engine's colour, -peak in a lighter shade of it, recorded peaks as dots), the
largest Floquet multiplier against speed (with the line |mu| = 1), the Campbell diagram (crank
harmonics and the natural-frequency bands against speed) and the natural frequencies over a
revolution [deg]. ``uncertainty.rrd``: per gauge the band of predicted bending strain over the
crank angle (envelope of the samples, 5-95 %, nominal: the scenario as written, which is not a
sample and may leave the envelope) with the recorded peaks. All charts are static, so every
panel shows at once, whatever the timeline.

Both are written to their file only; ``cosim sweep/uncertainty`` then show the finished file in
a viewer if asked (:func:`cosim.recording.sinks.show_file`).

Owns: the sweep and uncertainty recordings. Boundaries: no sweep or band computation.
"""
from __future__ import annotations

import math

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from ..files import clear_link
from .charts import Chart, Series, log_chart
from .layout import RECORD_COLORS, engine_color, part, recording_id, shades

MODE_COLORS = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75)]
HARMONIC_COLOR = (110, 110, 110)
DEGREE_TICKS = (0.0, 90.0, 180.0, 270.0, 360.0)
NOMINAL_COLOR = (230, 170, 0)             # stands out from the band's blues, readable as label text


def _open(path, app: str, label: str):
    rec = rr.RecordingStream(app, recording_id=recording_id(label, path))
    rec.set_sinks(rr.FileSink(str(clear_link(path))))
    return rec


def _close(rec, views, columns: int = 1) -> None:
    if columns > 1 and len(views) > 1:
        half = math.ceil(len(views) / 2)
        layout = rrb.Horizontal(rrb.Vertical(*views[:half]), rrb.Vertical(*views[half:]))
    else:
        layout = rrb.Vertical(*views)
    rec.send_blueprint(rrb.Blueprint(layout, collapse_panels=True), make_active=True, make_default=True)
    rec.flush()
    rec.disconnect()                      # the file's footer


def sweep_recording(path, name: str, points: list, fmap=None, rpm_range=None, record_peaks=()) -> None:
    """Write ``sweep.rrd``: the sweep's ``points`` (summary.json's), the natural-frequency map
    ``fmap`` ({"angle_rad", "f_Hz"}) over ``rpm_range``, the recorded peaks by speed."""
    rec = _open(path, "flexlink-bench-sweep", f"{name}-sweep")
    points = [p for p in points if p.get("rpm") is not None]
    engines = sorted({e for p in points for e in p["engines"]})
    gauges = sorted({g for p in points for e in p["engines"].values() for g in (e.get("gauges") or {})})
    views = []
    for g in gauges:
        series = []
        for engine in engines:
            rows = sorted((p["rpm"], s["bending_max_ue"], s["bending_min_ue"]) for p in points
                          for s in [((p["engines"].get(engine) or {}).get("gauges") or {}).get(g)] if s)
            if not rows:
                continue
            r = np.array(rows, dtype=float)
            plus, minus = shades(engine_color(engine, engines), 2)
            series += [Series(f"{engine} +peak [µε]", r[:, 0], r[:, 1], plus),
                       Series(f"{engine} -peak [µε]", r[:, 0], r[:, 2], minus)]
        recorded = [x for x in record_peaks or () if x.get("gauge") == g]
        for i, label in enumerate(dict.fromkeys(x["record"] for x in recorded)):
            mine = [x for x in recorded if x["record"] == label]
            for side, key in (("+", "bending_max_ue"), ("-", "bending_min_ue")):
                xy = [(x["rpm"], x[key]) for x in mine if x.get(key) is not None]
                if xy:
                    series.append(Series(f"{label} {side}peak (record)", [a for a, _ in xy], [b for _, b in xy],
                                         RECORD_COLORS[i % len(RECORD_COLORS)], width=0))
        views.append(log_chart(rec, Chart(f"/peaks/{part(g)}", f"{g}: peak bending strain vs crank speed",
                                          "crank speed [rpm]", "bending strain [µε]", series)))
    floq = sorted((p["rpm"], p["engines"]["tmm"]["floquet_max"]) for p in points
                  if (p["engines"].get("tmm") or {}).get("floquet_max") is not None)
    if floq:
        f = np.array(floq, dtype=float)
        series = [Series("tmm largest |Floquet multiplier|", f[:, 0], f[:, 1], engine_color("tmm")),
                  Series("|mu| = 1: parametric resonance above", f[[0, -1], 0], [1.0, 1.0], (214, 39, 40),
                         width=1.0, dots=False)]
        unstable = f[f[:, 1] > 1.0]
        if len(unstable):        # solved orbits a march would leave, drawn apart from the stable ones
            series.append(Series("tmm unstable orbits", unstable[:, 0], unstable[:, 1], (148, 103, 189), width=0))
        views.append(log_chart(rec, Chart("/floquet", "largest Floquet multiplier vs crank speed",
                                          "crank speed [rpm]", "|mu|", series,
                                          y_range=(0.0, max(1.2, float(np.nanmax(f[:, 1])) * 1.1)))))
    if fmap is not None:
        rpms = [p["rpm"] for p in points] or [0.0, 1.0]
        views += _frequency_charts(rec, fmap, rpm_range or (min(rpms), max(rpms)))
    _close(rec, views, columns=2)


def _frequency_charts(rec, fmap, rpm_range, max_harmonic: int = 20) -> list:
    """Campbell diagram (harmonics and mode bands vs rpm) and the natural frequencies vs crank angle."""
    f = np.asarray(fmap["f_Hz"], dtype=float)
    angle = np.degrees(np.asarray(fmap["angle_rad"], dtype=float))
    order = np.argsort(np.mod(angle, 360.0))
    a = np.mod(angle, 360.0)[order]
    lo_rpm, hi_rpm = float(rpm_range[0]), float(rpm_range[1])
    f_top = float(np.nanmax(f)) * 1.1 if np.isfinite(f).any() else 100.0
    campbell, over_angle = [], []
    for m in range(f.shape[1]):
        col = f[:, m]
        ok = np.isfinite(col) & (col > 0)
        if not ok.any():
            continue
        color = MODE_COLORS[m % len(MODE_COLORS)]
        for which, v in (("min", col[ok].min()), ("max", col[ok].max())):
            campbell.append(Series(f"mode {m + 1} {which} [Hz]", [lo_rpm, hi_rpm], [v, v], color, width=1.5,
                                   dots=False))
        y = col[order]
        over_angle.append(Series(f"mode {m + 1} [Hz]", np.append(a, a[0] + 360.0), np.append(y, y[0]), color))
    for k in range(1, max_harmonic + 1):
        if k * lo_rpm / 60 > f_top:
            break
        top = min(hi_rpm, 60 * f_top / k)
        campbell.append(Series(f"{k} x crank" if k <= 3 or k % 5 == 0 else "", [lo_rpm, top],
                               [k * lo_rpm / 60, k * top / 60], HARMONIC_COLOR, width=0.8, dots=False))
    campbell = [s for s in campbell if s.name] + [s for s in campbell if not s.name]
    views = [log_chart(rec, Chart("/campbell", "Campbell: crank harmonics and natural-frequency bands",
                                  "crank speed [rpm]", "frequency [Hz]", campbell,
                                  x_range=(lo_rpm, hi_rpm), y_range=(0.0, f_top)))]
    views.append(log_chart(rec, Chart("/frequencies", "natural frequencies over a revolution",
                                      "crank angle [deg]", "frequency [Hz]", over_angle, x_range=(0.0, 360.0),
                                      x_ticks=DEGREE_TICKS)))
    return views


def uncertainty_recording(path, name: str, rows: list, records: list) -> None:
    """Write ``uncertainty.rrd``: per gauge the band over the crank angle (``rows`` as band.csv)
    with the recorded peaks (``records``: the summary's record check)."""
    rec = _open(path, "flexlink-bench-uncertainty", f"{name}-uncertainty")
    views = []
    color = engine_color("tmm")
    light = shades(color, 2)[1]
    for g in sorted({r["gauge"] for r in rows}):
        rr_ = sorted((r for r in rows if r["gauge"] == g), key=lambda r: r["crank_angle_deg"])
        a = np.array([r["crank_angle_deg"] for r in rr_], dtype=float)

        def col(key):
            return np.array([r[key] for r in rr_], dtype=float)
        # The nominal is the scenario as written, not a sample: it may leave the samples' envelope
        # (cosim.uncertainty.nominal_note), which its name says.
        series = [Series("envelope of the samples, low [µε]", a, col("low_ue"), light, width=1.0, dots=False),
                  Series("envelope of the samples, high [µε]", a, col("high_ue"), light, width=1.0, dots=False),
                  Series("5 % [µε]", a, col("p5_ue"), color, width=1.5, dots=False),
                  Series("95 % [µε]", a, col("p95_ue"), color, width=1.5, dots=False),
                  Series("nominal: scenario as written, not a sample [µε]", a, col("nominal_ue"), NOMINAL_COLOR,
                         width=2.0, dots=False)]
        for i, x in enumerate(r for r in records if r["gauge"] == g):
            c = RECORD_COLORS[i % len(RECORD_COLORS)]
            series.append(Series(f"{x['record']} {x['peak']}peak, {'inside' if x['inside'] else 'OUTSIDE'} the band",
                                 [0.0, 360.0], [x["recorded_ue"]] * 2, c, width=1.5, dots=False))
        views.append(log_chart(rec, Chart(f"/band/{part(g)}", f"{g}: band of predicted bending strain",
                                          "crank angle [deg]", "bending strain [µε]", series, x_range=(0.0, 360.0),
                                          x_ticks=DEGREE_TICKS)))
    _close(rec, views)
