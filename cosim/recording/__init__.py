"""Rerun recordings of the bench: a run streamed into one ``.rrd`` with its default layout, and the
sweep and uncertainty summaries.

Modules (none imports rerun at package import; ``cosim run`` keeps rerun in a child process):

==================  ====================================================================
``layout``          entity names, series names, colours, timeline values (pure)
``spec``            what the recording needs of a scenario, as plain data
``batch``           macro steps -> batches (run side: linkage frames at display rate; samples from cosim.samples)
``linkage``         the linkage drawing from the engines' nodes, its automatic factor (pure)
``references``      records checked and named for drawing (pure)
``blueprint``       the run's default layout, a pure function of the spec
``sinks``           file and viewer sinks (spawn, connect, serve, stdout) with bounded waits
``writer``          batches -> rerun chunks, one per entity and send
``recorder``        :class:`Recorder`: the API, in this process
``process``         :class:`RecorderProcess`: the same, rerun in a child process
``reader``          read a recording back (sample counts, values, layout)
``summaries``       the sweep and uncertainty recordings (2D charts that read in rpm and deg)
``charts``          x-y charts drawn in rerun's 2D view
``animation``       a GIF of the linkage from a run's nodes (matplotlib)
==================  ====================================================================

Timelines
---------
``sim_time``
    simulated time, a *duration* timeline [s] (stored in ns).
``crank_angle_mdeg``
    the crank angle as an integer *sequence* timeline: ``round(degrees(angle) * 1000)``,
    millidegrees, cumulative (it does not wrap), counter-clockwise positive, from the ground
    line A->D. Rerun timelines are integers, durations or timestamps, hence the millidegrees.
``crank_angle_wrapped_mdeg``
    the same crank angle within its revolution, 0 <= value < 360 000: with this timeline chosen
    in the time panel the revolutions lie on top of each other.
``revolution``
    which revolution a sample belongs to: cumulative millidegrees // 360 000.

Every engine is logged on its *own* crank angle (in motor mode the engines' cranks drift apart),
motor traces on their motor's crank angle.

Entity layout (``<e>`` an engine: tmm, exudyn, mujoco; ``<g>`` a gauge)
-----------------------------------------------------------------------
``/<e>/strain/<g>``               bending strain [µε] ("<e> bending [µε]")
``/<e>/axial_strain/<g>``         axial strain [µε] ("<e> <g> axial [µε]")
``/<e>/drive_torque``             drive torque at the crank pivot [N m], CCW positive
``/<e>/crank_speed``              crank speed [rad/s]
``/<e>/drive_power``              drive torque x crank speed [W]: what a drive delivers
``/<e>/extras/<name>``            engine-specific signals, unit from the engine
``/<e>/linkage``                  static Transform3D flipping y for the 2D view (rerun's 2D view
                                  points y down, rerun issue #1387; the data are in the
                                  mechanism's frame, y up)
``/<e>/linkage/straight``         LineStrips2D: each link as a line between its end nodes (grey)
``/<e>/linkage/deformed``         LineStrips2D: each link's nodes, their offset from that line
                                  times the exaggeration (engine colour; :mod:`.linkage`)
``/<e>/linkage/legend``           static Points2D: the engine's name in its colour (the legend)
``/<e>/events``                   TextLog: an engine that failed, with the error
``/ground/line``                  static LineStrips2D: the ground line between the fixed pivots
``/motor/<e>/current``            armature current [A]          (motor runs only)
``/motor/<e>/voltage``            armature voltage [V]
``/motor/<e>/torque``             [electromagnetic torque (motor shaft), drive torque (crank)] [N m]
``/motor/<e>/speed``              [motor shaft speed, crank speed, speed set-point] [rad/s]
``/motor/<e>/power``              [electrical power, copper loss, friction loss] [W]
``/motor/<e>/energy``             [electrical energy, copper loss, friction loss, work on the crank] [J]
``/motor/<e>/<field>``            any other MotorTrace field, unit from ``MotorTrace.UNITS``
``/records/strain/<g>/<label>``   a record's bending strain [µε]: a history, or constant lines
``/records/axial_strain/<g>/<label>``  a record's axial strain [µε]
``/scenario/...``                 text documents (resolved scenario, drawing note, scores, ...)

Every scalar entity carries a static ``SeriesLines`` naming the engine (or record), the quantity
and its unit, so legends are self-explanatory; the strain plots hold one series per engine and
record, so their legends stay small.

Owns: the recording package's public names and the entity list. Boundaries: no rerun import at
package import (no numpy either).
"""
from __future__ import annotations

_LAZY = {
    "CRANK_ANGLE": "layout", "CRANK_ANGLE_WRAPPED": "layout", "MODES": "layout", "REVOLUTION": "layout",
    "SIM_TIME": "layout",
    "Recorder": "recorder", "RecorderProcess": "process", "ViewerOptions": "sinks", "RecordingSpec": "spec",
    "spec_from_scenario": "spec", "read_back": "reader", "read_scalars": "reader", "read_blueprint": "reader",
    "read_column": "reader", "read_static": "reader", "chunk_counts": "reader", "run_blueprint": "blueprint",
}


def __getattr__(name):
    # Imported on first use: the package itself must not import rerun (the run's process of
    # `cosim run` never does), nor numpy (`cosim --help` imports the package for its options).
    if name in _LAZY:
        from importlib import import_module
        return getattr(import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
