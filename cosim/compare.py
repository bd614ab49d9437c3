"""Scores of an engine's gauge history against a record.

For a history record (one revolution over crank angle), both curves are put on the same uniform
angle grid and compared:

* ``+peak`` / ``-peak`` errors: model / record - 1 of the maximum and of the minimum (so for a
  - peak, a positive error means the model's magnitude is larger);
* ``phase_lag_deg``: the shift that maximises the circular cross-correlation (FFT, refined to
  a fraction of a grid step by a parabola through the peak); positive = the model lags;
* ``scale``: the least-squares amplitude ratio model / record after the shift (of the
  fluctuating parts); ``offset_ue``: mean difference;
* ``rms_error_ue`` and ``correlation`` after the shift (and ``rms_error_unaligned_ue``);
* ``inside_envelope``: the fraction of the revolution where the model lies within the record's
  tolerance envelope (its spread band if it has one, else +/- ``tolerance`` x its peak-to-peak).

For a peaks record only the peak errors exist. Face and sign conventions are compared, never
changed: a record whose face differs from the scenario gauge's, or whose sign convention is not
stated, is reported in ``warnings``; a strongly negative correlation that becomes strongly
positive when negated is reported as a possible sign mismatch (the scores stay as computed).

Owns: the scores of a gauge history against a record (peak and RMS errors). Boundaries: pure, no
files, no engines.
"""
from __future__ import annotations

import math

import numpy as np

N_GRID = 720


def _on_grid(angle, values, n=N_GRID):
    """One revolution of samples (angle [rad], any start) -> values on the grid 0..2pi."""
    a = np.mod(np.asarray(angle, float), 2 * math.pi)
    order = np.argsort(a)
    a, v = a[order], np.asarray(values, float)[order]
    grid = np.arange(n) * 2 * math.pi / n
    return np.interp(grid, a, v, period=2 * math.pi)


def circular_lag(model, record) -> float:
    """Lag (in grid steps, fractional) of ``model`` behind ``record`` by circular cross-correlation."""
    m, r = np.asarray(model, float) - np.mean(model), np.asarray(record, float) - np.mean(record)
    xc = np.fft.irfft(np.fft.rfft(m) * np.conj(np.fft.rfft(r)), n=len(m))
    k = int(np.argmax(xc))
    y0, y1, y2 = xc[k - 1], xc[k], xc[(k + 1) % len(xc)]
    denom = y0 - 2 * y1 + y2
    frac = 0.5 * (y0 - y2) / denom if denom != 0 else 0.0
    lag = k + frac
    return lag - len(m) if lag > len(m) / 2 else lag


def _shift(values, steps):
    """Circular shift by a fractional number of grid steps (Fourier), so a fitted lag is exact."""
    n = len(values)
    k = np.fft.rfftfreq(n, d=1.0 / n)
    return np.fft.irfft(np.fft.rfft(values) * np.exp(2j * math.pi * k * steps / n), n=n)


def score_history(model_angle, model_values, record_angle, record_values, *, band=None, tolerance: float = 0.1,
                  n: int = N_GRID) -> dict:
    """Scores of one revolution of a model history against a record (both over crank angle)."""
    m = _on_grid(model_angle, model_values, n)
    r = _on_grid(record_angle, record_values, n)
    lag = circular_lag(m, r)
    aligned = _shift(m, lag)                      # the model moved back by its lag
    mf, rf = aligned - aligned.mean(), r - r.mean()
    scale = float(mf @ rf / (rf @ rf)) if rf @ rf > 0 else float("nan")
    corr = float(mf @ rf / math.sqrt((mf @ mf) * (rf @ rf))) if (mf @ mf) * (rf @ rf) > 0 else float("nan")
    corr_raw = float(np.corrcoef(m, r)[0, 1]) if np.std(m) > 0 and np.std(r) > 0 else float("nan")
    if band is not None:
        lo, hi = (_on_grid(record_angle, b, n) for b in band)
    else:
        half = tolerance * (r.max() - r.min())
        lo, hi = r - half, r + half
    out = {"model_max_ue": float(m.max()), "model_min_ue": float(m.min()), "record_max_ue": float(r.max()),
           "record_min_ue": float(r.min()),
           "plus_peak_error": _rel(m.max(), r.max()), "minus_peak_error": _rel(m.min(), r.min()),
           "phase_lag_deg": float(lag * 360.0 / n), "scale": scale, "offset_ue": float(aligned.mean() - r.mean()),
           "rms_error_ue": float(np.sqrt(np.mean((aligned - r) ** 2))),
           "rms_error_unaligned_ue": float(np.sqrt(np.mean((m - r) ** 2))),
           "correlation": corr, "correlation_unaligned": corr_raw,
           "inside_envelope": float(np.mean((m >= lo) & (m <= hi))),
           "envelope": "record spread band" if band is not None else f"+/-{tolerance:g} x record peak-to-peak"}
    return out


def score_peaks(model_max, model_min, record_max=None, record_min=None) -> dict:
    out = {"model_max_ue": model_max, "model_min_ue": model_min, "record_max_ue": record_max,
           "record_min_ue": record_min}
    if record_max is not None:
        out["plus_peak_error"] = _rel(model_max, record_max)
    if record_min is not None:
        out["minus_peak_error"] = _rel(model_min, record_min)
    return out


def _rel(model, record):
    """model / record - 1: for a + peak the excess over the record, for a - peak the excess of the
    model's magnitude (a model peak of -266 against a recorded -191 is +39 %)."""
    return float(model / record - 1.0) if record else float("nan")


def convention_warnings(record, gauge) -> list:
    """Face and sign-convention differences between a record and a scenario gauge (reported,
    never corrected)."""
    warnings = []
    faces = {c.face for c in getattr(record, "channels", ()) if (c.gauge or c.column) == gauge.name}
    faces |= {r.get("face") or record.meta.get("face", "unknown") for r in getattr(record, "rows", ())
              if r.get("gauge") == gauge.name}
    for face in sorted(f for f in faces if f):
        if face == "unknown":
            warnings.append(f"record {record.name}: the gauge face is not stated; its + and - peaks are compared with "
                            f"the scenario's {gauge.face} face as printed (a flipped face would swap them)")
        elif face != gauge.face:
            warnings.append(f"record {record.name}: gauge face {face} differs from the scenario's {gauge.face} face; "
                            "bending has the opposite sign there (not flipped)")
    if str(record.sign_convention).lower() not in ("tension positive", "tension positive (bench convention)"):
        warnings.append(f"record {record.name}: sign convention '{record.sign_convention}' (the bench uses tension "
                        "positive); not converted")
    return warnings


def sign_check(scores: dict) -> str | None:
    c = scores.get("correlation_unaligned")
    if c is not None and c == c and c < -0.5:
        return (f"correlation {c:.2f} before alignment: the record may use the opposite sign or face (not flipped; "
                "check the record's sidecar)")
    return None
