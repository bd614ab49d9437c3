"""Post-processing of engine runs: revolution windows by crank angle and the steady-state check.

A revolution is measured on the crank angle the engine itself reports (the window and the
revolution change are :mod:`tmm_core.revolution`'s, the one definition the time domain's own
steady check uses too). The *revolution change* of a run is that of its drive torque and every
gauge's bending strain. A run is *steady* when that change is below the tolerance (default 0.5 %).

Also the post-processing of motor-driven runs: the crank's revolutions in time, the speed
fluctuation per revolution and the energy balance of a channel.

Owns: these definitions. Must not touch: engines, files, the recording.
"""
from __future__ import annotations

import math

import numpy as np

from tmm_core import InputError
from tmm_core.revolution import last_revolution, phase, revolution_change, revolutions_completed

STEADY_TOLERANCE = 5e-3     # last two revolutions agree to 0.5 % of their peak-to-peak


def run_change(run) -> float:
    """:func:`revolution_change` of an engine run (drive torque and gauge bending strains)."""
    if len(run.t) == 0:
        return float("nan")
    signals = [run.drive_torque] + [bending for bending, _ in run.gauges.values()]
    return revolution_change(run.crank_angle, [s for s in signals if np.all(np.isfinite(s))])


def link_rotations(run) -> dict:
    """``{link: degrees}``: the largest angle [deg] between a segment of the link (two neighbouring
    nodes of the engine's deformed positions, ``run.nodes``) and the link's chord (its first node
    to its last) over the last revolution; how far the elastic motion is from small rotations.
    Links with fewer than three nodes have no segment that can turn against the chord and are
    left out. Sign-free, so the same for every engine's node layout."""
    if len(run.t) == 0 or not run.nodes:
        return {}
    mask = last_revolution(run.crank_angle)
    out = {}
    for name, positions in run.nodes.items():
        p = np.asarray(positions)
        if p.ndim != 3 or p.shape[1] < 3 or len(p) != len(mask):
            continue
        p = p[mask]
        chord = p[:, -1] - p[:, 0]
        segment = np.diff(p, axis=1)
        cross = chord[:, None, 0] * segment[..., 1] - chord[:, None, 1] * segment[..., 0]
        dot = np.einsum("kd,ksd->ks", chord, segment)
        out[name] = float(np.degrees(np.abs(np.arctan2(cross, dot)).max()))
    return out


def steadiness(run, tolerance: float) -> dict:
    """Whether an engine run ended steady: its last two revolutions agree within ``tolerance``
    (relative to each signal's peak-to-peak, :func:`run_change`); never assumed, so
    a run shorter than two revolutions is not steady. ``{"steady", "revolution_change" (None when
    undefined), "steady_tolerance"}``, and for a run that is not steady after three revolutions or
    more ``"unsteady"``: what it shows (:func:`revolution_trend`)."""
    change = run_change(run)
    out = {"steady": bool(change < tolerance), "revolution_change": None if change != change else float(change),
           "steady_tolerance": tolerance}
    if not out["steady"] and len(run.t):
        signals = [run.drive_torque] + [bending for bending, _ in run.gauges.values()]
        trend = revolution_trend(run.crank_angle, [s for s in signals if np.all(np.isfinite(s))], tolerance)
        if trend is not None:
            out["unsteady"] = trend
    return out


TREND_REVOLUTIONS = 6       # complete revolutions (counted back from the end) a trend is read from


def revolution_trend(angle, signals, tolerance: float = STEADY_TOLERANCE,
                     revolutions: int = TREND_REVOLUTIONS) -> dict | None:
    """What a run that is not steady shows over its last (up to ``revolutions``) complete
    revolutions, counted back from the last sample: the revolution-to-revolution change (as
    :func:`revolution_change`, oldest first) and each revolution's peak-to-peak, of the signal
    that changes most. ``kind``: 'grows' (the peak-to-peak grows by more than 1 % per revolution,
    in every revolution read), 'decays slowly' (the change falls by 10 % or more per revolution,
    in every revolution read: ``revolutions_to_steady`` more would reach ``tolerance`` at that
    rate) or 'bounded, not periodic' (neither: the response stays within its peak-to-peak range
    but does not repeat). An irregular response can look like either over a few revolutions: the
    verdict names how many it read (a ``cosim run`` holds the last four, cosim.runs.KEEP_REVOLUTIONS).
    None with fewer than three complete revolutions. ``text``: one sentence."""
    a = np.asarray(angle, dtype=float)
    n = min(int(math.floor(revolutions_completed(a) + 1e-9)), int(revolutions))
    if n < 3:
        return None
    ph = phase(a)
    two_pi = 2 * math.pi * (1 - 1e-12)
    best = None
    for x in signals:
        x = np.asarray(x, dtype=float)
        windows = [(ph > -(j + 1) * two_pi) & (ph <= -j * two_pi + 1e-12) for j in range(n)]   # 0 = last
        spans = [float(np.ptp(x[w])) for w in windows]
        if min(spans) <= 0.0:
            continue
        changes = [float(np.max(np.abs(x[w] - np.interp(ph[w] - 2 * math.pi, ph, x)))) / s
                   for w, s in zip(windows[:-1], spans[:-1])]
        if best is None or changes[0] > best[0][0]:
            best = (changes, spans)
    if best is None:
        return None
    changes, spans = best[0][::-1], best[1][::-1]               # oldest first
    steps = len(changes) - 1
    growth = (spans[-1] / spans[0]) ** (1.0 / (len(spans) - 1))
    decay = (changes[-1] / changes[0]) ** (1.0 / steps) if changes[0] > 0 else 1.0
    rising = sum(b > a_ for a_, b in zip(spans[:-1], spans[1:])) / (len(spans) - 1)
    falling = sum(b < a_ for a_, b in zip(changes[:-1], changes[1:])) / steps
    out = {"revolutions": len(spans), "changes": changes, "peak_to_peak": spans,
           "peak_to_peak_ratio_per_revolution": growth, "change_ratio_per_revolution": decay,
           "revolutions_to_steady": None}
    if growth > 1.01 and rising == 1.0:
        out["kind"] = "grows"
        out["text"] = (f"grows: the peak-to-peak rose {100 * (growth - 1):.1f} % per revolution over the last "
                       f"{len(spans)} revolutions, in each of them")
    elif decay < 0.9 and falling == 1.0:
        out["kind"] = "decays slowly"
        more = math.ceil(math.log(tolerance / changes[-1]) / math.log(decay)) if changes[-1] > tolerance else 0
        out["revolutions_to_steady"] = more
        out["text"] = (f"decays slowly: over the last {len(spans)} revolutions the change fell from "
                       f"{100 * changes[0]:.2g} % to {100 * changes[-1]:.2g} % ({100 * (1 - decay):.0f} % less per "
                       f"revolution); at that rate about {more} more revolutions would reach the "
                       f"{100 * tolerance:.2g} % tolerance")
    else:
        out["kind"] = "bounded, not periodic"
        out["text"] = (f"bounded, not periodic: over the last {len(spans)} revolutions the peak-to-peak stayed "
                       f"within {min(spans) / spans[-1]:.2f}-{max(spans) / spans[-1]:.2f} x the last one's while "
                       f"the change did not fall ({100 * min(changes):.2g}-{100 * max(changes):.2g} %): more "
                       "revolutions are unlikely to make it steady")
    return out


class SteadyWatch:
    """Follows engines macro step by macro step and tells when each one is steady. Keeps only
    the last three revolutions of each engine (memory bounded in run length)."""

    def __init__(self, tolerance: float = STEADY_TOLERANCE, min_revolutions: float = 2.0):
        self.tolerance = tolerance
        self.min_revolutions = min_revolutions
        self._chunks = {}           # engine -> [(angle, torque, [bending, ...]), ...]
        self._start = {}            # engine -> first crank angle [rad]
        self.change = {}            # engine -> revolution change at the last check

    def add(self, engine: str, out) -> None:
        """Record one macro step's :class:`cosim.engines.base.EngineOutput`."""
        if len(out.t) == 0:
            return
        chunks = self._chunks.setdefault(engine, [])
        self._start.setdefault(engine, float(out.crank_angle[0]))
        chunks.append((np.asarray(out.crank_angle, float), np.asarray(out.drive_torque, float),
                       [np.asarray(b, float) for b, _ in out.gauges.values()]))
        while len(chunks) > 1 and abs(chunks[-1][0][-1] - chunks[1][0][0]) > 6 * math.pi:
            chunks.pop(0)

    def revolutions(self, engine: str) -> float:
        chunks = self._chunks.get(engine)
        return abs(chunks[-1][0][-1] - self._start[engine]) / (2 * math.pi) if chunks else 0.0

    def steady(self, engine: str) -> bool:
        """True when the engine has run ``min_revolutions`` and its last two revolutions agree."""
        if self.revolutions(engine) < max(2.0, self.min_revolutions) - 1e-9:
            return False
        chunks = self._chunks[engine]
        angle = np.concatenate([c[0] for c in chunks])
        signals = [np.concatenate([c[1] for c in chunks])]
        signals += [np.concatenate([c[2][i] for c in chunks]) for i in range(len(chunks[0][2]))]
        self.change[engine] = revolution_change(angle, [x for x in signals if np.all(np.isfinite(x))])
        return self.change[engine] < self.tolerance


# -- motor-driven runs: speed and energy ---------------------------------------------------
def revolution_bounds(t, angle, start_angle: float = 0.0, t0: float = 0.0) -> np.ndarray:
    """Times [s] bounding the complete crank revolutions the samples (``t`` [s], ``angle`` [rad],
    cumulative, either direction) cover, counted from ``start_angle`` at ``t0``: consecutive
    entries bound one revolution (linear interpolation of the angle samples). A run that holds
    only its last revolutions starts after revolutions it cannot time: those are left out, and so
    is the revolution in which its samples start (its start is unknown)."""
    t, angle = np.asarray(t, dtype=float), np.asarray(angle, dtype=float)
    if len(t) < 2:
        return np.zeros(0)
    turns = np.maximum.accumulate(np.abs(angle - start_angle) / (2 * math.pi))
    first = max(1, math.ceil(turns[0] - 1e-9))        # the first revolution end inside the samples
    ends = np.interp(np.arange(first, int(np.floor(turns[-1])) + 1), turns, t)
    return np.r_[t0, ends] if first == 1 else ends


def speed_fluctuation(t, angle, speed, start_angle: float = 0.0, t0: float = 0.0) -> dict:
    """Per complete crank revolution (:func:`revolution_bounds`): ``t_start``, ``t_end`` [s],
    ``mean`` (2 pi / period), ``max``, ``min`` [rad/s] of the speed samples and
    ``fluctuation`` = (max - min) / mean."""
    t, speed = np.asarray(t, dtype=float), np.abs(np.asarray(speed, dtype=float))
    bounds = revolution_bounds(t, angle, start_angle, t0)
    out = {k: [] for k in ("t_start", "t_end", "mean", "max", "min", "fluctuation")}
    for a, b in zip(bounds[:-1], bounds[1:]):
        sel = (t >= a) & (t <= b)
        if not np.any(sel):
            continue
        mean = 2 * math.pi / (b - a)
        hi, lo = float(speed[sel].max()), float(speed[sel].min())
        for key, v in zip(out, (a, b, mean, hi, lo, (hi - lo) / mean)):
            out[key].append(v)
    return {k: np.array(v) for k, v in out.items()}


def energy_balance(channel, t_start: float | None = None, t_end: float | None = None) -> dict:
    """Energy flows [J] of a motor-driven channel between two motor sample times (default: its
    last complete revolution): electrical energy in; copper and friction losses; the change of
    magnetic energy (1/2 L i^2) and of the drive's kinetic energy (1/2 J_fw w^2 + 1/2 J_rotor
    w_m^2); and the mechanical work the linkage takes, integrated from the *engine's* load torque
    and crank speed (trapezoidal rule over the engine's samples). ``residual_J`` is the input
    minus all the rest; it checks the coupling, because the linkage work comes from the engine
    while everything else comes from the motor. (The elastic energy of a compliant shaft is not
    counted: over a steady revolution it returns to its start value.)"""
    tr, p = channel.motor, channel.motor_parameters
    if tr is None or p is None:
        raise InputError(f"{channel.engine}: an energy balance needs a motor-driven run")
    run = channel.run
    if t_start is None or t_end is None:
        ends = revolution_bounds(run.t, run.crank_angle, channel.angle0, channel.t0)
        if len(ends) < 2:
            raise InputError(f"{channel.engine}: no complete revolution to balance")
        t_start, t_end = ends[-2], ends[-1]
    # Window ends on engine samples (a subset of the motor's sample times).
    ta, tb = (float(run.t[int(np.argmin(np.abs(run.t - x)))]) for x in (t_start, t_end))
    ia, ib = (int(np.argmin(np.abs(tr.t - x))) for x in (ta, tb))
    sel = (run.t >= ta - 1e-12) & (run.t <= tb + 1e-12)
    d = lambda x: float(x[ib] - x[ia])          # noqa: E731
    W_link = float(np.trapezoid(run.drive_torque[sel] * run.crank_speed[sel], run.t[sel]))
    kinetic = 0.5 * p.flywheel_inertia_kg_m2 * tr.crank_speed_rad_s**2 + 0.5 * p.rotor_inertia_kg_m2 * \
        tr.motor_speed_rad_s**2
    out = {"t_start_s": ta, "t_end_s": tb, "electrical_in_J": d(tr.energy_in_J),
           "copper_loss_J": d(tr.copper_loss_J), "friction_loss_J": d(tr.friction_loss_J),
           "magnetic_energy_change_J": 0.5 * p.inductance_H * d(tr.current_A**2),
           "drive_kinetic_energy_change_J": d(kinetic), "linkage_work_J": W_link,
           "drive_work_J": d(tr.drive_work_J)}
    out["residual_J"] = (out["electrical_in_J"] - out["copper_loss_J"] - out["friction_loss_J"] -
                         out["magnetic_energy_change_J"] - out["drive_kinetic_energy_change_J"] - W_link)
    return out
