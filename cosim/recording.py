"""Stream a co-simulation run into one rerun recording (``.rrd``), with a default blueprint.

A :class:`Recorder` receives the master's :class:`cosim.master.MacroStep` after every macro step
(``Recorder.log_macro_step`` is a ready-made callback body) and writes everything into ONE
recording: a file (the default, headless use), and optionally a spawned or an already running
viewer. A default blueprint goes with the data, so whoever opens the file sees, without arranging
anything, one strain plot per gauge with that gauge from every engine and every record, the
drive torque, the linkage of every engine in 2D, and the motor's current, voltage and torque.

Timelines
---------
``sim_time``
    simulated time, a *duration* timeline [s] (stored in ns).
``crank_angle_mdeg``
    the crank angle as an integer *sequence* timeline: ``round(degrees(angle) * 1000)``, i.e.
    millidegrees, cumulative (it does not wrap at 360 deg), counter-clockwise positive, from the
    ground line A->D. Rerun timelines are integers, durations or timestamps, hence the
    millidegrees. Every engine is logged on its *own* crank angle (in motor mode the engines'
    cranks drift apart), motor traces on their motor's crank angle.

Entity layout (``<e>`` is an engine name: tmm, exudyn, mujoco; ``<g>`` a gauge; ``<l>`` a link)
------------------------------------------------------------------------------------------------
``/<e>/strain/<g>``                 Scalars [bending, axial] in microstrain [µε] (series named
                                    "<e> bending [µε]", "<e> axial [µε]")
``/<e>/drive_torque``               drive torque at the crank pivot [N m], CCW positive
``/<e>/crank_speed``                crank speed [rad/s]
``/<e>/extras/<name>``              engine-specific signals, unit from the engine (e.g. MuJoCo's
                                    loop_closure_m [m])
``/<e>/linkage``                    static Transform3D flipping y for the 2D view (see below)
``/<e>/linkage/rigid``              LineStrips2D, one strip per link through the engine's nodes at
                                    their rigid-body positions (grey) plus the ground line A-D
``/<e>/linkage/deformed``           LineStrips2D, nodes at rigid position + exaggeration x elastic
                                    displacement (engine colour); the factor is in the strip
                                    labels, the view title and ``/scenario/linkage_drawing``
``/<e>/events``                     TextLog: an engine that failed, with the error
``/motor/<e>/current``              armature current [A]
``/motor/<e>/voltage``              armature voltage [V]
``/motor/<e>/torque``               [electromagnetic torque (motor shaft), drive torque (crank)] [N m]
``/motor/<e>/speed``                [motor speed, crank speed, set-point] [rad/s]
``/motor/<e>/power``                [electrical power, copper loss, friction loss] [W]
``/motor/<e>/energy``               [energy in, copper loss, friction loss, drive work] [J]
``/motor/<e>/<field>``              any other MotorTrace field, unit from ``MotorTrace.UNITS``
``/motor/<e>/power_demand``         prescribed mode (no motor): drive torque x crank speed [W],
                                    the power a drive would have to deliver
``/records/strain/<g>/<label>``     a record of gauge <g> (:meth:`Recorder.log_reference`):
                                    [bending, axial] [µε], or constant lines for peak statistics
``/scenario/...``                   text documents (resolved scenario, drawing note, ...)

Every scalar entity carries a static ``SeriesLines`` with one name per series naming the engine
(or record), the quantity and its unit, so legends are self-explanatory.

Bulk data goes through the columnar API (``send_columns``): samples are buffered for a few macro
steps and sent as one chunk per entity. The linkage is drawn once every ``linkage_every`` macro
steps, at the last sample of the step.

2D drawing: rerun's 2D view draws +y *downwards* (image convention; 2D view coordinates are not
configurable, rerun issue #1387). The linkage data are logged in the mechanism's global frame (y
up) and a static ``Transform3D`` with scale (1, -1, 1) on ``/<e>/linkage`` turns them upright.

Reading back: :func:`read_back` (entity -> number of samples), :func:`read_scalars` (the values
of one scalar entity) and :func:`read_blueprint` (the views of the default blueprint) use rerun's
own reader, ``rerun.chunk.RrdReader``.
"""
from __future__ import annotations

import dataclasses
import math
import re
import warnings
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

SIM_TIME = "sim_time"
CRANK_ANGLE = "crank_angle_mdeg"
MICRO = 1e6                                   # dimensionless strain -> microstrain
DEFAULT_VIEWER_PORT = 9876
MODES = ("prescribed", "motor")                # as cosim.master.MODES (not imported: keeps this module light)

ENGINE_COLORS = {"tmm": (31, 119, 180), "exudyn": (255, 127, 14), "mujoco": (44, 160, 44)}
_SPARE_COLORS = [(148, 103, 189), (140, 86, 75), (227, 119, 194), (23, 190, 207), (188, 189, 34)]
RECORD_COLORS = [(20, 20, 20), (214, 39, 40), (127, 127, 127), (120, 60, 160)]
RIGID_COLOR = (150, 150, 150)

# Motor trace fields grouped into multi-series entities (the rest get one entity each).
MOTOR_GROUPS = {
    "current": ("current_A",),
    "voltage": ("voltage_V",),
    "torque": ("torque_em_Nm", "drive_torque_Nm"),
    "speed": ("motor_speed_rad_s", "crank_speed_rad_s", "setpoint_rad_s"),
    "power": ("electrical_power_W", "copper_loss_W", "friction_loss_W"),
    "energy": ("energy_in_J", "copper_loss_J", "friction_loss_J", "drive_work_J"),
}
_UNIT_SUFFIXES = ("_rad_s2", "_rad_s", "_rad", "_Nm", "_A", "_V", "_W", "_J")


def _plot(*, name: str, contents) -> rrb.TimeSeriesView:
    """A time-series view that opens on the whole run: without an explicit x range the viewer
    shows only a short window around the time cursor on sequence timelines (crank angle)."""
    whole = rrb.TimeRange(start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.infinite())
    return rrb.TimeSeriesView(name=name, contents=contents, axis_x=rrb.TimeAxis(view_range=whole))


def _part(name) -> str:
    """One entity-path part from a free-form name (no slashes, spaces or other specials), so the
    blueprint's queries can name the same path without escaping."""
    s = re.sub(r"[^A-Za-z0-9_.\-]+", "_", str(name)).strip("_")
    return s or "unnamed"


def _mdeg(angle_rad) -> np.ndarray:
    return np.rint(np.degrees(np.asarray(angle_rad, dtype=float)) * 1000.0).astype(np.int64)


def _shades(color, n: int) -> list:
    """``n`` distinguishable shades of one colour: the colour, then lighter and darker ones."""
    out = []
    for i in range(n):
        f = (0.0, 0.45, -0.35, 0.7, -0.55)[i % 5]
        target = 255 if f > 0 else 0
        out.append(tuple(int(round(c + abs(f) * (target - c))) for c in color))
    return out


def _pretty_field(field: str) -> str:
    for suffix in _UNIT_SUFFIXES:
        if field.endswith(suffix):
            field = field[: -len(suffix)]
            break
    return field.replace("_", " ")


class _ScalarBuffer:
    """Samples of one scalar entity waiting to be sent in one ``send_columns`` call."""

    def __init__(self):
        self.t, self.angle, self.values = [], [], []

    def add(self, t, angle, values):
        t, angle, values = np.asarray(t, dtype=float), np.asarray(angle, dtype=float), np.asarray(values, dtype=float)
        ok = np.isfinite(t) & np.isfinite(angle)       # a sample without a place on both timelines is dropped
        if not ok.all():
            t, angle, values = t[ok], angle[ok], values[ok]
        self.t.append(t)
        self.angle.append(_mdeg(angle))
        self.values.append(values)

    def __len__(self):
        return sum(len(t) for t in self.t)

    def take(self):
        out = np.concatenate(self.t), np.concatenate(self.angle), np.concatenate(self.values)
        self.t, self.angle, self.values = [], [], []
        return out


@dataclasses.dataclass
class _Reference:
    """A record waiting for :meth:`Recorder.close` (it is placed against the run's extent)."""

    entity: str
    t: np.ndarray | None
    angle: np.ndarray | None
    values: np.ndarray                 # (k, m) microstrain, or (m,) constants


class Recorder:
    """Streams a co-simulation run into one rerun recording (see the module docstring for layout,
    units and timelines).

    Use as ``callback`` body of :meth:`cosim.master.CoSimulation.run` (``log_macro_step``), then
    :meth:`close` (or use the recorder as a context manager). Samples are buffered for
    ``flush_every_steps`` macro steps (class attribute) before being sent.
    """

    flush_every_steps = 10              # macro steps buffered before a send (live viewers update then)
    flush_samples = 50_000              # ... or this many buffered samples, whichever comes first

    def __init__(self, scenario, engines: dict, mode: str, *, save_path=None, spawn: bool = False,
                 connect: str | None = None, exaggeration: float = 20.0, linkage_every: int = 1,
                 application_id: str = "flexlink-bench"):
        """engines: {engine_name: {link_name: node stations (local x, m) of that engine's nodes}}
        (each engine meshes links differently; rigid node positions are computed from the
        scenario's kinematics at the engine's crank angle and these stations).
        save_path: write the .rrd there (the default use, headless). spawn: also spawn a viewer.
        connect: also stream to a running viewer at this address (e.g. "rerun+http://127.0.0.1:9876/proxy").
        exaggeration: factor applied to the elastic displacement when drawing the deformed linkage;
        declared in the recording (as text) so readers know it."""
        if save_path is None and not spawn and not connect:
            raise ValueError("Recorder needs somewhere to send the recording: give save_path (an .rrd file), "
                             "spawn=True or connect='rerun+http://host:port/proxy'")
        if not (isinstance(exaggeration, (int, float)) and math.isfinite(exaggeration) and exaggeration > 0):
            raise ValueError(f"exaggeration must be a positive finite number, got {exaggeration!r}")
        if not (isinstance(linkage_every, int) and linkage_every >= 1):
            raise ValueError(f"linkage_every must be a positive integer, got {linkage_every!r}")
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        self.scenario = scenario
        self.mode = mode
        self.engines = {name: dict(stations or {}) for name, stations in engines.items()}
        self.exaggeration = float(exaggeration)
        self.linkage_every = linkage_every
        self.save_path = Path(save_path) if save_path is not None else None
        self._buffers: dict[str, _ScalarBuffer] = {}
        self._linkage: dict[str, list] = {}          # entity -> [(t, angle, strips, labels | None)]
        self._pending_linkage: dict[str, list] = {}  # engine -> [(t, angle, {link: nodes (n, 2)})]
        self._declared: set = set()
        self._started: set = set()                   # engines whose statics are logged
        self._references: list[_Reference] = []
        self._steps_buffered = 0
        self._history: dict[str, list] = {}          # engine -> [(t, angle)] arrays, for records
        self._warned: set = set()
        self._closed = False

        self.rec = rr.RecordingStream(application_id)
        self.blueprint = self._blueprint()
        sinks = []
        if self.save_path is not None:
            self.save_path.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(str(self.save_path)))
        urls = []
        if spawn:
            # Spawn the viewer only; the connection is one of our sinks so that file and viewer
            # receive the same stream (set_sinks replaces whatever spawn(connect=True) would add).
            rr.spawn(port=DEFAULT_VIEWER_PORT, connect=False, recording=self.rec)
            urls.append(f"rerun+http://127.0.0.1:{DEFAULT_VIEWER_PORT}/proxy")
        if connect and connect not in urls:
            urls.append(connect)
        sinks += [rr.GrpcSink(u) for u in urls]
        self.rec.set_sinks(*sinks, default_blueprint=self.blueprint)
        if urls:
            # A viewer that already shows this application keeps its active layout; make ours active.
            self.rec.send_blueprint(self.blueprint, make_active=True, make_default=False)
        self.rec.send_recording_name(f"{scenario.name} ({mode})")
        self._log_statics()

    # -- public API -------------------------------------------------------------------------------
    def log_macro_step(self, step) -> None:
        """Buffer one :class:`cosim.master.MacroStep`; send every ``flush_every_steps`` steps."""
        self._check_open()
        draw = (step.step - 1) % self.linkage_every == 0 or step.step == step.n_steps
        for engine, (out, trace) in step.outputs.items():
            self._engine_output(engine, out, draw)
            if trace is not None:
                self._motor_trace(engine, trace)
            elif np.size(out.t):
                # Prescribed speed: no motor, but what a drive would have to deliver (torque times
                # crank speed) is the motor-side quantity a user sizes a motor with.
                entity = f"/motor/{_part(engine)}/power_demand"
                self._declare(entity, [f"{engine} drive power demand [W]"], [self._color(engine)])
                self._add(entity, np.asarray(out.t, float), np.asarray(out.crank_angle, float),
                          np.asarray(out.drive_torque, float) * np.asarray(out.crank_speed, float))
        for engine, message in (step.failed or {}).items():
            self.rec.set_time(SIM_TIME, duration=float(step.t))
            self.rec.log(f"/{_part(engine)}/events", rr.TextLog(f"{engine} failed: {message}", level="ERROR"))
            self.rec.reset_time()
        self._steps_buffered += 1
        if (self._steps_buffered >= self.flush_every_steps
                or sum(len(b) for b in self._buffers.values()) >= self.flush_samples):
            self._send_buffers()

    def log_reference(self, gauge: str, label: str, t=None, angle=None, bending_ue=None, axial_ue=None,
                      kind: str = "measurement") -> None:
        """A record for a gauge (issue 7 will call this): a history over time or crank angle, or
        constant lines for peak statistics; logged under /records/...

        * ``t`` [s] given: a history over simulated time;
        * ``angle`` [rad] given: a history over one crank revolution (same angle convention as the
          engines); it is repeated over every revolution the run covers;
        * neither: ``bending_ue`` / ``axial_ue`` are constants (a number, or several such as
          (+peak, -peak)) drawn as horizontal lines across the run.

        Values in microstrain. The record is written at :meth:`close`, once the run's extent in
        time and crank angle is known; the crank angle of a time history (and the time of an
        angle history) comes from the first engine's crank, or the scenario's nominal speed
        outside its samples. ``kind`` (measurement, published model, synthetic, ...) goes into the
        series names."""
        self._check_open()
        if t is not None and angle is not None:
            raise ValueError("log_reference: give t or angle, not both")
        comps = [(c, v) for c, v in (("bending", bending_ue), ("axial", axial_ue)) if v is not None]
        if not comps:
            raise ValueError(f"log_reference({gauge!r}, {label!r}): give bending_ue and/or axial_ue")
        entity = f"/records/strain/{_part(gauge)}/{_part(label)}"
        colors = RECORD_COLORS[len(self._references) % len(RECORD_COLORS)]
        if t is None and angle is None:
            names, vals = [], []
            for comp, v in comps:
                v = np.atleast_1d(np.asarray(v, dtype=float)).ravel()
                tags = ["+peak", "-peak"] if len(v) == 2 else ([""] if len(v) == 1 else
                                                               [f"#{i + 1}" for i in range(len(v))])
                names += [" ".join(filter(None, (label, f"({kind})", comp, tag))) + " [µε]" for tag in tags]
                vals.append(v)
            values = np.concatenate(vals)
            self._references.append(_Reference(entity, None, None, values))
        else:
            x = np.asarray(t if t is not None else angle, dtype=float).ravel()
            cols = [np.asarray(v, dtype=float).ravel() for _, v in comps]
            for (comp, _), c in zip(comps, cols):
                if c.shape != x.shape:
                    raise ValueError(f"log_reference({gauge!r}, {label!r}): {comp}_ue has {c.size} values, "
                                     f"{'t' if t is not None else 'angle'} has {x.size}")
            names = [f"{label} ({kind}) {comp} [µε]" for comp, _ in comps]
            values = np.column_stack(cols)
            self._references.append(_Reference(entity, x if t is not None else None,
                                               x if angle is not None else None, values))
        self._declare(entity, names, _shades(colors, len(names)), width=2.5)

    def log_text(self, entity: str, text: str) -> None:
        """A static text document; a relative ``entity`` goes under ``/scenario``."""
        self._check_open()
        path = entity if entity.startswith("/") else "/scenario/" + "/".join(_part(p) for p in entity.split("/"))
        media = rr.MediaType.MARKDOWN if entity.endswith(".md") else rr.MediaType.TEXT
        self.rec.log(path, rr.TextDocument(text, media_type=media), static=True)

    def flush(self) -> None:
        """Send everything buffered and wait until the sinks have it."""
        self._check_open()
        self._send_buffers()
        self.rec.flush()

    def close(self) -> None:
        """Send the buffers and the records, finish the file (footer) and disconnect; idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            self._send_buffers()
            for ref in self._references:
                self._send_reference(ref)
            try:
                self.rec.flush()
            except RuntimeError as exc:     # e.g. the viewer went away: the file must still be finished
                warnings.warn(f"recording: flushing to the viewer failed: {exc}", RuntimeWarning, stacklevel=2)
        finally:
            # disconnect() closes the sinks: the FileSink then writes its footer (manifest).
            self.rec.disconnect()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- engines ------------------------------------------------------------------------------------
    def _engine_output(self, engine, out, draw):
        e = _part(engine)
        t, angle = np.asarray(out.t, dtype=float), np.asarray(out.crank_angle, dtype=float)
        if t.size == 0:
            return
        self._ensure_engine(engine)
        color = self._color(engine)
        self._history.setdefault(engine, []).append((t, angle))
        for gauge, (bending, axial) in out.gauges.items():
            entity = f"/{e}/strain/{_part(gauge)}"
            self._declare(entity, [f"{engine} bending [µε]", f"{engine} axial [µε]"], _shades(color, 2))
            self._add(entity, t, angle, np.column_stack([np.asarray(bending, float), np.asarray(axial, float)]) * MICRO)
        self._declare(f"/{e}/drive_torque", [f"{engine} drive torque [N m]"], [color])
        self._add(f"/{e}/drive_torque", t, angle, out.drive_torque)
        self._declare(f"/{e}/crank_speed", [f"{engine} crank speed [rad/s]"], [color])
        self._add(f"/{e}/crank_speed", t, angle, out.crank_speed)
        for name, (unit, values) in out.extras.items():
            entity = f"/{e}/extras/{_part(name)}"
            self._declare(entity, [f"{engine} {name} [{unit}]"], [color])
            self._add(entity, t, angle, values)
        if draw:
            self._buffer_linkage(engine, out)

    def _motor_trace(self, engine, trace):
        e = _part(engine)
        t = np.asarray(trace.t, dtype=float)
        if t.size == 0:
            return
        units = type(trace).UNITS
        fields = [f.name for f in dataclasses.fields(trace) if f.name not in ("t",)]
        groups = {g: [f for f in fs if f in fields] for g, fs in MOTOR_GROUPS.items()}
        grouped = {f for fs in groups.values() for f in fs}
        groups.update({_part(f): [f] for f in fields if f not in grouped})
        color = self._color(engine)
        for group, fs in groups.items():
            if not fs:
                continue
            entity = f"/motor/{e}/{group}"
            names = [f"{engine} motor {_pretty_field(f)} [{units.get(f, '?')}]" for f in fs]
            self._declare(entity, names, _shades(color, len(fs)))
            values = np.column_stack([np.asarray(getattr(trace, f), dtype=float) for f in fs])
            self._add(entity, t, trace.crank_angle_rad, values if len(fs) > 1 else values[:, 0])

    # -- linkage ------------------------------------------------------------------------------------
    def _buffer_linkage(self, engine, out):
        """Keep the last sample of the step (time, crank angle, node positions) for drawing; the
        strips are built at send time, with the kinematics of all buffered steps in one call."""
        nodes = {name: np.asarray(v, dtype=float)[-1] for name, v in out.nodes.items()}
        self._pending_linkage.setdefault(engine, []).append((float(out.t[-1]), float(out.crank_angle[-1]), nodes))

    def _draw_linkage(self, engine, rows):
        """Rigid and deformed strips of the buffered steps (skipped, with one warning, where the
        kinematics cannot assemble or the nodes do not match the stations)."""
        e = _part(engine)
        mech = self.scenario.mechanism
        angles = np.array([r[1] for r in rows])
        try:
            motions = [(mech.motion(angles), np.arange(len(rows)))]
        except Exception:               # one angle that cannot assemble must not drop the others
            motions = []
            for i, angle in enumerate(angles):
                try:
                    motions.append((mech.motion(angles[i:i + 1]), np.array([i])))
                except Exception as exc:    # toggle/assembly errors must not stop the run
                    self._warn(f"kin:{engine}", f"recording: no linkage drawing for {engine} at {angle:.4g} rad: {exc}")
        for motion, index in motions:
            ground = [getattr(motion, p, None) for p in ("A", "D")]
            base = {}
            for link in mech.links():
                n_nodes = next((np.shape(rows[i][2][link.name])[0] for i in index if link.name in rows[i][2]), None)
                stations = self._stations(engine, link, n_nodes)
                base[link.name] = np.asarray(motion.link(link.name).point(stations)[0])       # (b, n, 2)
            for j, i in enumerate(index):
                t, angle, nodes = rows[i]
                rigid = [np.array([np.asarray(g)[j] for g in ground])] if all(g is not None for g in ground) else []
                deformed, labels = [], []
                for link in mech.links():
                    b = base[link.name][j]
                    rigid.append(b)
                    now = nodes.get(link.name)
                    if now is None:
                        continue
                    if now.shape != b.shape:
                        self._warn(f"nodes:{engine}:{link.name}",
                                   f"recording: {engine} reports {now.shape[0]} nodes on {link.name} but has "
                                   f"{b.shape[0]} stations; its deformed shape is not drawn")
                        continue
                    deformed.append(b + self.exaggeration * (now - b))
                    labels.append(f"{engine} {link.name} (elastic ×{self.exaggeration:g})")
                self._linkage.setdefault(f"/{e}/linkage/rigid", []).append((t, angle, rigid, None))
                if deformed:
                    self._linkage.setdefault(f"/{e}/linkage/deformed", []).append((t, angle, deformed, labels))

    def _stations(self, engine, link, n_nodes):
        """The engine's stations of ``link``; else the scenario's if they match the node count;
        else evenly spaced over the link."""
        given = self.engines.get(engine, {}).get(link.name)
        if given is not None:
            return np.asarray(given, dtype=float)
        own = np.asarray(link.stations, dtype=float)
        if n_nodes is None or n_nodes == len(own):
            return own
        return np.linspace(0.0, float(link.length_m), n_nodes)

    # -- sending ------------------------------------------------------------------------------------
    def _add(self, entity, t, angle, values):
        self._buffers.setdefault(entity, _ScalarBuffer()).add(t, angle, values)

    def _send_buffers(self):
        for engine, rows in self._pending_linkage.items():
            if rows:
                self._draw_linkage(engine, rows)
                rows.clear()
        for entity, buf in self._buffers.items():
            if len(buf):
                t, mdeg, values = buf.take()
                self._send_scalars(entity, t, mdeg, values)
        for entity, rows in self._linkage.items():
            if not rows:
                continue
            strips = [s for _, _, row, _ in rows for s in row]
            columns = rr.LineStrips2D.columns(strips=strips)
            if rows[0][3] is not None:
                columns = rr.LineStrips2D.columns(strips=strips, labels=[lab for *_, labs in rows for lab in labs])
            self.rec.send_columns(entity, indexes=self._time_columns([r[0] for r in rows], _mdeg([r[1] for r in rows])),
                                  columns=columns.partition([len(r[2]) for r in rows]))
            rows.clear()
        self._steps_buffered = 0

    def _send_scalars(self, entity, t, mdeg, values):
        self.rec.send_columns(entity, indexes=self._time_columns(t, mdeg), columns=rr.Scalars.columns(scalars=values))

    @staticmethod
    def _time_columns(t, mdeg):
        return [rr.TimeColumn(SIM_TIME, duration=np.asarray(t, dtype=float)),
                rr.TimeColumn(CRANK_ANGLE, sequence=np.asarray(mdeg, dtype=np.int64))]

    def _send_reference(self, ref: _Reference):
        t_hist, a_hist = self._reference_history()
        t_lo, t_hi, a_lo, a_hi = self._extent()
        if ref.t is None and ref.angle is None:            # constant lines across the run
            self._send_scalars(ref.entity, [t_lo, t_hi], _mdeg([a_lo, a_hi]), np.vstack([ref.values, ref.values]))
            return
        if ref.t is not None:
            t = ref.t
            angle = self._angle_at(t, t_hist, a_hist)
            values = ref.values
        else:
            # One revolution, repeated over every revolution in [a_lo, a_hi].
            a = ref.angle
            k = np.arange(math.floor((a_lo - a.max()) / (2 * math.pi)), math.ceil((a_hi - a.min()) / (2 * math.pi)) + 1)
            angle = (a[None, :] + 2 * math.pi * k[:, None]).ravel()
            values = np.tile(ref.values, (len(k), 1))
            keep = (angle >= a_lo - 1e-12) & (angle <= a_hi + 1e-12)
            angle, values = angle[keep], values[keep]
            order = np.argsort(angle)
            angle, values = angle[order], values[order]
            t = self._time_at(angle, t_hist, a_hist)
        if len(t):
            self._send_scalars(ref.entity, t, _mdeg(angle), values if values.shape[1] > 1 else values[:, 0])

    def _reference_history(self):
        """(t, angle) samples of the first engine that logged any (records are placed on its crank)."""
        for engine in list(self.engines) + [e for e in self._history if e not in self.engines]:
            if self._history.get(engine):
                t = np.concatenate([h[0] for h in self._history[engine]])
                a = np.concatenate([h[1] for h in self._history[engine]])
                return t, a
        return np.zeros(0), np.zeros(0)

    def _extent(self):
        """Time and crank-angle span of everything the engines logged (one nominal revolution if none)."""
        ts = [h[0] for hs in self._history.values() for h in hs]
        As = [h[1] for hs in self._history.values() for h in hs]
        if ts:
            t_all, a_all = np.concatenate(ts), np.concatenate(As)
            return float(t_all.min()), float(t_all.max()), float(a_all.min()), float(a_all.max())
        w, a0 = self._nominal()
        a1 = a0 + math.copysign(2 * math.pi, w)
        return 0.0, 2 * math.pi / abs(w), min(a0, a1), max(a0, a1)

    def _nominal(self):
        drive = self.scenario.drive
        w = float(drive.speed_rad_s) or 1.0
        return w, float(drive.start_angle_rad)

    def _angle_at(self, t, t_hist, a_hist):
        w, a0 = self._nominal()
        if len(t_hist) < 2:
            return a0 + w * t
        a = np.interp(t, t_hist, a_hist)
        # Outside the engine's samples: continue at the nominal speed.
        a = np.where(t < t_hist[0], a_hist[0] + w * (t - t_hist[0]), a)
        return np.where(t > t_hist[-1], a_hist[-1] + w * (t - t_hist[-1]), a)

    def _time_at(self, angle, t_hist, a_hist):
        w, a0 = self._nominal()
        d = np.diff(a_hist)
        if len(a_hist) < 2 or not d.any() or not (np.all(d >= 0) or np.all(d <= 0)):
            return (angle - a0) / w            # no monotone crank history: nominal speed
        order = np.argsort(a_hist)
        t = np.interp(angle, a_hist[order], t_hist[order])
        lo, hi = a_hist[order][0], a_hist[order][-1]
        t = np.where(angle < lo, t_hist[order][0] + (angle - lo) / w, t)
        return np.where(angle > hi, t_hist[order][-1] + (angle - hi) / w, t)

    # -- statics and blueprint ------------------------------------------------------------------------
    def _declare(self, entity, names, colors, width=1.5):
        """Static series names (engine, quantity, unit) and colours of a scalar entity, once."""
        if entity in self._declared:
            return
        self._declared.add(entity)
        self.rec.log(entity, rr.SeriesLines(names=names, colors=colors, widths=[width] * len(names)), static=True)

    def _log_statics(self):
        note = (f"Linkage drawing: rigid-body positions of each engine's nodes in grey; deformed shape in the "
                f"engine's colour with the elastic displacement exaggerated ×{self.exaggeration:g} "
                f"(drawn = rigid + {self.exaggeration:g} × (deformed − rigid)), at the end of every "
                f"{self.linkage_every} macro step(s). Global frame, metres, y up.\n\n"
                f"Strains in microstrain [µε] (positive = tension on the gauged face). Timelines: "
                f"{SIM_TIME} [s]; {CRANK_ANGLE} = each engine's own cumulative crank angle in millidegrees.")
        self.rec.log("/scenario/linkage_drawing", rr.TextDocument(note, media_type=rr.MediaType.MARKDOWN), static=True)

    def _ensure_engine(self, engine):
        """Static drawing settings of an engine, logged when its first output arrives (so only
        engines that run get a root, including one missing from the ``engines`` argument)."""
        if engine in self._started:
            return
        self._started.add(engine)
        e = _part(engine)
        # Upright drawing: the 2D view points y down (see module docstring).
        self.rec.log(f"/{e}/linkage", rr.Transform3D(scale=[1.0, -1.0, 1.0]), static=True)
        self.rec.log(f"/{e}/linkage/rigid", rr.LineStrips2D.from_fields(
            colors=[RIGID_COLOR], radii=[rr.Radius.ui_points(1.0)], draw_order=1.0), static=True)
        self.rec.log(f"/{e}/linkage/deformed", rr.LineStrips2D.from_fields(
            colors=[self._color(engine)], radii=[rr.Radius.ui_points(2.0)], draw_order=2.0,
            show_labels=False), static=True)

    def _blueprint(self) -> rrb.Blueprint:
        # View queries cannot wildcard one path level (only a trailing /**), so they name every
        # engine: the given ones and the bench's standard ones (a query matching nothing is harmless).
        engines = list(dict.fromkeys([_part(e) for e in self.engines] + list(ENGINE_COLORS)))
        gauge_views = []
        for g in self.scenario.gauges:
            gp = _part(g.name)
            where = f"{g.link} at {g.position_m * 1000:.4g} mm, {g.face} face"
            gauge_views.append(_plot(
                name=f"strain {g.name} [µε] ({where})",
                contents=[f"/{e}/strain/{gp}" for e in engines] + [f"/records/strain/{gp}/**"]))
        torque = _plot(name="drive torque at the crank [N m]",
                                    contents=[f"/{e}/drive_torque" for e in engines])
        speed = _plot(name="crank speed [rad/s]", contents=[f"/{e}/crank_speed" for e in engines])
        extras = _plot(name="engine extras", contents=[f"/{e}/extras/**" for e in engines])
        linkage = rrb.Spatial2DView(
            name=f"linkage: rigid (grey), deformed ×{self.exaggeration:g} elastic displacement",
            contents=[f"/{e}/linkage/**" for e in engines], visual_bounds=self._linkage_bounds())
        scenario = rrb.TextDocumentView(name="scenario", origin="/scenario")
        left = [*gauge_views, rrb.Tabs(torque, speed, extras, active_tab=0)]
        if self.mode == "motor":
            motor = [_plot(name=f"motor {q} [{u}]", contents=[f"/motor/{e}/{q}" for e in engines])
                     for q, u in (("current", "A"), ("voltage", "V"), ("torque", "N m"))]
            more = rrb.Tabs(_plot(name="motor speeds [rad/s]", contents=[f"/motor/{e}/speed" for e in engines]),
                            _plot(name="motor power and losses [W]",
                                               contents=[f"/motor/{e}/power" for e in engines]),
                            _plot(name="motor energies [J]", contents=[f"/motor/{e}/energy" for e in engines]))
            right = [rrb.Tabs(linkage, scenario, active_tab=0), *motor, more]
            right_shares = [3, 1, 1, 1, 1]
        else:
            demand = _plot(name="prescribed speed: drive power demand (torque x crank speed) [W]",
                           contents=[f"/motor/{e}/power_demand" for e in engines])
            right = [rrb.Tabs(linkage, scenario, active_tab=0), speed, demand]
            left[-1] = rrb.Tabs(torque, extras, active_tab=0)
            right_shares = [3, 1, 1]
        return rrb.Blueprint(
            rrb.Horizontal(rrb.Vertical(*left, row_shares=[3] * len(gauge_views) + [2]),
                           rrb.Vertical(*right, row_shares=right_shares),
                           column_shares=[3, 2]),
            rrb.BlueprintPanel(state="collapsed"),
            rrb.SelectionPanel(state="collapsed"),
            rrb.TimePanel(timeline=SIM_TIME, state="collapsed"),
        )

    def _linkage_bounds(self):
        """View bounds holding the rigid linkage over a revolution, with a margin for the
        exaggerated deflection (None if the kinematics cannot give them: the viewer then fits the
        data itself)."""
        try:
            motion = self.scenario.mechanism.motion(np.linspace(0.0, 2 * math.pi, 145))
            pts = np.concatenate([np.asarray(motion.link(link.name).point(np.asarray(link.stations, float))[0])
                                  .reshape(-1, 2) for link in self.scenario.mechanism.links()])
        except Exception:               # e.g. a linkage that cannot turn a full revolution
            return None
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        pad = 0.15 * float(np.max(hi - lo))
        # y_range in view coordinates: the /<e>/linkage transform flips y.
        return rrb.VisualBounds2D(x_range=[lo[0] - pad, hi[0] + pad], y_range=[-hi[1] - pad, -lo[1] + pad])

    # -- helpers --------------------------------------------------------------------------------------
    def _color(self, engine):
        if engine in ENGINE_COLORS:
            return ENGINE_COLORS[engine]
        others = [e for e in self.engines if e not in ENGINE_COLORS]
        i = others.index(engine) if engine in others else len(others)
        return _SPARE_COLORS[i % len(_SPARE_COLORS)]

    def _warn(self, key, message):
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(message, RuntimeWarning, stacklevel=3)

    def _check_open(self):
        if self._closed:
            raise RuntimeError("the Recorder is closed")


# -- reading back ------------------------------------------------------------------------------------
def _batches(path, blueprint: bool = False):
    """Arrow record batches of the recording (or its first blueprint) in an .rrd, with rerun's
    own reader (a file without footer, e.g. from an interrupted run, streams too)."""
    from rerun.chunk import RrdReader
    reader = RrdReader(str(path))
    if blueprint:
        stores = reader.blueprints()
        if not stores:
            return
        stream = reader.stream(store=stores[0])
    else:
        stream = reader.stream()
    for chunk in stream:
        yield chunk.entity_path, chunk.is_static, chunk.to_record_batch()


def _data_fields(batch):
    return [f for f in batch.schema if (f.metadata or {}).get(b"rerun:kind") == b"data"]


def _non_empty_rows(batch) -> int:
    import pyarrow as pa
    import pyarrow.compute as pc
    fields = _data_fields(batch)
    if not fields or batch.num_rows == 0:
        return 0
    any_data = np.zeros(batch.num_rows, dtype=bool)
    for f in fields:
        col = batch.column(batch.schema.get_field_index(f.name))
        ok = col.is_valid().to_numpy(zero_copy_only=False)
        if pa.types.is_list(col.type) or pa.types.is_large_list(col.type):
            ok &= pc.fill_null(pc.list_value_length(col), 0).to_numpy(zero_copy_only=False) > 0
        any_data |= ok
    return int(any_data.sum())


def read_back(path) -> dict:
    """{entity_path: number of non-empty samples} of the recording in an .rrd file.

    A sample is a row with data on a timeline; an entity with only static data (text, series
    names) counts its static rows instead (1 for a text document). Rerun's own entities
    (``/__properties``) are left out. Static series names of a time-series entity do not add to
    its count."""
    counts, static = {}, {}
    for entity, is_static, batch in _batches(path):
        if entity.startswith("/__"):
            continue
        n = _non_empty_rows(batch)
        target = static if is_static else counts
        target[entity] = target.get(entity, 0) + n
    for entity, n in static.items():
        counts.setdefault(entity, min(n, 1))        # static rows overwrite each other: one value
    return dict(sorted(counts.items()))


def read_scalars(path, entity: str, timeline: str = SIM_TIME):
    """(index, values) of a scalar entity: ``index`` in seconds for ``sim_time`` (integers for
    ``crank_angle_mdeg``), ``values`` (n, m) as logged, sorted by the index."""
    import pyarrow as pa
    idx, vals = [], []
    for ent, is_static, batch in _batches(path):
        if ent != entity or is_static or timeline not in batch.schema.names:
            continue
        col = batch.column(batch.schema.get_field_index("Scalars:scalars"))
        i = batch.column(batch.schema.get_field_index(timeline))
        i = i.cast(pa.int64()).to_numpy(zero_copy_only=False)
        idx.append(i / 1e9 if timeline == SIM_TIME else i)
        vals += [np.asarray(v, dtype=float) for v in col.to_pylist()]
    if not idx:
        raise KeyError(f"{path}: no scalar samples of {entity} on timeline {timeline}")
    index = np.concatenate(idx)
    values = np.array(vals)
    order = np.argsort(index, kind="stable")
    return index[order], values[order]


def read_blueprint(path) -> list:
    """The views of the first blueprint in an .rrd: [{"name", "class", "origin", "contents"}]
    (an empty list if the file has no blueprint)."""
    views = {}
    for entity, _, batch in _batches(path, blueprint=True):
        m = re.match(r"^/view/([^/]+)(/ViewContents)?$", entity)
        if not m:
            continue
        view = views.setdefault(m.group(1), {"name": None, "class": None, "origin": None, "contents": []})
        row = {f.name: batch.column(batch.schema.get_field_index(f.name)).to_pylist()[-1]
               for f in _data_fields(batch) if batch.num_rows}
        if m.group(2):
            view["contents"] = list(row.get("ViewContents:query") or [])
        else:
            view["name"] = _first(row.get("ViewBlueprint:display_name"))
            view["class"] = _first(row.get("ViewBlueprint:class_identifier"))
            view["origin"] = _first(row.get("ViewBlueprint:space_origin"))
    return list(views.values())


def _first(v):
    return v[0] if isinstance(v, list) and v else v
