"""What the recording needs to know about a scenario, as plain data.

:func:`spec_from_scenario` reads it once in the run's own process; the writer (possibly in a
child process, :mod:`cosim.recording.process`) and the blueprint work from the spec alone, so
neither imports the scenario loader or the kinematics.

Owns: what the recording needs from a scenario, as plain data. Boundaries: no rerun import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .layout import MODES


@dataclass(frozen=True)
class GaugeSpec:
    name: str
    link: str
    position_m: float
    face: str


@dataclass(frozen=True)
class RecordingSpec:
    """The scenario as the recording sees it (SI units, crank angle in rad)."""

    scenario: str
    mode: str
    gauges: tuple = ()                      # GaugeSpec
    links: tuple = ()                       # (name, length [m])
    engines: tuple = ()                     # engines the run starts (views name them; others still appear)
    ground: tuple | None = None             # ((x, y), (x, y)) of the fixed pivots [m], the ground line
    bounds: tuple | None = None             # ((x_lo, x_hi), (y_lo, y_hi)) of the linkage over a revolution [m]
    speed_rad_s: float = 1.0                # nominal crank speed (records outside the engines' samples)
    start_angle_rad: float = 0.0
    notes: dict = field(default_factory=dict)

    def __post_init__(self):
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")


def spec_from_scenario(sc, mode: str, engines=()) -> RecordingSpec:
    """The recording spec of a scenario: gauges, links, the ground line and the drawing bounds
    from the rigid kinematics over one revolution (computed once, here; a linkage that cannot
    turn a full revolution gets no bounds and the viewer fits the data itself)."""
    mech = sc.mechanism
    gauges = tuple(GaugeSpec(g.name, g.link, float(g.position_m), str(g.face)) for g in sc.gauges)
    links = tuple((link.name, float(link.length_m)) for link in mech.links())
    ground = bounds = None
    try:
        motion = mech.motion(np.array([float(sc.drive.start_angle_rad)]))
        if getattr(motion, "A", None) is not None and getattr(motion, "D", None) is not None:
            ground = tuple(tuple(float(v) for v in np.asarray(p)[0]) for p in (motion.A, motion.D))
    except Exception:           # a mechanism without fixed pivots A and D (or that cannot assemble)
        ground = None
    try:
        motion = mech.motion(np.linspace(0.0, 2 * math.pi, 145))
        pts = np.concatenate([np.asarray(motion.link(link.name).point(np.asarray(link.stations, float))[0])
                              .reshape(-1, 2) for link in mech.links()])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        bounds = ((float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1])))
    except Exception:           # e.g. a linkage that cannot turn a full revolution
        bounds = None
    speed = float(sc.drive.speed_rad_s) or 1.0
    return RecordingSpec(scenario=sc.name, mode=mode, gauges=gauges, links=links, engines=tuple(engines),
                         ground=ground, bounds=bounds, speed_rad_s=speed,
                         start_angle_rad=float(sc.drive.start_angle_rad))
