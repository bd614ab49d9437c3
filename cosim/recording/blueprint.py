"""The default layout of a run recording: a pure function of the recording spec.

:func:`run_blueprint` returns the rerun blueprint that goes with the data, so whoever opens the
file sees, without arranging anything: one bending-strain plot per gauge (every engine and
every record), a tab row with the drive torque, the axial strains, the crank speed and the
engines' extras, the linkage of every engine in 2D with an engine legend, and (motor runs) the
motor's current, voltage and torque, or (prescribed runs) the drive power. :func:`views` lists
the views of a blueprint (for tests and readers).

Owns: the default layout, a pure function of the spec. Boundaries: no data.
"""
from __future__ import annotations

import rerun.blueprint as rrb

from .layout import ENGINE_COLORS, SIM_TIME, part
from .spec import RecordingSpec

LEGEND_MARGIN = 0.15          # of the linkage's size, around it in the 2D view


def plot(name: str, contents) -> rrb.TimeSeriesView:
    """A time-series view that opens on the whole run: without an explicit x range the viewer
    shows only a short window around the time cursor on sequence timelines (crank angle)."""
    whole = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return rrb.TimeSeriesView(name=name, contents=list(contents), axis_x=rrb.TimeAxis(view_range=whole))


def linkage_title(exaggeration: float | None) -> str:
    if exaggeration is None:
        return "linkage (no elastic deformation drawn yet)"
    return (f"linkage: deformation ×{exaggeration:g} (each link's bending and stretch exaggerated; "
            f"grey: straight links between the joints)")


def linkage_bounds(spec: RecordingSpec):
    """View bounds holding the linkage over a revolution with a margin (None: the viewer fits the
    data). In view coordinates: the 2D view points y down, the drawing is flipped (writer)."""
    if spec.bounds is None:
        return None
    (x_lo, x_hi), (y_lo, y_hi) = spec.bounds
    pad = LEGEND_MARGIN * max(x_hi - x_lo, y_hi - y_lo)
    return rrb.VisualBounds2D(x_range=[x_lo - pad, x_hi + pad], y_range=[-y_hi - pad, -y_lo + pad])


def run_blueprint(spec: RecordingSpec, engines=(), exaggeration: float | None = None) -> rrb.Blueprint:
    """The blueprint of a run recording (see the module docstring). ``engines``: engines that
    logged besides ``spec.engines``; ``exaggeration``: the linkage drawing's factor (None: not
    known yet)."""
    # View queries cannot wildcard one path level (only a trailing /**), so they name every
    # engine: the given ones and the bench's standard ones (a query matching nothing is harmless).
    names = list(dict.fromkeys([part(e) for e in (*spec.engines, *engines)] + list(ENGINE_COLORS)))
    gauge_views = []
    for g in spec.gauges:
        gp = part(g.name)
        where = f"{g.link} at {g.position_m * 1000:.4g} mm, {g.face} face"
        gauge_views.append(plot(f"bending strain {g.name} [µε] ({where})",
                                [f"/{e}/strain/{gp}" for e in names] + [f"/records/strain/{gp}/**"]))
    torque = plot("drive torque at the crank [N m]", [f"/{e}/drive_torque" for e in names])
    axial = plot("axial strains [µε]", [f"/{e}/axial_strain/**" for e in names] + ["/records/axial_strain/**"])
    speed = plot("crank speed [rad/s]", [f"/{e}/crank_speed" for e in names])
    extras = plot("engine extras", [f"/{e}/extras/**" for e in names])
    power = plot("drive power: drive torque × crank speed [W]", [f"/{e}/drive_power" for e in names])
    linkage = rrb.Spatial2DView(name=linkage_title(exaggeration), contents=[f"/{e}/linkage/**" for e in names],
                                visual_bounds=linkage_bounds(spec))
    about = rrb.Tabs(linkage, rrb.TextDocumentView(name="scenario", origin="/scenario"),
                     rrb.TextLogView(name="engine events", contents=[f"/{e}/events" for e in names]), active_tab=0)
    left = [*gauge_views, rrb.Tabs(torque, axial, speed, extras, active_tab=0)]
    if spec.mode == "motor":
        # Tabs, not a stack of thin plots: a legend of four series would cover a thin plot.
        motor = rrb.Tabs(*[plot(f"motor {q} [{u}]", [f"/motor/{e}/{q}" for e in names])
                           for q, u in (("current", "A"), ("voltage", "V"),
                                        ("torque", "N m"))], active_tab=0)
        more = rrb.Tabs(plot("motor and crank speeds [rad/s]", [f"/motor/{e}/speed" for e in names]),
                        plot("motor power and losses [W]", [f"/motor/{e}/power" for e in names]),
                        plot("motor energies [J]", [f"/motor/{e}/energy" for e in names]), power)
        right, right_shares = [about, motor, more], [3, 2, 2]
    else:
        right, right_shares = [about, power], [3, 1]
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Vertical(*left, row_shares=[3] * len(gauge_views) + [2]),
                       rrb.Vertical(*right, row_shares=right_shares),
                       column_shares=[3, 2]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(timeline=SIM_TIME, state="collapsed"),
    )


def views(blueprint) -> list:
    """Every view of a blueprint (or container), depth first: [{"name", "class", "origin", "contents"}]."""
    node = getattr(blueprint, "root_container", blueprint)
    if hasattr(node, "class_identifier"):
        return [{"name": node.name, "class": node.class_identifier, "origin": str(node.origin),
                 "contents": [str(c) for c in (node.contents if isinstance(node.contents, (list, tuple))
                                               else [node.contents])]}]
    return [v for child in getattr(node, "contents", ()) for v in views(child)]
