"""X-y charts drawn in rerun's 2D view: axes that read in rpm or degrees.

Rerun plots series only against a timeline, and labels a sequence timeline's axis ``#100``; its
time-series views all follow the one timeline chosen in the time panel, so a plot over crank
angle is empty while the time panel shows crank speed. A sweep (peaks against speed) and a band
(strain against crank angle) are x-y data, so they are drawn here as static 2D charts: a frame,
grid lines at round ticks with labelled values, the axis titles, the series as line strips with
dots at the data points, and a legend of labelled dots. Static data show at every time, whatever
the timeline.

:func:`log_chart` logs one :class:`Chart` under its root entity and returns its view.

Owns: x-y charts in rerun's 2D view. Boundaries: no sweep or band logic.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

WIDTH, HEIGHT = 1.6, 1.0                  # the plot frame in view units
# Labels are drawn on light boxes: dark text.
FRAME_COLOR, GRID_COLOR, TEXT_COLOR = (160, 160, 160), (70, 70, 70), (60, 60, 60)


@dataclass
class Series:
    name: str
    x: np.ndarray
    y: np.ndarray
    color: tuple
    width: float = 2.0                    # line width [UI points]; 0: dots only
    dots: bool = True


@dataclass
class Chart:
    root: str                             # entity path of the chart
    title: str
    x_label: str
    y_label: str
    series: list = field(default_factory=list)
    x_range: tuple | None = None          # default: the data's
    y_range: tuple | None = None
    x_ticks: tuple | None = None          # default: round 1-2-5 steps (e.g. 0, 90, ... 360 for degrees)


def ticks(lo: float, hi: float, n: int = 6) -> np.ndarray:
    """About ``n`` round values (1-2-5 steps) covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return np.array([lo])
    raw = (hi - lo) / n
    e = 10 ** math.floor(math.log10(raw))
    step = next(m * e for m in (1, 2, 5, 10) if m * e >= raw)
    return np.arange(math.ceil(lo / step - 1e-9) * step, hi + step * 1e-9, step)


def _fmt(v: float, step: float) -> str:
    digits = max(0, -int(math.floor(math.log10(step)))) if step > 0 else 0
    return f"{v:.{digits}f}"


def _range(values, given):
    """The axis range: ``given``, else the data's widened to round ticks."""
    if given is not None:
        return float(given[0]), float(given[1])
    v = np.concatenate([np.asarray(x, dtype=float).ravel() for x in values]) if values else np.zeros(1)
    v = v[np.isfinite(v)]
    lo, hi = (float(v.min()), float(v.max())) if v.size else (0.0, 1.0)
    if hi == lo:
        lo, hi = lo - 1.0, hi + 1.0
    t = ticks(lo, hi)
    step = t[1] - t[0] if len(t) > 1 else 1.0
    return math.floor(lo / step + 1e-9) * step, math.ceil(hi / step - 1e-9) * step


def log_chart(rec: rr.RecordingStream, chart: Chart) -> rrb.Spatial2DView:
    """Log ``chart`` (static) and return a 2D view of it."""
    x0, x1 = _range([s.x for s in chart.series], chart.x_range)
    y0, y1 = _range([s.y for s in chart.series], chart.y_range)

    def to_view(x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return np.column_stack([(x - x0) / (x1 - x0) * WIDTH, -(y - y0) / (y1 - y0) * HEIGHT])
    root = chart.root
    frame = [[0, 0], [WIDTH, 0], [WIDTH, -HEIGHT], [0, -HEIGHT], [0, 0]]
    rec.log(f"{root}/frame", rr.LineStrips2D([frame], colors=[FRAME_COLOR], radii=[rr.Radius.ui_points(1.0)],
                                            draw_order=1.0), static=True)
    xt = np.asarray(chart.x_ticks, dtype=float) if chart.x_ticks is not None else ticks(x0, x1)
    yt = ticks(y0, y1)
    xt, yt = xt[(xt >= x0) & (xt <= x1)], yt[(yt >= y0) & (yt <= y1)]
    xs = xt[1] - xt[0] if len(xt) > 1 else 1.0
    ys = yt[1] - yt[0] if len(yt) > 1 else 1.0
    grid = [to_view([x, x], [y0, y1]) for x in xt] + [to_view([x0, x1], [y, y]) for y in yt]
    rec.log(f"{root}/grid", rr.LineStrips2D(grid, colors=[GRID_COLOR], radii=[rr.Radius.ui_points(0.5)],
                                           draw_order=0.5), static=True)
    labels = [(p, _fmt(x, xs)) for p, x in zip(to_view(xt, np.full(len(xt), y0)) + [0, 0.05], xt)]
    labels += [(p, _fmt(y, ys)) for p, y in zip(to_view(np.full(len(yt), x0), yt) - [0.1, 0], yt)]
    labels += [((WIDTH / 2, 0.15), chart.x_label), ((-0.05, -HEIGHT - 0.08), chart.y_label)]
    rec.log(f"{root}/labels", rr.Points2D([p for p, _ in labels], labels=[t for _, t in labels],
                                          colors=[TEXT_COLOR], radii=[rr.Radius.ui_points(0.1)], show_labels=True),
            static=True)
    for i, s in enumerate(chart.series):
        path = f"{root}/series/{i}"
        pts = to_view(s.x, s.y)
        ok = np.isfinite(pts).all(axis=1)
        if s.width > 0 and ok.sum() > 1:
            rec.log(f"{path}/line", rr.LineStrips2D([pts[ok]], colors=[s.color], radii=[rr.Radius.ui_points(s.width / 2)],
                                                   draw_order=2.0), static=True)
        if s.dots and ok.any():
            rec.log(f"{path}/dots", rr.Points2D(pts[ok], colors=[s.color], radii=[rr.Radius.ui_points(2.5)],
                                                draw_order=3.0), static=True)
    # The legend: a labelled dot per named series, beside the frame, spread over its height so
    # that the labels (a fixed size on screen) do not overlap in a small view.
    named = [s for s in chart.series if s.name]
    if named:
        step = HEIGHT / max(len(named), 8)
        # Labels centre on their dot: the dots sit far enough right that the text clears the frame.
        rec.log(f"{root}/legend", rr.Points2D([(WIDTH + 0.45, -HEIGHT + step * (i + 0.5)) for i in range(len(named))],
                                              labels=[s.name for s in named], colors=[s.color for s in named],
                                              radii=[rr.Radius.ui_points(4.0)], show_labels=True), static=True)
    bounds = rrb.VisualBounds2D(x_range=[-0.25, WIDTH + 0.95], y_range=[-HEIGHT - 0.15, 0.25])
    return rrb.Spatial2DView(name=chart.title, origin=root, visual_bounds=bounds)
