"""Resonance maps of a linkage: natural frequencies of the instantaneous structure against crank
angle, and a Campbell-type diagram of the crank-speed harmonics against the frequency bands.

A linkage's stiffness changes with the crank angle, so each mode has a *band* of frequencies over
a revolution. The crank excites the harmonics k f_rev (f_rev = rpm / 60) of its speed; a
harmonic that enters a band is a resonance candidate. :func:`campbell` lists, per mode and
harmonic, the speed range over which that happens; :func:`plot_sweep` draws the peaks of a
sweep, the Campbell diagram and the frequencies over the crank angle into PNG and SVG files.

Owns: natural-frequency maps against crank angle and speed, the Campbell diagram. Boundaries: no
sweep running (cosim.sweeps).
"""
from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

# Called through its module, so a test can put a stand-in there (tests/test_run_loop.py).
from tmm_core import frequencies

from .figures import gauge_label, new_figure, peak_markers, save

log = logging.getLogger(__name__)

#: Wall-time bound [s] of a natural-frequency map: a post-run analysis must not run for minutes
#: (a few seconds per crank angle on a four-bar, measured 2.4 s on the FE rig; more on a finely
#: meshed rig or a high frequency range).
MAP_SECONDS = 120.0


def frequency_map(scenario, n_angles: int = 36, n_modes: int = 4, f_max_Hz: float = 1000.0,
                  progress: bool = False, max_seconds: float | None = MAP_SECONDS, rtol: float = 1e-10) -> dict:
    """Natural frequencies [Hz] at ``n_angles`` crank angles over a revolution: {"angle_rad",
    "f_Hz" (angles, modes; NaN where fewer modes lie below ``f_max_Hz``), "capped" (fewer angles
    than asked)}; ``rtol``: the frequency search's relative tolerance. One angle at a time (a few
    seconds each on a four-bar), so that ``progress`` can show a bar. Bounded in time: when the
    first angle shows that ``n_angles`` would take longer than ``max_seconds`` [s] (None: no
    bound), the map takes as many angles as fit, still spread over the whole revolution, and
    says so (its bands are then coarser)."""
    from tqdm import tqdm

    start = scenario.drive.start_angle_rad
    angles = start + np.linspace(0, 2 * math.pi, n_angles, endpoint=False)
    with tqdm(total=n_angles, desc="natural frequencies", unit="angle", disable=None if progress else True) as bar:
        tic = time.perf_counter()
        first = frequencies.fourbar_frequencies(scenario.mechanism, [start], n_modes, f_max_Hz, rtol)[0]
        bar.update(1)
        each = time.perf_counter() - tic
        fits = _angles_within(n_angles, each, max_seconds)
        if fits < n_angles:
            log.warning("natural-frequency map: %d of %d crank angles (%.1f s each; bounded to %.0f s), "
                        "its frequency bands are coarser", fits, n_angles, each, max_seconds)
            angles, bar.total = start + np.linspace(0, 2 * math.pi, fits, endpoint=False), fits
            bar.refresh()
        rows = [first]
        for a in angles[1:]:
            rows.append(frequencies.fourbar_frequencies(scenario.mechanism, [a], n_modes, f_max_Hz, rtol)[0])
            bar.update(1)
    return {"angle_rad": angles, "f_Hz": np.array(rows).reshape(len(angles), n_modes), "capped": fits < n_angles}


def _angles_within(n_angles: int, seconds_each: float, max_seconds: float | None) -> int:
    """How many crank angles of ``seconds_each`` [s] fit in ``max_seconds`` [s] (at least the
    one already computed, at most ``n_angles``)."""
    if max_seconds is None or seconds_each * n_angles <= max_seconds:
        return n_angles
    return max(1, min(n_angles, int(max_seconds / max(seconds_each, 1e-9))))


def campbell(fmap: dict, rpm_min: float, rpm_max: float, max_harmonic: int = 20) -> list:
    """Resonance candidates: for every mode band [f_min, f_max] and harmonic k, the crank-speed
    range [rpm] over which k rpm / 60 lies in the band (clipped to the swept range)."""
    out = []
    f = fmap["f_Hz"]
    for mode in range(f.shape[1]):
        col = f[:, mode][np.isfinite(f[:, mode])]
        if not len(col):
            continue
        lo, hi = float(col.min()), float(col.max())
        for k in range(1, max_harmonic + 1):
            a, b = 60 * lo / k, 60 * hi / k
            if b >= rpm_min and a <= rpm_max:
                out.append({"mode": mode + 1, "harmonic": k, "band_Hz": [lo, hi],
                            "rpm": [max(a, rpm_min), min(b, rpm_max)]})
    return out


def plot_sweep(folder, name: str, points: list, fmap: dict | None, marks_rpm=(), max_harmonic: int = 20,
               record_peaks=(), not_steady_rpm=(), unstable_rpm=()) -> list:
    """Write ``sweep_peaks`` and ``campbell`` figures (PNG and SVG) to ``folder``; returns the paths.
    ``record_peaks`` (:func:`cosim.figures.peaks_by_speed`) are drawn as open markers at their speeds;
    ``not_steady_rpm``: marched points whose last revolutions still differ (shaded);
    ``unstable_rpm``: solved orbits a march would leave (shaded; ``summary["unstable_orbits"]``)."""

    folder = Path(folder)
    paths = []
    done = [p for p in points if p.get("rpm") is not None]
    fig = new_figure(figsize=(9, 4.8))
    ax = fig.subplots()
    series = {}
    for p in sorted(done, key=lambda q: q["rpm"]):
        for engine, e in p["engines"].items():
            for g, s in (e.get("gauges") or {}).items():
                series.setdefault((engine, g), []).append((p["rpm"], s["bending_max_ue"], s["bending_min_ue"]))
    gauge_colors = {}
    for (engine, g), v in sorted(series.items()):
        v = np.array(v)
        line, = ax.plot(v[:, 0], v[:, 1], label=f"{engine}, {gauge_label(g)} +peak")
        ax.plot(v[:, 0], v[:, 2], "--", color=line.get_color(), label=f"{engine}, {gauge_label(g)} -peak")
        gauge_colors.setdefault(g, line.get_color())
    # Only the gauges the sweep computed: a record of another gauge has no curve to compare with.
    peak_markers(ax, [p for p in record_peaks if p["gauge"] in gauge_colors], gauge_colors)
    failed = [p["rpm"] for p in done if any(e.get("status") != "completed" for e in p["engines"].values())]
    for r in failed:
        ax.axvline(r, color="0.85", lw=3, zorder=0)
    for r in not_steady_rpm:
        ax.axvline(r, color="mistyrose", lw=3, zorder=0)
    # Solved orbits a march would leave (|Floquet multiplier| > 1): their peaks are not what a
    # run at that speed settles to.
    for r in unstable_rpm:
        ax.axvline(r, color="thistle", lw=3, zorder=0)
    for r in marks_rpm:
        ax.axvline(r, color="k", lw=0.8, ls=":")
    ax.set_xlabel("crank speed [rpm]")
    ax.set_ylabel("peak bending strain [µε]")
    notes = (["grey: no solution, e.g. buckling"] if failed else []) + \
        (["pink: not steady, peaks of a transient"] if len(not_steady_rpm) else []) + \
        (["violet: unstable orbit, |mu| > 1"] if len(unstable_rpm) else [])
    ax.set_title(f"{name}: steady-state peak strain vs speed" + (f" ({'; '.join(notes)})" if notes else ""))
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    ax.grid(alpha=0.3)
    paths += save(fig, folder, "sweep_peaks")
    if fmap is None:
        return paths
    rpms = np.array([p["rpm"] for p in done]) if done else np.array([1.0])
    r_lo, r_hi = float(rpms.min()), float(rpms.max())
    fig = new_figure(figsize=(12, 4.8))
    a1, a2 = fig.subplots(1, 2)
    f = fmap["f_Hz"]
    deg = np.degrees(fmap["angle_rad"])
    for m in range(f.shape[1]):
        a1.plot(deg, f[:, m], label=f"mode {m + 1}")
        col = f[:, m][np.isfinite(f[:, m])]
        if len(col):
            a2.axhspan(col.min(), col.max(), alpha=0.25, color=f"C{m}", label=f"mode {m + 1} band")
    a1.set_xlabel("crank angle [deg]")
    a1.set_ylabel("natural frequency [Hz]")
    a1.set_title("instantaneous structure (crank clamped)")
    a1.legend(fontsize=7)
    a1.grid(alpha=0.3)
    rr = np.linspace(r_lo, r_hi, 200)
    fmax = np.nanmax(f) * 1.1 if np.isfinite(np.nanmax(f)) else 100.0
    for k in range(1, max_harmonic + 1):
        y = k * rr / 60
        if y[0] > fmax:
            break
        a2.plot(rr, y, color="0.4", lw=0.7)
    harmonic_labels(a2, r_lo, r_hi, fmax, max_harmonic)
    for r in marks_rpm:
        a2.axvline(r, color="k", lw=0.8, ls=":")
    a2.set_xlim(r_lo, r_hi)
    a2.set_ylim(0, fmax)
    a2.set_xlabel("crank speed [rpm]")
    a2.set_ylabel("frequency [Hz]")
    a2.set_title("Campbell: crank-speed harmonics vs mode bands", pad=14)
    a2.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.06, 1.0), borderaxespad=0)
    paths += save(fig, folder, "campbell")
    return paths


def harmonic_labels(ax, r_lo: float, r_hi: float, fmax: float, max_harmonic: int, min_gap: float = 0.045) -> None:
    """Label each harmonic line "kx" where it leaves the plot (right edge, or top edge for the
    steep ones), skipping a label that would land within ``min_gap`` (fraction of the axis) of
    one already placed: with 20 harmonics the right-edge labels would otherwise overprint."""
    placed = {"right": [], "top": []}
    span_r = max(r_hi - r_lo, 1e-9)
    for k in range(1, max_harmonic + 1):
        y_end = k * r_hi / 60
        if k * r_lo / 60 > fmax:
            break
        if y_end <= fmax:            # leaves through the right edge: position along y
            edge, pos, xy = "right", y_end / fmax, (r_hi, y_end)
            kw = dict(ha="left", va="center")
        else:                        # leaves through the top: position along x
            x = 60 * fmax / k
            edge, pos, xy = "top", (x - r_lo) / span_r, (x, fmax)
            kw = dict(ha="center", va="bottom")
        if any(abs(pos - q) < min_gap for q in placed[edge]):
            continue
        placed[edge].append(pos)
        ax.annotate(f"{k}x", xy, xytext=(2, 0) if edge == "right" else (0, 1), textcoords="offset points",
                    fontsize=6, color="0.3", clip_on=False, **kw)


def record_map(rec, fmap: dict, rpm_range, max_harmonic: int = 20) -> None:
    """Frequencies over the crank angle and the harmonic lines into a rerun recording."""
    import rerun as rr
    f = fmap["f_Hz"]
    mdeg = np.rint(np.degrees(fmap["angle_rad"]) * 1000).astype(np.int64)
    rec.log("/tmm/frequencies", rr.SeriesLines(names=[f"mode {m + 1} [Hz]" for m in range(f.shape[1])]), static=True)
    rec.send_columns("/tmm/frequencies", indexes=[rr.TimeColumn("crank_angle_mdeg", sequence=mdeg)],
                     columns=rr.Scalars.columns(scalars=np.nan_to_num(f, nan=0.0)))
    rpm = np.arange(int(rpm_range[0]), int(rpm_range[1]) + 1)
    lines = np.stack([k * rpm / 60 for k in range(1, max_harmonic + 1)], -1)
    rec.log("/tmm/campbell/harmonics", rr.SeriesLines(names=[f"{k} x crank [Hz]" for k in range(1, max_harmonic + 1)]),
            static=True)
    rec.send_columns("/tmm/campbell/harmonics", indexes=[rr.TimeColumn("crank_speed_rpm", sequence=rpm)],
                     columns=rr.Scalars.columns(scalars=lines))
    bands = []
    for m in range(f.shape[1]):
        col = f[:, m][np.isfinite(f[:, m])]
        bands += [col.min(), col.max()] if len(col) else [0.0, 0.0]
    rec.log("/tmm/campbell/bands", rr.SeriesLines(names=[f"mode {m // 2 + 1} {'min' if m % 2 == 0 else 'max'} [Hz]"
                                                         for m in range(len(bands))]), static=True)
    rec.send_columns("/tmm/campbell/bands", indexes=[rr.TimeColumn("crank_speed_rpm", sequence=rpm)],
                     columns=rr.Scalars.columns(scalars=np.tile(bands, (len(rpm), 1))))
