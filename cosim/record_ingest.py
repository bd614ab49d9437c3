"""Ingestion of raw lab recordings (:class:`cosim.records.Record` of raw, time-sampled channels).

Ingestion (:func:`ingest`) turns a raw, time-sampled recording with a once-per-revolution
trigger into a one-revolution history over crank angle: trigger pulses -> crank angle (constant
speed within each revolution), calibration, drift removal (a slow trend of the per-revolution
means, zero at the start of the recording), zero-phase low-pass filtering (Butterworth, filtfilt) at a declared
cut-off, ensemble averaging over revolutions with a spread band, bending/axial separation from
top and bottom gauges, and strain-to-deflection calibration as Wang used (a simply supported
span under a central load: deflection / surface strain = L^2 / (6 h)).

Owns: raw recordings turned into one-revolution histories. Boundaries: the record format and its
loading are :mod:`cosim.records`.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from tmm_core import InputError

from .records import Record, RecordError, quantity_value, record_error
from .units import factor

# Even sampling at the declared rate. Every step within 0.5-1.5x the median step: one dropped
# sample doubles a step, a duplicated or spliced row shortens one, while timestamps rounded to a
# tenth of the step still pass. Then the mean step (span / intervals: immune to that rounding,
# equal to the median when even) within 1 % of 1 / sample_rate: a DAQ's clock is good to ppm,
# while a wrong rate (2751 typed for 2500 Hz) is off by several %.
RATE_TOLERANCE = 0.01
STEP_RANGE = (0.5, 1.5)
MS_PER_S = 1000.0                     # a median step 1000x 1 / rate (within RATE_TOLERANCE): milliseconds
# A trigger is a two-level signal with sharp edges. Levels: the medians of the samples below and
# above the midpoint of its extremes. A sample is at a level within 20 % of the level-to-level span
# (a sigma-delta DAQ's anti-alias filter overshoots a step by ~9 % and rings); at least 90 % of the
# samples are at a level (a sine spends ~63 % there) and every rising edge goes from the low band
# to the high band within 4 sample steps (a gauge signal takes tens to hundreds).
TRIGGER_BAND = 0.20
TRIGGER_AT_LEVELS = 0.90
TRIGGER_EDGE_STEPS = 4
# Pulse period: the median within 5 % of 60 / the declared speed (a motor's set point and slip),
# and every period within 20 % of the median (a missed pulse doubles one, an extra one splits one).
SPEED_TOLERANCE = 0.05
PERIOD_SPREAD = 0.20


def check_time(t, rate_Hz: float | None, path, column: str) -> float:
    """Refuse a time column [s] that is not strictly increasing and evenly sampled at ``rate_Hz``
    (see RATE_TOLERANCE, STEP_RANGE); ``None``: no declared rate, only evenness is checked.
    Returns the mean step [s]."""
    t = np.asarray(t, float)
    if t.size < 3:
        raise record_error(path, f"{t.size} samples: too few for a time-sampled recording", column=column)
    dt = np.diff(t)
    back = np.nonzero(dt <= 0)[0]
    if back.size:
        i = int(back[0])
        raise record_error(path, f"time is not strictly increasing: {t[i]:.9g} s then {t[i + 1]:.9g} s (data rows "
                                 f"{i + 1} and {i + 2})", column=column)
    step = float(np.median(dt))
    worst = int(np.argmax(np.abs(dt / step - 1)))
    if not STEP_RANGE[0] <= dt[worst] / step <= STEP_RANGE[1]:
        what = "a gap" if dt[worst] > step else "an uneven step"
        raise record_error(path, f"{what}: a step of {dt[worst]:.6g} s after t = {t[worst]:.9g} s (data row "
                                 f"{worst + 1}), {dt[worst] / step:.3g}x the median {step:.6g} s (evenly sampled: "
                                 f"every step within {STEP_RANGE[0]:g}-{STEP_RANGE[1]:g}x the median)", column=column)
    step = float((t[-1] - t[0]) / (t.size - 1))
    side = Path(path).with_suffix(".toml").name
    if rate_Hz is not None:
        ratio = step * rate_Hz
        if abs(ratio / MS_PER_S - 1) <= RATE_TOLERANCE:
            raise record_error(path, f"the mean time step is {step:.6g}, {ratio:.4g}x the {1 / rate_Hz:.6g} s of "
                                     f"acquisition.sample_rate = {rate_Hz:g} Hz in {side}: the time looks like "
                                     "milliseconds; write it in seconds", column=column)
        if abs(ratio - 1) > RATE_TOLERANCE:
            raise record_error(path, f"the mean time step {step:.6g} s ({1 / step:.6g} Hz) is "
                                     f"{100 * (ratio - 1):+.1f} % off acquisition.sample_rate = {rate_Hz:g} Hz in "
                                     f"{side} (at most {100 * RATE_TOLERANCE:g} %)", column=column)
    return step


def trigger_levels(signal) -> tuple:
    """Low and high level of a two-level signal (its units): the medians of the samples below and
    above the midpoint of its extremes."""
    s = np.asarray(signal, float)
    mid = 0.5 * (np.min(s) + np.max(s))
    return float(np.median(s[s < mid])), float(np.median(s[s >= mid]))


def check_trigger_shape(signal, path, column: str) -> None:
    """Refuse a trigger channel that is not two-level with sharp edges (TRIGGER_BAND,
    TRIGGER_AT_LEVELS, TRIGGER_EDGE_STEPS): a gauge signal named as the trigger."""
    s = np.asarray(signal, float)
    if not np.max(s) > np.min(s):
        raise record_error(path, "the trigger channel has no pulses (constant signal)", column=column)
    lo, hi = trigger_levels(s)
    band = TRIGGER_BAND * (hi - lo)
    low, high = np.abs(s - lo) <= band, np.abs(s - hi) <= band
    share = float(np.mean(low | high))
    if share < TRIGGER_AT_LEVELS:
        raise record_error(path, f"not a trigger: {100 * share:.0f} % of its samples lie at its two levels "
                                 f"({lo:.4g}, {hi:.4g} within {100 * TRIGGER_BAND:g} % of their span), a trigger has "
                                 f"at least {100 * TRIGGER_AT_LEVELS:g} % (is it a gauge channel?)", column=column)
    idx = np.arange(s.size)
    last_low = np.maximum.accumulate(np.where(low, idx, -1))
    next_high = np.minimum.accumulate(np.where(high, idx, s.size)[::-1])[::-1]
    k = np.nonzero((s[:-1] < 0.5 * (lo + hi)) & (s[1:] >= 0.5 * (lo + hi)))[0]
    k = k[(last_low[k] >= 0) & (next_high[k + 1] < s.size)]       # edges cut by the recording's ends: unknown
    steps = next_high[k + 1] - last_low[k]
    if steps.size and steps.max() > TRIGGER_EDGE_STEPS:
        i = int(k[np.argmax(steps)])
        raise record_error(path, f"not a trigger: a rising edge at data row {i + 1} takes {int(steps.max())} sample "
                                 f"steps from its low to its high level, a trigger's at most {TRIGGER_EDGE_STEPS} "
                                 "(is it a gauge channel?)", column=column)


def check_trigger_period(marks, speed_rpm: float | None, path, column: str) -> None:
    """Refuse pulse times [s] whose period disagrees with the declared crank speed [rpm] (if any)
    or varies from pulse to pulse (SPEED_TOLERANCE, PERIOD_SPREAD)."""
    periods = np.diff(np.asarray(marks, float))
    median = float(np.median(periods))
    if speed_rpm:
        expected, side = 60.0 / abs(speed_rpm), Path(path).with_suffix(".toml").name
        if abs(median / expected - 1) > SPEED_TOLERANCE:
            raise record_error(path, f"pulses every {median:.6g} s ({60 / median:.4g} rpm) but record.speed = "
                                     f"{abs(speed_rpm):g} rpm in {side} gives one every {expected:.6g} s (a "
                                     f"once-per-revolution trigger agrees within {100 * SPEED_TOLERANCE:g} %)",
                               column=column)
    worst = int(np.argmax(np.abs(periods / median - 1)))
    if abs(periods[worst] / median - 1) > PERIOD_SPREAD:
        raise record_error(path, f"a pulse period of {periods[worst]:.6g} s after the pulse at t = "
                                 f"{marks[worst]:.6g} s is {periods[worst] / median:.3g}x the median {median:.6g} s: "
                                 f"a missed or extra pulse (every period within {100 * PERIOD_SPREAD:g} % of the "
                                 "median)", column=column)


def trigger_times(t, signal, threshold: float | None = None, path="<signal>", column="trigger") -> np.ndarray:
    """Times [s] of the rising edges of a once-per-revolution trigger (linear interpolation of the
    threshold crossing; threshold default: midway between the signal's extremes)."""
    t, s = np.asarray(t, float), np.asarray(signal, float)
    lo, hi = np.min(s), np.max(s)
    if not hi > lo:
        raise record_error(path, "the trigger channel has no pulses (constant signal)", column=column)
    thr = 0.5 * (lo + hi) if threshold is None else threshold
    k = np.nonzero((s[:-1] < thr) & (s[1:] >= thr))[0]
    if len(k) < 2:
        raise record_error(path, f"the trigger channel has {len(k)} rising edge(s); at least two pulses (one complete "
                          "revolution) are needed", column=column)
    return t[k] + (thr - s[k]) / (s[k + 1] - s[k]) * (t[k + 1] - t[k])


def crank_angle_from_trigger(t, marks, trigger_angle: float = 0.0, direction: float = 1.0) -> tuple:
    """Crank angle [rad] at samples ``t`` between the first and last trigger mark (constant
    speed within each revolution), and the mask of those samples."""
    t = np.asarray(t, float)
    inside = (t >= marks[0]) & (t <= marks[-1])
    rev = np.interp(t[inside], marks, np.arange(len(marks), dtype=float))
    return trigger_angle + direction * 2 * math.pi * rev, inside


def drift_trend(t, x, marks, order: int = 1) -> np.ndarray:
    """The slow drift of ``x`` at times ``t`` [s] (``x``'s units): a polynomial (``order``) through the
    per-revolution means between trigger ``marks`` [s], zero at the start of the recording (the
    bridge is balanced then), so the periodic signal's own mean is kept. Zero when there are no
    more revolutions than ``order``."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    centers, means = [], []
    for a, b in zip(marks[:-1], marks[1:]):
        sel = (t >= a) & (t < b)
        if np.any(sel):
            centers.append(0.5 * (a + b))
            means.append(float(np.mean(x[sel])))
    if len(centers) <= order:
        return np.zeros_like(x)
    coef = np.polyfit(centers, means, order)
    return np.polyval(coef, t) - np.polyval(coef, t[0])


def remove_drift(t, x, marks, order: int = 1) -> np.ndarray:
    """``x`` less its :func:`drift_trend`."""
    return np.asarray(x, float) - drift_trend(t, x, marks, order)


def lowpass(x, sample_rate_Hz: float, cutoff_Hz: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (forward-backward, so no phase lag)."""
    from scipy.signal import butter, sosfiltfilt
    if not 0 < cutoff_Hz < 0.5 * sample_rate_Hz:
        raise InputError(f"low-pass cut-off {cutoff_Hz!r} Hz must lie between 0 and half the sample rate "
                         f"({0.5 * sample_rate_Hz:g} Hz)")
    sos = butter(order, cutoff_Hz, btype="low", fs=sample_rate_Hz, output="sos")
    return sosfiltfilt(sos, np.asarray(x, float))


def ensemble_average(angle, x, n_bins: int = 360) -> dict:
    """Average over revolutions on a uniform one-revolution grid: ``angle_rad`` (bin centres from
    the trigger angle), ``mean``, ``std``, ``min``, ``max``, ``revolutions``."""
    angle, x = np.asarray(angle, float), np.asarray(x, float)
    start = angle[0]
    rev = np.floor((angle - start) / (2 * math.pi)).astype(int)
    grid = (np.arange(n_bins) + 0.5) / n_bins * 2 * math.pi
    curves = []
    for r in range(rev.max() + 1):
        sel = rev == r
        phase = angle[sel] - start - 2 * math.pi * r
        if phase.size < 4 or phase[-1] - phase[0] < 2 * math.pi * 0.98:
            continue                                       # incomplete revolution at either end
        curves.append(np.interp(grid, phase, x[sel]))
    if not curves:
        raise InputError("no complete revolution between trigger pulses")
    c = np.array(curves)
    return {"angle_rad": start + grid, "mean": c.mean(0), "std": c.std(0), "min": c.min(0), "max": c.max(0),
            "revolutions": len(curves)}


def bending_axial(top, bottom) -> tuple:
    """Bending strain of the top face and axial strain from top and bottom surface strains."""
    top, bottom = np.asarray(top, float), np.asarray(bottom, float)
    return 0.5 * (top - bottom), 0.5 * (top + bottom)


def deflection_per_strain(span_m: float, depth_m: float) -> float:
    """Static calibration of a midspan gauge as deflection: a simply supported span under a
    central load has midspan deflection P L^3 / (48 EI) and surface strain (P L / 4)(h / 2) / EI,
    so deflection / strain = L^2 / (6 h) [m per unit strain]."""
    if not (span_m > 0 and depth_m > 0):
        raise InputError(f"span and depth must be positive, got {span_m!r}, {depth_m!r}")
    return span_m**2 / (6 * depth_m)


def _sample_rate(record: Record, t, notes: list) -> float:
    """The declared sample rate [Hz], after checking the time column against it (a rate taken from
    the median step when none is declared, and said so in ``notes``)."""
    side, col = record.path.with_suffix(".toml"), record.index[0]
    acq = record.acquisition
    declared = None
    if "sample_rate" in acq:
        declared = quantity_value(acq["sample_rate"], side, "acquisition.sample_rate", "Hz")
    if declared is not None and not declared > 0:
        raise record_error(side, f"key 'acquisition.sample_rate' = {acq['sample_rate']!r}: must be positive")
    step = check_time(t, declared, record.path, col)
    if declared is None:
        notes.append(f"acquisition.sample_rate not declared in {side.name}: taken as {1 / step:.6g} Hz from the "
                     f"mean step of column '{col}'")
        return 1.0 / step
    return declared


def _marks(record: Record, t) -> np.ndarray:
    """Trigger pulse times [s], after checking that the trigger channel is one and agrees with the
    declared speed."""
    trig = record.acquisition.get("trigger_channel")
    if trig is None:
        raise RecordError(f"record {record.path.with_suffix('.toml')}: key 'acquisition.trigger_channel' is required "
                          "for ingestion")
    check_trigger_shape(record.data[trig], record.path, trig)
    marks = trigger_times(t, record.data[trig], path=record.path, column=trig)
    check_trigger_period(marks, record.speed_rpm, record.path, trig)
    return marks


def _microstrain(c, x) -> tuple:
    """A channel's samples in microstrain and the quantity they stand for (raw -> surface)."""
    if c.quantity == "raw":
        return x * c.calibration * factor(c.calibration_unit or "microstrain", "microstrain"), "surface"
    return x * factor(c.unit, "microstrain"), c.quantity


def ingest(record: Record, cutoff_Hz: float | None = None, n_bins: int = 360, drift_order: int = 1) -> dict:
    """Raw time record -> one-revolution history per gauge: {"angle_rad", "revolutions", "notes",
    gauge: {"bending_ue", "axial_ue", "bending_std_ue", ... (surface channels per face)}}.

    Steps: checks (time evenly sampled at the declared rate, the trigger a two-level signal whose
    pulses match the declared speed: :class:`RecordError` otherwise); trigger pulses -> crank
    angle; calibration to microstrain; drift removal; zero-phase low-pass at ``cutoff_Hz`` [Hz]
    (default: the sidecar's ``acquisition.cutoff``, none if absent); ensemble average;
    bending/axial from top and bottom surface channels of a gauge. ``notes``: what was corrected
    or left out, one sentence each."""
    col, unit = record.index
    if unit != "s":
        raise RecordError(f"record {record.path}: ingestion needs a time index, not {unit!r}")
    acq, side, notes = record.acquisition, record.path.with_suffix(".toml"), []
    t = record.data[col]
    fs = _sample_rate(record, t, notes)
    marks = _marks(record, t)
    if cutoff_Hz is None and "cutoff" in acq:
        cutoff_Hz = quantity_value(acq["cutoff"], side, "acquisition.cutoff", "Hz")
    trigger_angle = math.radians(quantity_value(acq.get("trigger_angle", "0 deg"), side, "acquisition.trigger_angle",
                                                 "deg"))
    direction = -1.0 if acq.get("rotation", "ccw") == "cw" else 1.0
    angle, inside = crank_angle_from_trigger(t, marks, trigger_angle, direction)
    notes.append(f"{int(np.sum(~inside))} of {t.size} samples before the first or after the last trigger pulse "
                 f"(t < {marks[0]:.6g} s or > {marks[-1]:.6g} s) left out: no crank angle there")
    surfaces = {}
    for c in record.channels:
        if c.quantity == "trigger":
            continue
        x, q = _microstrain(c, record.data[c.column])
        trend = drift_trend(t, x, marks, drift_order)
        notes.append(f"drift removed from channel '{c.column}': {trend[-1]:+.4g} ue over {t[-1] - t[0]:.4g} s "
                     f"(order-{drift_order} trend through the per-revolution means, zero at the start)")
        x = x - trend
        if cutoff_Hz:
            x = lowpass(x, fs, cutoff_Hz)
        surfaces.setdefault(c.gauge or c.column, {})[(q, c.face)] = x[inside]
    if cutoff_Hz:
        notes.append(f"every channel low-pass filtered at {cutoff_Hz:g} Hz (zero-phase Butterworth, order 4)")
    out = {"marks_s": marks, "sample_rate_Hz": fs, "cutoff_Hz": cutoff_Hz, "notes": notes}
    for gauge, chans in surfaces.items():
        out[gauge] = _averages(chans, angle, n_bins, out)
    return out


def _averages(chans: dict, angle, n_bins: int, out: dict) -> dict:
    """Ensemble averages [ue] of one gauge's channels ({(quantity, face): samples}); sets
    ``out``'s ``angle_rad`` and ``revolutions``."""
    g = {}
    if ("surface", "top") in chans and ("surface", "bottom") in chans:
        b, a = bending_axial(chans[("surface", "top")], chans[("surface", "bottom")])
        series = {"bending": b, "axial": a}
    else:
        series = {f"{q}_{face}" if q == "surface" else q: v for (q, face), v in chans.items()}
    for name, v in series.items():
        avg = ensemble_average(angle, v, n_bins)
        g[f"{name}_ue"], g[f"{name}_std_ue"] = avg["mean"], avg["std"]
        g[f"{name}_min_ue"], g[f"{name}_max_ue"] = avg["min"], avg["max"]
        out["angle_rad"], out["revolutions"] = avg["angle_rad"], avg["revolutions"]
    return g
