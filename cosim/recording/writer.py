"""Turn batches of a run (:mod:`cosim.recording.batch`) into rerun chunks.

The writer keeps every entity's samples until it sends them: with only a file attached, once
when the recording closes (or when an entity holds ``max_rows`` samples), so the file has one
chunk per entity and ``rerun rrd stats`` finds it optimal; with a viewer attached, every
``live_interval_s`` seconds of wall time, so the viewer follows the run. Each send is one
``send_columns`` call per entity on all four timelines (:mod:`cosim.recording.layout`).

Owns: batches turned into rerun chunks. Boundaries: no layout decisions (cosim.recording.layout).
"""
from __future__ import annotations

import time

import numpy as np
import pyarrow as pa
import rerun as rr

from .. import alignment
from . import linkage as drawing
from .blueprint import run_blueprint
from .layout import (CRANK_ANGLE, CRANK_ANGLE_WRAPPED, MICRO, REVOLUTION, SIM_TIME, STRAIGHT_COLOR, angle_indexes,
                     engine_color, motor_groups, motor_label, part, shades)
from .sinks import ViewerOptions, attach, finish
from .spec import RecordingSpec


def time_columns(t, angle) -> list:
    m, wrapped, rev = angle_indexes(angle)
    return [rr.TimeColumn(SIM_TIME, duration=np.asarray(t, dtype=float)), rr.TimeColumn(CRANK_ANGLE, sequence=m),
            rr.TimeColumn(CRANK_ANGLE_WRAPPED, sequence=wrapped), rr.TimeColumn(REVOLUTION, sequence=rev)]


def strips_array(strips: list):
    """The Arrow array of rerun's line-strip component from a list of (n, 2) point arrays, built
    in one piece (rerun converts a list strip by strip, ~15 us each: more than the run's own
    cost of a macro step of the transfer-matrix engine)."""
    kind = rr.components.LineStrip2DBatch._ARROW_DATATYPE
    lengths = np.fromiter((len(s) for s in strips), dtype=np.int64, count=len(strips))
    offsets = pa.array(np.concatenate([[0], np.cumsum(lengths)]).astype(np.int32))
    points = np.concatenate(strips).astype(np.float32).ravel() if strips else np.zeros(0, np.float32)
    return pa.ListArray.from_arrays(offsets, pa.FixedSizeListArray.from_arrays(pa.array(points), type=kind.value_type),
                                    type=kind)


class StreamWriter:
    """One recording stream: its sinks, the statics, the buffered entities, the linkage frames
    and the records (placed at :meth:`close`)."""

    live_interval_s = 1.0
    max_rows = 200_000

    def __init__(self, spec: RecordingSpec, save_path=None, viewer: ViewerOptions = ViewerOptions(),
                 exaggeration: float | None = None, application_id: str = "flexlink-bench", stations=None):
        self.spec, self.save_path = spec, save_path
        self.exaggeration = exaggeration
        self.viewer = viewer
        self.stations = {e: dict(s or {}) for e, s in (stations or {}).items()}
        self._buffers: dict[str, list] = {}          # entity -> [(t, angle, values)]
        self._declared: set = set()
        self._frames: dict[str, list] = {}           # engine -> [cosim.recording.batch.FrameBlock]
        self._history: dict[str, list] = {}          # engine -> [(t, angle)]
        self._engines: list = []
        self._references: list = []
        self._blueprint_sent = False
        self.rec = rr.RecordingStream(application_id)
        self.urls = attach(self.rec, save_path, viewer)
        self._last_send = time.monotonic()
        self.rec.send_recording_name(f"{spec.scenario} ({spec.mode})")
        self._log_statics()
        if exaggeration is not None or self.urls:
            # A viewer needs a layout now; with a fixed factor the title is final already.
            self._send_blueprint()

    # -- input ------------------------------------------------------------------------------------
    def set_stations(self, stations: dict) -> None:
        """{engine: {link: node stations [m]}}: where each node sits along its link."""
        for e, s in (stations or {}).items():
            self.stations[e] = dict(s or {})

    def write(self, batch: dict | None) -> None:
        """Buffer one batch; send when the policy says so (module docstring)."""
        if batch is None:
            return
        for engine, data in batch["engines"].items():
            self._engine(engine, data)
        for t, engine, message in batch["events"]:
            self.rec.set_time(SIM_TIME, duration=float(t))
            self.rec.log(f"/{part(engine)}/events", rr.TextLog(f"{engine} failed: {message}", level="ERROR"))
            self.rec.reset_time()
        if self.urls and time.monotonic() - self._last_send >= self.live_interval_s:
            self.send()
        else:
            for entity in [e for e, rows in self._buffers.items() if sum(len(r[0]) for r in rows) >= self.max_rows]:
                self._send_entity(entity)

    def reference(self, ref) -> None:
        """A :class:`cosim.recording.references.Reference`, placed and sent at :meth:`close`."""
        self._declare(ref.entity, ref.names, ref.colors, width=2.5)
        self._references.append(ref)

    def text(self, path: str, text: str) -> None:
        media = rr.MediaType.MARKDOWN if path.endswith(".md") else rr.MediaType.TEXT
        self.rec.log(path, rr.TextDocument(text, media_type=media), static=True)

    def send(self) -> None:
        """Send everything buffered (one chunk per entity)."""
        self._send_frames()
        for entity in list(self._buffers):
            self._send_entity(entity)
        self._last_send = time.monotonic()

    def complete(self) -> None:
        """Send the rest and the records; write the layout if not yet."""
        self.send()
        for ref in self._references:
            self._send_reference(ref)
        self._references = []
        if not self._blueprint_sent:
            self._send_blueprint()

    def finish(self) -> list:
        """Flush and close the sinks (bounded for a viewer); returns warnings, never raises for
        a viewer."""
        return finish(self.rec, self.urls, self.viewer.timeout_s)

    def close(self) -> list:
        self.complete()
        return self.finish()

    # -- engines -----------------------------------------------------------------------------------
    def _engine(self, engine, d):
        t, angle = d["t"], d["angle"]
        ok = np.isfinite(t) & np.isfinite(angle)       # a sample without a place on the timelines is dropped
        if not ok.all():
            d = _masked(d, ok)
            t, angle = d["t"], d["angle"]
        if engine not in self._engines:
            self._start_engine(engine)
        e, color = part(engine), self._color(engine)
        self._history.setdefault(engine, []).append((t, angle))
        if t.size:
            for g, (bending, axial) in d["gauges"].items():
                self._add(f"/{e}/strain/{part(g)}", t, angle, bending * MICRO, [f"{engine} bending [µε]"], [color])
                # One plot holds every gauge's axial strain: a shade of the engine colour per gauge.
                shade = shades(color, 1 + list(d["gauges"]).index(g))[-1]
                self._add(f"/{e}/axial_strain/{part(g)}", t, angle, axial * MICRO, [f"{engine} {g} axial [µε]"],
                          [shade])
            self._add(f"/{e}/drive_torque", t, angle, d["torque"], [f"{engine} drive torque [N m]"], [color])
            self._add(f"/{e}/crank_speed", t, angle, d["speed"], [f"{engine} crank speed [rad/s]"], [color])
            self._add(f"/{e}/drive_power", t, angle, d["torque"] * d["speed"],
                      [f"{engine} drive power (torque × crank speed) [W]"], [color])
            for name, (unit, values) in d["extras"].items():
                self._add(f"/{e}/extras/{part(name)}", t, angle, values, [f"{engine} {name} [{unit}]"], [color])
        motor = d.get("motor")
        if motor is not None and np.size(motor.get("t")):
            units = d.get("motor_units") or {}
            mt, ma = motor["t"], motor["crank_angle_rad"]
            for group, fields in motor_groups(motor).items():
                values = np.column_stack([motor[f] for f in fields])
                self._add(f"/motor/{e}/{group}", mt, ma, values if len(fields) > 1 else values[:, 0],
                          [f"{engine} {motor_label(f)} [{units.get(f, '?')}]" for f in fields],
                          shades(color, len(fields)))
        if d["frames"]:
            self._frames.setdefault(engine, []).extend(d["frames"])

    def _start_engine(self, engine):
        """Static drawing settings of an engine, when its first output arrives (only engines that
        run get a root, including one the spec does not name)."""
        self._engines.append(engine)
        e = part(engine)
        # Rerun's 2D view points y down (image convention, not configurable: rerun issue #1387);
        # the mechanism's frame has y up, so the drawing is flipped.
        self.rec.log(f"/{e}/linkage", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        self.rec.log(f"/{e}/linkage/straight", rr.LineStrips2D.from_fields(
            colors=[STRAIGHT_COLOR], radii=[rr.Radius.ui_points(1.0)], draw_order=1.0), static=True)
        self.rec.log(f"/{e}/linkage/deformed", rr.LineStrips2D.from_fields(
            colors=[self._color(engine)], radii=[rr.Radius.ui_points(2.0)], draw_order=2.0), static=True)
        if self._blueprint_sent and engine not in self.spec.engines:
            self._send_blueprint()                     # its views must name it
        elif self.exaggeration is not None:
            self._legend()

    # -- linkage -----------------------------------------------------------------------------------
    def _send_frames(self):
        frames = {e: blocks for e, blocks in self._frames.items() if blocks}      # {engine: [FrameBlock]}
        if not frames:
            return
        if self.exaggeration is None:
            # The factor is fixed by the first frames sent: with a file only, the whole run.
            largest = max(drawing.largest_offset(b.nodes, self.stations.get(e)) for e, bs in frames.items() for b in bs)
            longest = max([length for _, length in self.spec.links] or [0.0])
            self.exaggeration = drawing.auto_factor(largest, longest)
            self._send_blueprint()
        k = self.exaggeration
        for engine, blocks in frames.items():
            e = part(engine)
            straight, deformed, counts = [], [], []
            for b in blocks:
                s, d, c = drawing.block_strips(b.nodes, len(b.t), self.stations.get(engine), k)
                straight += s
                deformed += d
                counts += c
            index = time_columns(np.concatenate([b.t for b in blocks]), np.concatenate([b.angle for b in blocks]))
            self.rec.send_columns(f"/{e}/linkage/straight", indexes=index,
                                  columns=rr.LineStrips2D.columns(strips=strips_array(straight)).partition(counts))
            self.rec.send_columns(f"/{e}/linkage/deformed", indexes=index,
                                  columns=rr.LineStrips2D.columns(strips=strips_array(deformed)).partition(counts))
            blocks.clear()

    def _legend(self):
        """The linkage view's engine legend: a labelled dot per engine in its colour, at the view's
        top left (static, so it shows at every time)."""
        if self.spec.bounds is None:
            return
        (x_lo, x_hi), (y_lo, y_hi) = self.spec.bounds
        size = max(x_hi - x_lo, y_hi - y_lo)
        for i, engine in enumerate(self._engines):           # only engines that ran
            # Top left inside the view (its bounds add 15 % around the linkage; labels centre on the dot).
            pos = [x_lo + 0.1 * size, y_hi + 0.12 * size - 0.07 * size * i]
            self.rec.log(f"/{part(engine)}/linkage/legend", rr.Points2D(
                [pos], colors=[self._color(engine)], radii=[rr.Radius.ui_points(5.0)],
                labels=[f"{engine}" + (f" (deformation ×{self.exaggeration:g})" if self.exaggeration else "")],
                show_labels=True), static=True)

    # -- statics and layout ------------------------------------------------------------------------
    def _log_statics(self):
        if self.spec.ground is not None:
            self.rec.log("/ground", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
            self.rec.log("/ground/line", rr.LineStrips2D([self.spec.ground], colors=[STRAIGHT_COLOR],
                                                         radii=[rr.Radius.ui_points(1.0)]), static=True)
        self._note()

    def _note(self):
        k = "chosen from the largest deformation" if self.exaggeration is None else f"×{self.exaggeration:g}"
        note = (f"Linkage drawing: each link as a straight grey line between its joints (the engine's end nodes), "
                f"and in the engine's colour its nodes with their offset from that line (the link's own bending "
                f"and stretch) exaggerated {k}; the joints are where the engine put them. Global frame, metres, "
                f"y up; at most the run's linkage frame rate.\n\n"
                f"Strains in microstrain [µε] (positive = tension on the gauged face). Timelines: {SIM_TIME} [s]; "
                f"{CRANK_ANGLE} = each engine's own cumulative crank angle [mdeg]; {CRANK_ANGLE_WRAPPED} = the same "
                f"within a revolution, 0-360 000 mdeg (choose it in the time panel to overlay the revolutions); "
                f"{REVOLUTION} = which revolution (crank angle // 360 deg).")
        self.rec.log("/scenario/linkage_drawing", rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)

    def _send_blueprint(self):
        bp = run_blueprint(self.spec, self._engines, self.exaggeration)
        self.rec.send_blueprint(bp, make_active=True, make_default=True)
        self._blueprint_sent = True
        if self.exaggeration is not None:
            self._note()
            self._legend()

    # -- scalars -----------------------------------------------------------------------------------
    def _declare(self, entity, names, colors, width=1.5):
        """Static series names (engine, quantity, unit) and colours of a scalar entity, once."""
        if entity in self._declared:
            return
        self._declared.add(entity)
        self.rec.log(entity, rr.SeriesLines(names=names, colors=colors, widths=[width] * len(names)), static=True)

    def _add(self, entity, t, angle, values, names, colors):
        self._declare(entity, names, colors)
        self._buffers.setdefault(entity, []).append((t, angle, np.asarray(values, dtype=float)))

    def _send_entity(self, entity):
        rows = self._buffers.pop(entity, [])
        if rows:
            t = np.concatenate([r[0] for r in rows])
            a = np.concatenate([r[1] for r in rows])
            v = np.concatenate([r[2] for r in rows])
            self._send_scalars(entity, t, a, v)

    def _send_scalars(self, entity, t, angle, values):
        self.rec.send_columns(entity, indexes=time_columns(t, angle), columns=rr.Scalars.columns(scalars=values))

    # -- records -----------------------------------------------------------------------------------
    def _send_reference(self, ref):
        t_hist, a_hist = self._reference_history()
        t_lo, t_hi, a_lo, a_hi = alignment.extent([h for hs in self._history.values() for h in hs],
                                                  self.spec.speed_rad_s, self.spec.start_angle_rad)
        w, a0 = self.spec.speed_rad_s, self.spec.start_angle_rad
        if ref.t is None and ref.angle is None:            # constant lines across the run
            self._send_scalars(ref.entity, [t_lo, t_hi], [a_lo, a_hi], np.vstack([ref.values, ref.values]))
            return
        if ref.t is not None:
            t, values = ref.t, ref.values
            angle = alignment.angle_at(t, t_hist, a_hist, w, a0)
        else:
            angle, values = alignment.repeat_revolution(ref.angle, ref.values, a_lo, a_hi)
            t = alignment.time_at(angle, t_hist, a_hist, w, a0)
        if len(t):
            self._send_scalars(ref.entity, t, angle, values if values.shape[1] > 1 else values[:, 0])

    def _reference_history(self):
        """(t, angle) of the first engine that logged any (records are placed on its crank)."""
        for engine in [*self.spec.engines, *self._engines]:
            hs = self._history.get(engine)
            if hs and sum(len(h[0]) for h in hs):
                return np.concatenate([h[0] for h in hs]), np.concatenate([h[1] for h in hs])
        return np.zeros(0), np.zeros(0)

    def _color(self, engine):
        return engine_color(engine, [*self.spec.engines, *self._engines])


def _masked(d: dict, ok) -> dict:
    """An engine batch without the samples where ``ok`` is False (motor traces and frames keep
    their own samples)."""
    out = dict(d, t=d["t"][ok], angle=d["angle"][ok], speed=d["speed"][ok], torque=d["torque"][ok])
    out["gauges"] = {g: (b[ok], a[ok]) for g, (b, a) in d["gauges"].items()}
    out["extras"] = {n: (u, v[ok]) for n, (u, v) in d["extras"].items()}
    return out
