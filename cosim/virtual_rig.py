"""A virtual rig: a synthetic raw lab recording made from a known strain history, to prove that
ingestion (:func:`cosim.record_ingest.ingest`) recovers the truth.

The truth is one revolution of top- and bottom-face surface strain over crank angle (typically a
reference-engine run). The rig turns the crank at constant speed, samples the gauges at
``sample_rate_Hz`` (2751 Hz as on Wang's rig) as voltages through a known calibration, and adds
white noise, a slow linear drift and a once-per-revolution trigger pulse whose timing jitters.
The record's provenance is ``synthetic``: it is never a measurement and only ever used to test
the pipeline.

Owns: synthetic records from known truth. Boundaries: no fitting and no scoring.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .scenario_types import from_rpm

PULSE_WIDTH_DEG = 5.0


def synthesize(folder, name: str, truth_angle, top_ue, bottom_ue, *, rpm: float, revolutions: int = 12,
               sample_rate_Hz: float = 2751.0, calibration_ue_per_V: float = 250.0, noise_ue: float = 5.0,
               drift_ue_per_s: float = 20.0, trigger_jitter_s: float = 2e-4, trigger_angle_deg: float = 0.0,
               gauge: str = "coupler_mid", seed: int = 1) -> Path:
    """Write ``<folder>/<name>.csv`` and ``.toml``; returns the sidecar path.

    ``truth_angle`` [rad] over one revolution with ``top_ue``/``bottom_ue`` [microstrain]."""
    rng = np.random.default_rng(seed)
    omega = from_rpm(rpm)
    period = 2 * math.pi / omega
    t = np.arange(int(revolutions * period * sample_rate_Hz)) / sample_rate_Hz
    angle = math.radians(trigger_angle_deg) + omega * t            # the crank passes the trigger at t = k period
    a = np.mod(np.asarray(truth_angle, float), 2 * math.pi)
    order = np.argsort(a)

    def truth(values):
        return np.interp(np.mod(angle, 2 * math.pi), a[order], np.asarray(values, float)[order], period=2 * math.pi)

    drift = drift_ue_per_s * t
    volts = {}
    for face, values in (("top", top_ue), ("bottom", bottom_ue)):
        signal = truth(values) + drift + rng.normal(0.0, noise_ue, t.size)
        volts[face] = signal / calibration_ue_per_V
    # Trigger: a 5 V pulse of PULSE_WIDTH_DEG starting at each pass, its timing jittered.
    trigger = np.zeros(t.size)
    width = math.radians(PULSE_WIDTH_DEG) / omega
    for k in range(revolutions + 1):
        start = k * period + rng.normal(0.0, trigger_jitter_s)
        trigger[(t >= start) & (t < start + width)] = 5.0
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    csv_path = folder / f"{name}.csv"
    with open(csv_path, "w", encoding="utf-8") as fh:
        fh.write("time_s,top_V,bottom_V,trigger_V\n")
        for row in zip(t, volts["top"], volts["bottom"], trigger):
            fh.write(f"{row[0]:.7f},{row[1]:.7g},{row[2]:.7g},{row[3]:g}\n")
    side = folder / f"{name}.toml"
    side.write_text(f'''[record]
name = "{name}"
format = "history"
kind = "synthetic"
speed = "{rpm} rpm"
description = "Virtual rig: synthetic raw recording made from a known history (never a measurement)"
sign_convention = "tension positive"

[provenance]
source = "synthetic: cosim.virtual_rig.synthesize (seed {seed})"
notes = "noise {noise_ue} ue rms, drift {drift_ue_per_s} ue/s, trigger jitter {trigger_jitter_s} s rms, calibration {calibration_ue_per_V} ue/V"

[index]
column = "time_s"
unit = "s"

[channels.top_V]
gauge = "{gauge}"
face = "top"
quantity = "raw"
unit = "V"
calibration = {calibration_ue_per_V}
calibration_unit = "microstrain"

[channels.bottom_V]
gauge = "{gauge}"
face = "bottom"
quantity = "raw"
unit = "V"
calibration = {calibration_ue_per_V}
calibration_unit = "microstrain"

[channels.trigger_V]
quantity = "trigger"
unit = "V"

[acquisition]
sample_rate = "{sample_rate_Hz} Hz"
trigger_channel = "trigger_V"
trigger_angle = "{trigger_angle_deg} deg"
filter = "none"
''', encoding="utf-8")
    return side


def synthesize_peaks(folder, name: str, rig: str, peaks: dict, *, noise_relative: float = 0.10,
                     noise_absolute_ue: float = 5.0, seed: int = 1, truth: dict | None = None) -> Path:
    """A synthetic *peaks* record (the format of Table I) made from known model peaks: writes
    ``<folder>/<name>.csv`` and ``.toml`` and returns the sidecar path.

    ``peaks``: ``{rpm: {gauge: {"+": ue, "-": ue}}}`` (bending, signed: the "-" peak negative,
    written as a magnitude like Table I). Each value gets Gaussian noise of standard deviation
    ``sqrt((noise_relative * value)^2 + noise_absolute_ue^2)`` (the same error model as
    :mod:`cosim.identify`'s residuals). ``truth``: the parameter values the peaks came from,
    written into the provenance (never used by the bench). The record's kind is ``synthetic``."""
    rng = np.random.default_rng(seed)
    lines = ["rpm,gauge,peak,quantity,value,unit"]
    for rpm in sorted(peaks):
        for gauge in sorted(peaks[rpm]):
            for side in ("+", "-"):
                if side not in peaks[rpm][gauge]:
                    continue
                v = float(peaks[rpm][gauge][side])
                v += rng.normal(0.0, math.hypot(noise_relative * v, noise_absolute_ue))
                lines.append(f"{rpm:g},{gauge},{side},bending,{abs(v):.6g},microstrain")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{name}.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    truth_text = ", ".join(f"{k} = {v!r}" for k, v in (truth or {}).items()) or "not given"
    side_path = folder / f"{name}.toml"
    side_path.write_text(f'''[record]
name = "{name}"
format = "peaks"
kind = "synthetic"
rig = "{rig}"
description = "Virtual rig: +/- bending peaks of a model run with known parameters, with noise (never a measurement)"
sign_convention = "as the model's declared gauge faces"

[provenance]
source = "synthetic: cosim.virtual_rig.synthesize_peaks (seed {seed})"
notes = "noise sqrt(({noise_relative} * peak)^2 + {noise_absolute_ue}^2) ue; truth: {truth_text}"
''', encoding="utf-8")
    return side_path
