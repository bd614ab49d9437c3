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

import numpy as np

from tmm_core import InputError

from .records import Record, RecordError, quantity_value, record_error
from .units import factor

def trigger_times(t, signal, threshold: float | None = None, path="<signal>", column="trigger") -> np.ndarray:
    """Times of the rising edges of a once-per-revolution trigger (linear interpolation of the
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


def remove_drift(t, x, marks, order: int = 1) -> np.ndarray:
    """Subtract a slow drift: a polynomial (``order``) through the per-revolution means, taken as
    zero at the start of the recording (the bridge is balanced then), so the periodic signal's own
    mean is kept."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    centers, means = [], []
    for a, b in zip(marks[:-1], marks[1:]):
        sel = (t >= a) & (t < b)
        if np.any(sel):
            centers.append(0.5 * (a + b))
            means.append(float(np.mean(x[sel])))
    if len(centers) <= order:
        return x.copy()
    coef = np.polyfit(centers, means, order)
    return x - (np.polyval(coef, t) - np.polyval(coef, t[0]))


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


def ingest(record: Record, cutoff_Hz: float | None = None, n_bins: int = 360, drift_order: int = 1) -> dict:
    """Raw time record -> one-revolution history per gauge: {"angle_rad", "revolutions",
    gauge: {"bending_ue", "axial_ue", "bending_std_ue", ... (surface channels per face)}}.

    Steps: trigger pulses -> crank angle; calibration to microstrain; drift removal; zero-phase
    low-pass at ``cutoff_Hz`` (default: the sidecar's ``acquisition.cutoff``, none if absent);
    ensemble average; bending/axial from top and bottom surface channels of a gauge."""
    col, unit = record.index
    if unit != "s":
        raise RecordError(f"record {record.path}: ingestion needs a time index, not {unit!r}")
    acq = record.acquisition
    trig = acq.get("trigger_channel")
    if trig is None:
        raise RecordError(f"record {record.path.with_suffix('.toml')}: key 'acquisition.trigger_channel' is required "
                          "for ingestion")
    t = record.data[col]
    marks = trigger_times(t, record.data[trig], path=record.path, column=trig)
    fs = quantity_value(acq["sample_rate"], record.path.with_suffix(".toml"), "acquisition.sample_rate", "Hz") \
        if "sample_rate" in acq else 1.0 / float(np.median(np.diff(t)))
    if cutoff_Hz is None and "cutoff" in acq:
        cutoff_Hz = quantity_value(acq["cutoff"], record.path.with_suffix(".toml"), "acquisition.cutoff", "Hz")
    trigger_angle = math.radians(quantity_value(acq.get("trigger_angle", "0 deg"), record.path, "trigger_angle",
                                                 "deg"))
    direction = -1.0 if acq.get("rotation", "ccw") == "cw" else 1.0
    angle, inside = crank_angle_from_trigger(t, marks, trigger_angle, direction)
    surfaces = {}
    for c in record.channels:
        if c.quantity == "trigger":
            continue
        x = record.data[c.column]
        if c.quantity == "raw":
            x = x * c.calibration * factor(c.calibration_unit or "microstrain", "microstrain")
            q = "surface"
        else:
            x = x * factor(c.unit, "microstrain")
            q = c.quantity
        x = remove_drift(t, x, marks, drift_order)
        if cutoff_Hz:
            x = lowpass(x, fs, cutoff_Hz)
        surfaces.setdefault(c.gauge or c.column, {})[(q, c.face)] = x[inside]
    out = {"marks_s": marks, "sample_rate_Hz": fs, "cutoff_Hz": cutoff_Hz}
    for gauge, chans in surfaces.items():
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
        out[gauge] = g
    return out
