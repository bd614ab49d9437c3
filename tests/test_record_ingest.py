"""Ingestion of raw recordings refuses what it cannot read right (issue 32, "no silent nonsense"):
time that is not evenly sampled at the declared rate (gaps, a wrong rate, milliseconds, time going
back), a trigger channel that is not a trigger, pulses that do not match the declared speed; and
what it corrects, it says."""
import math

import numpy as np
import pytest

from cosim.record_ingest import ingest
from cosim.records import RecordError, load_record

FS, RPM, REVS = 2000.0, 300.0, 10          # 400 samples per revolution, exactly
AMPLITUDE_UE, CAL_UE_PER_V = 100.0, 250.0   # bending amplitude of the synthetic gauge; its calibration
PULSE_DEG = 10.0

SIDECAR = '''[record]
name = "{name}"
format = "history"
kind = "synthetic"
speed = "{rpm} rpm"
[provenance]
source = "synthetic: tests/test_record_ingest.py"
[index]
column = "time_s"
unit = "s"
[channels.top_V]
gauge = "g"
face = "top"
quantity = "raw"
unit = "V"
calibration = {cal}
calibration_unit = "microstrain"
[channels.bottom_V]
gauge = "g"
face = "bottom"
quantity = "raw"
unit = "V"
calibration = {cal}
calibration_unit = "microstrain"
[channels.trig_V]
quantity = "trigger"
unit = "V"
[acquisition]
sample_rate = "{rate} Hz"
trigger_channel = "{trigger}"
'''


def signals(drift_ue_per_s=0.0):
    """Time [s], top and bottom gauge [V] (bending 100 sin(crank angle) ue, axial = drift) and a
    5 V trigger pulse of PULSE_DEG at each crank angle 0, written out here from first principles."""
    t = np.arange(int(REVS * 60 / RPM * FS)) / FS
    theta = RPM * math.pi / 30 * t
    bending = AMPLITUDE_UE * np.sin(theta)
    drift = drift_ue_per_s * t
    top, bottom = (bending + drift) / CAL_UE_PER_V, (-bending + drift) / CAL_UE_PER_V
    trig = np.where(np.mod(np.degrees(theta) + 1e-9, 360.0) < PULSE_DEG, 5.0, 0.0)
    return t, top, bottom, trig


def write(folder, t, top, bottom, trig, *, rate=FS, rpm=RPM, trigger="trig_V", name="raw"):
    """A raw record ``<folder>/<name>.csv`` + ``.toml``; returns the sidecar path."""
    lines = ["time_s,top_V,bottom_V,trig_V"] + [f"{a:.9g},{b:.9g},{c:.9g},{d:g}" for a, b, c, d in
                                               zip(t, top, bottom, trig)]
    (folder / f"{name}.csv").write_text("\n".join(lines) + "\n")
    side = folder / f"{name}.toml"
    side.write_text(SIDECAR.format(name=name, rpm=rpm, cal=CAL_UE_PER_V, rate=rate, trigger=trigger))
    return side


def test_a_clean_raw_record_gives_the_known_amplitude_and_says_what_it_corrected(tmp_path):
    out = ingest(load_record(write(tmp_path, *signals(drift_ue_per_s=20.0))))
    g = out["g"]
    # The synthetic gauge bends 100 sin(theta) ue; 360 bins of 1 deg lose at most 1 - cos(0.5 deg).
    assert np.max(g["bending_ue"]) == pytest.approx(AMPLITUDE_UE, rel=0.01)
    assert np.min(g["bending_ue"]) == pytest.approx(-AMPLITUDE_UE, rel=0.01)
    # The sampled pulse rises between two samples and the interpolated edge lands half a sample
    # (0.45 deg, 0.8 ue) after the true crank angle 0: 2 % of the amplitude covers it.
    ref = AMPLITUDE_UE * np.sin(out["angle_rad"])
    assert np.max(np.abs(g["bending_ue"] - ref)) < 0.02 * AMPLITUDE_UE
    # 20 ue/s of common drift is removed (axial back to ~0) and the notes say so, per channel.
    assert np.max(np.abs(g["axial_ue"])) < 0.01 * AMPLITUDE_UE
    # The recording starts inside the first pulse (no rising edge there): pulses 1..9, 8 revolutions.
    assert out["revolutions"] == REVS - 2
    drift_notes = [n for n in out["notes"] if "drift" in n]
    assert len(drift_notes) == 2 and any("top_V" in n for n in drift_notes)
