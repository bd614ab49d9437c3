"""X-y charts drawn in rerun's 2D view: axes that read in rpm or degrees.

Rerun plots series only against a timeline, and labels a sequence timeline's axis ``#100``; its
time-series views all follow the one timeline chosen in the time panel, so a plot over crank
angle is empty while the time panel shows crank speed. A sweep (peaks against speed) and a band
(strain against crank angle) are x-y data, so they are drawn here as static 2D charts: a frame,
grid lines at round ticks with their values (drawn as strokes centred on the line: see
:data:`FIGURE_HEIGHT`), the axis titles, the series as line strips with
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
# Labels are drawn on light boxes: dark text. Tick values are strokes on the view's dark ground.
FRAME_COLOR, GRID_COLOR, TEXT_COLOR = (160, 160, 160), (70, 70, 70), (60, 60, 60)
TICK_COLOR = (200, 200, 200)

# Tick values are drawn as seven-segment figures of line strokes, in view units, centred on their
# grid line (y) or tick (x). Rerun draws a point's label as a box below the point (5 UI points
# down, a line of text high, whatever the zoom), so a y tick value logged as a point label sat
# under its grid line and read as the value of the line below (79 Hz read as 100).
FIGURE_HEIGHT = 0.05                      # height of a tick figure [view units]
TICK_GAP = 0.03                           # between the frame and the tick figures [view units]
_SEGMENTS = {"a": ((0, 1), (1, 1)), "b": ((1, 1), (1, 0.5)), "c": ((1, 0.5), (1, 0)), "d": ((0, 0), (1, 0)),
             "e": ((0, 0), (0, 0.5)), "f": ((0, 0.5), (0, 1)), "g": ((0, 0.5), (1, 0.5))}
_FIGURES = {"0": "abcdef", "1": "bc", "2": "abged", "3": "abgcd", "4": "fgbc", "5": "afgcd", "6": "afgedc",
            "7": "abc", "8": "abcdefg", "9": "abcdfg", "-": "g"}


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


def figure_strokes(text: str, anchor_x: float, centre_y: float, align: str = "right",
                   height: float = FIGURE_HEIGHT) -> list:
    """The line segments (each a 2 x 2 array, view units, y down) drawing the number ``text``
    (digits, '-', '.') ``height`` tall, its vertical middle at ``centre_y`` and its right end
    (``align`` 'right') or its middle ('center') at ``anchor_x``."""
    w, gap, dot = 0.5 * height, 0.3 * height, 0.25 * height
    advances = [dot if ch == "." else w + gap for ch in text]
    x = anchor_x - (sum(advances) - gap) * (1.0 if align == "right" else 0.5)
    strokes = []
    for ch, advance in zip(text, advances):
        if ch == ".":
            strokes.append(np.array([[x, centre_y + height / 2], [x + 0.1 * height, centre_y + height / 2]]))
        for seg in _FIGURES.get(ch, ""):
            (ax, ay), (bx, by) = _SEGMENTS[seg]
            strokes.append(np.array([[x + ax * w, centre_y - (ay - 0.5) * height],
                                     [x + bx * w, centre_y - (by - 0.5) * height]]))
        x += advance
    return strokes


def tick_values(x_range, y_range, x_ticks=None) -> tuple:
    """``(x ticks, y ticks)`` within the ranges: ``x_ticks`` if given, else round 1-2-5 steps."""
    (x0, x1), (y0, y1) = x_range, y_range
    xt = np.asarray(x_ticks, dtype=float) if x_ticks is not None else ticks(x0, x1)
    yt = ticks(y0, y1)
    return xt[(xt >= x0) & (xt <= x1)], yt[(yt >= y0) & (yt <= y1)]


def tick_labels(to_view, x_range, y_range, x_ticks=None) -> list:
    """``[(axis, value, text, strokes)]`` of the chart's tick values: each y value right of the
    frame's left edge and centred on its grid line, each x value centred under its tick.
    ``to_view(x, y)``: data to view units; ranges and ticks in data units."""
    x0, y0 = x_range[0], y_range[0]
    xt, yt = tick_values(x_range, y_range, x_ticks)
    xs = xt[1] - xt[0] if len(xt) > 1 else 1.0
    ys = yt[1] - yt[0] if len(yt) > 1 else 1.0
    out = []
    for x, (vx, _) in zip(xt, to_view(xt, np.full(len(xt), y0))):
        text = _fmt(x, xs)
        out.append(("x", float(x), text, figure_strokes(text, vx, TICK_GAP + FIGURE_HEIGHT / 2, "center")))
    for y, (_, vy) in zip(yt, to_view(np.full(len(yt), x0), yt)):
        text = _fmt(y, ys)
        out.append(("y", float(y), text, figure_strokes(text, -TICK_GAP, vy, "right")))
    return out


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
    xt, yt = tick_values((x0, x1), (y0, y1), chart.x_ticks)
    grid = [to_view([x, x], [y0, y1]) for x in xt] + [to_view([x0, x1], [y, y]) for y in yt]
    rec.log(f"{root}/grid", rr.LineStrips2D(grid, colors=[GRID_COLOR], radii=[rr.Radius.ui_points(0.5)],
                                           draw_order=0.5), static=True)
    labels = tick_labels(to_view, (x0, x1), (y0, y1), chart.x_ticks)
    figures = [stroke for *_, strokes in labels for stroke in strokes]
    rec.log(f"{root}/ticks", rr.LineStrips2D(figures, colors=[TICK_COLOR], radii=[rr.Radius.ui_points(0.6)],
                                            draw_order=1.0), static=True)
    labels = [((WIDTH / 2, 0.15), chart.x_label), ((-0.05, -HEIGHT - 0.08), chart.y_label)]
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
