"""The rerun recording of a co-simulation run (cosim.recording), read back with rerun's own reader.

The macro steps are fabricated with numpy (no engine runs): three engines with different sample
counts per macro step, motor traces, records and text.
"""
import dataclasses
import math
import time

import numpy as np
import pytest

from cosim import scenario as scenarios
from cosim.engines.base import EngineOutput
from cosim.master import MacroStep
from cosim.motor import MotorTrace
from cosim.recording import (CRANK_ANGLE, CRANK_ANGLE_WRAPPED, REVOLUTION, Recorder, chunk_counts, read_back,
                             read_blueprint, read_column, read_scalars, read_static)

SAMPLES = {"tmm": 4, "exudyn": 1, "mujoco": 6}      # samples per macro step, as the engines differ
N_STEPS = 6
MOTOR_ENTITIES = ("current", "voltage", "torque", "speed", "power", "energy")
AMPLITUDE = 1e-4                                    # fake deflection [m]


@pytest.fixture(scope="module")
def sc():
    return scenarios.load("crank_rocker_373rpm")


def stations_of(sc):
    """Per engine, the node stations of each link (exudyn meshed more coarsely)."""
    own = {link.name: np.asarray(link.stations, dtype=float) for link in sc.mechanism.links()}
    coarse = {name: np.linspace(0.0, x[-1], 5) for name, x in own.items()}
    return {"tmm": own, "exudyn": coarse, "mujoco": own}


def strain(engine, gauge_index, angle):
    """A fake (bending, axial) strain history, different per engine and gauge (dimensionless)."""
    phase = 0.1 * list(SAMPLES).index(engine) + gauge_index
    return 300e-6 * np.sin(angle + phase), 20e-6 * np.cos(2 * angle + phase)


def deflection(x, angle):
    """A fake elastic deflection [m] normal to the ground line, zero at the link ends."""
    return AMPLITUDE * np.sin(math.pi * x / x[-1])[None, :] * np.sin(3 * angle)[:, None]


def fake_steps(sc, engines, n_steps=N_STEPS, motor=True):
    w = sc.drive.speed_rad_s
    H = sc.revolution_period_s / 24
    fields = [f.name for f in dataclasses.fields(MotorTrace)]
    for k in range(n_steps):
        outputs = {}
        for engine, m in SAMPLES.items():
            t = H * k + H * np.arange(1, m + 1) / m
            angle = w * t
            motion = sc.mechanism.motion(angle)
            nodes = {}
            for link in sc.mechanism.links():
                x = engines[engine][link.name]
                rigid = np.asarray(motion.link(link.name).point(x)[0])
                nodes[link.name] = rigid + np.stack([np.zeros((m, len(x))), deflection(x, angle)], -1)
            gauges = {g.name: strain(engine, i, angle) for i, g in enumerate(sc.gauges)}
            extras = {"loop_closure_m": ("m", np.full(m, 1e-7))} if engine == "mujoco" else {}
            out = EngineOutput(t, angle, np.full(m, w), 5.0 * np.sin(2 * angle), gauges, nodes, extras)
            trace = None
            if motor:
                values = {f: np.cos(angle) for f in fields}
                values.update(t=t, crank_angle_rad=angle, current_A=2.0 + np.sin(angle))
                trace = MotorTrace(**values)
            outputs[engine] = (out, trace)
        yield MacroStep(k + 1, n_steps, H * (k + 1), outputs)


def series_names(path, entity):
    return read_static(path, entity, "SeriesLines:names")


def record_run(sc, path, mode="motor", cls=Recorder, **kwargs):
    engines = stations_of(sc)
    rec = cls(sc, engines, mode, save_path=path, **kwargs)
    rec.batch_samples = 10                 # several batches per entity, and the rest at close
    for step in fake_steps(sc, engines, motor=(mode == "motor")):
        rec.log_macro_step(step)
    return rec, engines


def test_layout_counts_and_blueprint(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path)
    angle = np.linspace(0.0, 2 * math.pi, 37)
    rec.log_reference("coupler_mid", "Table II", angle=angle, bending_ue=250 * np.sin(angle),
                      axial_ue=15 * np.cos(angle), kind="published_model")
    rec.log_reference("coupler_mid", "Table I", bending_ue=(310.0, -290.0), axial_ue=(20.0, -18.0))
    rec.log_text("resolved_scenario.toml", "[drive]\nspeed_rpm = 373\n")
    assert rec.close() == []
    assert rec.close() == []               # idempotent

    counts = read_back(path)
    roots = {e.split("/")[1] for e in counts}
    assert {"tmm", "exudyn", "mujoco", "motor", "records", "scenario", "ground"} <= roots

    gauges = [g.name for g in sc.gauges]
    for engine, m in SAMPLES.items():
        for g in gauges:
            assert counts[f"/{engine}/strain/{g}"] == N_STEPS * m
            assert counts[f"/{engine}/axial_strain/{g}"] == N_STEPS * m
        for q in ("drive_torque", "crank_speed", "drive_power"):
            assert counts[f"/{engine}/{q}"] == N_STEPS * m
        assert counts[f"/{engine}/linkage/straight"] == N_STEPS          # once per macro step
        assert counts[f"/{engine}/linkage/deformed"] == N_STEPS
        assert counts[f"/{engine}/linkage/legend"] == 1                  # the view's engine legend
        for q in MOTOR_ENTITIES:
            assert counts[f"/motor/{engine}/{q}"] == N_STEPS * m
    assert counts["/mujoco/extras/loop_closure_m"] == N_STEPS * SAMPLES["mujoco"]
    assert counts["/records/strain/coupler_mid/Table_I"] == 2          # a line: two ends
    assert counts["/records/axial_strain/coupler_mid/Table_I"] == 2
    assert counts["/records/strain/coupler_mid/Table_II"] > 0
    assert counts["/scenario/resolved_scenario.toml"] == 1
    assert counts["/scenario/linkage_drawing"] == 1

    assert series_names(path, "/exudyn/strain/coupler_mid") == ["exudyn bending [µε]"]
    assert series_names(path, "/exudyn/axial_strain/coupler_mid") == ["exudyn coupler_mid axial [µε]"]
    assert series_names(path, "/motor/tmm/current") == ["tmm motor current [A]"]
    assert series_names(path, "/records/strain/coupler_mid/Table_I") == ["Table I +peak (measurement) [µε]",
                                                                          "Table I -peak (measurement) [µε]"]
    assert series_names(path, "/records/strain/coupler_mid/Table_II") == ["Table II (published model) [µε]"]

    views = read_blueprint(path)
    assert views, "the default blueprint is not in the file"
    by_name = {v["name"]: v for v in views}
    for g in gauges:
        (view,) = [v for v in views if v["name"].startswith(f"bending strain {g} ")]
        assert view["class"] == "TimeSeries"
        assert set(view["contents"]) == {f"/{e}/strain/{g}" for e in SAMPLES} | {f"/records/strain/{g}/**"}
    linkage = [v for v in views if v["class"] == "2D"]
    assert len(linkage) == 1 and set(linkage[0]["contents"]) == {f"/{e}/linkage/**" for e in SAMPLES}
    # The factor is chosen from the largest deformation: 1e-4 m drawn at ~5 % of the 0.3 m rocker.
    assert "×100" in linkage[0]["name"]
    assert "×100" in read_static(path, "/tmm/linkage/legend", "Points2D:labels")[0]
    for q in ("current", "voltage", "torque"):
        assert set(by_name[next(n for n in by_name if n.startswith(f"motor {q} "))]["contents"]) == \
            {f"/motor/{e}/{q}" for e in SAMPLES}
    assert any(v["name"].startswith("drive torque") for v in views)


def test_values_read_back_equal_logged(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, engines = record_run(sc, path)
    rec.close()
    steps = list(fake_steps(sc, engines))
    gauge = sc.gauges[0].name
    for engine in ("exudyn", "tmm"):
        outs = [s.outputs[engine][0] for s in steps]
        t = np.concatenate([o.t for o in outs])
        bending = np.concatenate([o.gauges[gauge][0] for o in outs])
        axial = np.concatenate([o.gauges[gauge][1] for o in outs])
        angle = np.concatenate([o.crank_angle for o in outs])

        t_read, values = read_scalars(path, f"/{engine}/strain/{gauge}")
        assert values.shape == (len(t), 1)
        np.testing.assert_allclose(t_read, t, atol=1e-9)               # sim_time is stored in ns
        np.testing.assert_allclose(values[:, 0], bending * 1e6, rtol=1e-12)   # microstrain
        _, values = read_scalars(path, f"/{engine}/axial_strain/{gauge}")
        np.testing.assert_allclose(values[:, 0], axial * 1e6, rtol=1e-12)

        mdeg, _ = read_scalars(path, f"/{engine}/strain/{gauge}", timeline=CRANK_ANGLE)
        np.testing.assert_array_equal(mdeg, np.rint(np.degrees(angle) * 1000).astype(np.int64))
        # Revolutions overlaid: the wrapped angle and the revolution index give the cumulative angle.
        wrapped, _ = read_scalars(path, f"/{engine}/strain/{gauge}", timeline=CRANK_ANGLE_WRAPPED)
        rev, _ = read_scalars(path, f"/{engine}/strain/{gauge}", timeline=REVOLUTION)
        np.testing.assert_array_equal(np.sort(wrapped + 360_000 * rev), mdeg)
        assert wrapped.min() >= 0 and wrapped.max() < 360_000

    _, current = read_scalars(path, "/motor/tmm/current")
    tmm_angle = np.concatenate([s.outputs["tmm"][1].crank_angle_rad for s in steps])
    np.testing.assert_allclose(current[:, 0], 2.0 + np.sin(tmm_angle), rtol=1e-12)
    _, power = read_scalars(path, "/tmm/drive_power")
    out = [s.outputs["tmm"][0] for s in steps]
    np.testing.assert_allclose(power[:, 0], np.concatenate([o.drive_torque * o.crank_speed for o in out]), rtol=1e-12)


def test_one_chunk_per_entity_in_a_file_only_recording(sc, tmp_path):
    """With only a file attached every entity is sent once (``rerun rrd stats`` finds it optimal)."""
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path)
    rec.close()
    counts = chunk_counts(path)
    assert counts and max(counts.values()) == 1, counts


def test_records_span_the_run(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path, mode="prescribed")
    angle = np.linspace(0.0, 2 * math.pi, 37)
    rec.log_reference("rocker_mid", "history", angle=angle, bending_ue=100 * np.cos(angle))
    rec.log_reference("rocker_mid", "peaks", bending_ue=(120.0, -80.0))
    rec.log_reference("rocker_mid", "lab", t=[0.0, 0.01, 0.02], axial_ue=[1.0, 2.0, 3.0], kind="synthetic")
    rec.close()

    counts = read_back(path)
    # Prescribed: no motor entities at all; the drive power is the engine's own.
    assert not any(e.startswith("/motor") for e in counts)
    assert counts["/tmm/drive_power"] == N_STEPS * SAMPLES["tmm"]
    t_end = N_STEPS * sc.revolution_period_s / 24
    a_end = sc.drive.speed_rad_s * t_end
    # The one-revolution angle history is repeated over the crank angles the run covered; the
    # peaks span the run from its first sample (tmm's, after the start) to its last.
    mdeg, values = read_scalars(path, "/records/strain/rocker_mid/history", timeline=CRANK_ANGLE)
    assert mdeg.min() >= 0 and mdeg.max() <= round(math.degrees(a_end) * 1000)
    np.testing.assert_allclose(values[:, 0], 100 * np.cos(np.radians(mdeg / 1000.0)), atol=1e-3)
    t_peaks, peaks = read_scalars(path, "/records/strain/rocker_mid/peaks")
    np.testing.assert_allclose(peaks, [[120.0, -80.0]] * 2)
    assert t_peaks[0] > 0 and t_peaks[-1] == pytest.approx(t_end, abs=1e-9)
    t_lab, lab = read_scalars(path, "/records/axial_strain/rocker_mid/lab")
    np.testing.assert_allclose(t_lab, [0.0, 0.01, 0.02], atol=1e-9)
    np.testing.assert_allclose(lab[:, 0], [1.0, 2.0, 3.0])

    names = {v["name"] for v in read_blueprint(path)}
    assert not any(n.startswith("motor ") for n in names)
    assert any(n.startswith("drive power") for n in names)


def test_no_label_repeats_motor(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path)
    rec.close()
    names = [n for e in read_back(path) for n in (series_names(path, e) or [])]
    assert names and not any("motor motor" in n for n in names)
    assert series_names(path, "/motor/tmm/speed") == ["tmm motor shaft speed [rad/s]",
                                                       "tmm crank speed [rad/s]", "tmm speed set-point [rad/s]"]


def test_linkage_every_and_exaggeration(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, engines = record_run(sc, path, mode="prescribed", exaggeration=50.0, linkage_every=4)
    rec.close()
    counts = read_back(path)
    # Steps 1 and 5 by the stride; the last step (6) is always drawn.
    assert counts["/tmm/linkage/straight"] == counts["/tmm/linkage/deformed"] == 3

    t_ns, strips = read_column(path, "/tmm/linkage/deformed", "LineStrips2D:strips")[-1]
    last = list(fake_steps(sc, engines, motor=False))[-1].outputs["tmm"][0]
    assert t_ns == round(last.t[-1] * 1e9)
    links = sc.mechanism.links()
    assert len(strips) == len(links)                     # one strip per link
    motion = sc.mechanism.motion(last.crank_angle[-1:])
    for link, strip in zip(links, strips):
        x = engines["tmm"][link.name]
        rigid = np.asarray(motion.link(link.name).point(x)[0])[0]
        expected = rigid + 50.0 * np.stack([np.zeros(len(x)), deflection(x, last.crank_angle[-1:])[0]], -1)
        np.testing.assert_allclose(np.array(strip), expected, atol=1e-6)   # float32 in the file
    (linkage,) = [v for v in read_blueprint(path) if v["class"] == "2D"]
    assert "×50" in linkage["name"]


def test_linkage_at_display_rate(sc, tmp_path):
    """At most ``linkage_fps`` frames per simulated second (and always the last step): the fake
    steps are 6.7 ms apart, so 60 fps (16.7 ms) draws steps 1, 4 and the last, 6."""
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path, mode="prescribed", linkage_fps=60.0)
    rec.close()
    assert read_back(path)["/tmm/linkage/deformed"] == 3
    assert read_back(path)["/tmm/strain/coupler_mid"] == N_STEPS * SAMPLES["tmm"]      # data keep every sample


def test_roots_only_for_engines_that_run(sc, tmp_path):
    # The caller may leave an engine out of ``engines`` (no stations known) or name one that never
    # runs: the first is still recorded and in the blueprint, the second gets no root.
    path = tmp_path / "run.rrd"
    engines = stations_of(sc)
    rec = Recorder(sc, {"tmm": engines["tmm"], "ghost": {}}, "prescribed", save_path=path)
    for step in fake_steps(sc, engines, n_steps=2, motor=False):
        rec.log_macro_step(step)
    rec.close()
    counts = read_back(path)
    roots = {e.split("/")[1] for e in counts}
    assert {"tmm", "exudyn", "mujoco"} <= roots and "ghost" not in roots
    assert counts["/mujoco/linkage/straight"] == 2
    assert counts["/mujoco/strain/coupler_mid"] == 2 * SAMPLES["mujoco"]
    (view,) = [v for v in read_blueprint(path) if v["name"].startswith("bending strain coupler_mid ")]
    assert "/mujoco/strain/coupler_mid" in view["contents"]


def test_recorder_in_a_child_process_writes_the_same(sc, tmp_path):
    from cosim.recording import RecorderProcess
    here, there = tmp_path / "here.rrd", tmp_path / "there.rrd"
    for cls, path in ((Recorder, here), (RecorderProcess, there)):
        rec, _ = record_run(sc, path, cls=cls)
        rec.log_reference("coupler_mid", "Table I", bending_ue=(310.0, -290.0))
        # As a run does: hand over, write its other files, then wait. Nothing may be logged between.
        rec.hand_over()
        with pytest.raises(RuntimeError, match="closed"):
            rec.log_text("a", "b")
        assert rec.close() == []
    assert read_back(there) == read_back(here)
    np.testing.assert_array_equal(read_scalars(there, "/tmm/strain/rocker_mid")[1],
                                  read_scalars(here, "/tmm/strain/rocker_mid")[1])


def test_a_files_writer_process_starts_after_its_first_data_or_at_the_hand_over(sc, tmp_path, monkeypatch):
    """The child's start (rerun's import, ~0.5 s of CPU) slows the engines on a second vCPU: a
    file's child starts CHILD_START_AFTER_S after the first data, at the hand-over, or when
    CHILD_START_BYTES of messages wait; nothing is lost either way."""
    from cosim.recording import RecorderProcess, process
    monkeypatch.setattr(process, "CHILD_START_AFTER_S", 600.0)
    rec, _ = record_run(sc, tmp_path / "late.rrd", cls=RecorderProcess)
    assert not rec.writer_started
    rec.hand_over()
    assert rec.writer_started and rec.close() == []
    monkeypatch.setattr(process, "CHILD_START_BYTES", 1)
    rec, _ = record_run(sc, tmp_path / "early.rrd", cls=RecorderProcess)
    assert rec.writer_started and rec.close() == []
    # The timer starts it without a further message (a long macro step).
    monkeypatch.setattr(process, "CHILD_START_BYTES", 64e6)
    monkeypatch.setattr(process, "CHILD_START_AFTER_S", 0.2)
    rec, _ = record_run(sc, tmp_path / "timer.rrd", cls=RecorderProcess)
    deadline = time.monotonic() + 30
    while not rec.writer_started and time.monotonic() < deadline:
        time.sleep(0.05)
    assert rec.writer_started and rec.close() == []
    assert read_back(tmp_path / "late.rrd") == read_back(tmp_path / "early.rrd") == read_back(tmp_path / "timer.rrd")
    assert read_back(tmp_path / "late.rrd")["/tmm/strain/rocker_mid"] > 0


def test_needs_a_destination(sc):
    with pytest.raises(ValueError, match="save_path"):
        Recorder(sc, {"tmm": {}}, "prescribed")


@pytest.mark.parametrize("kwargs, match", [(dict(exaggeration=0.0), "exaggeration"),
                                           (dict(linkage_every=0), "linkage_every"),
                                           (dict(linkage_fps=-1.0), "linkage-fps")])
def test_bad_settings(sc, tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        Recorder(sc, {"tmm": {}}, "prescribed", save_path=tmp_path / "x.rrd", **kwargs)


def test_bad_reference(sc, tmp_path):
    rec = Recorder(sc, {"tmm": {}}, "prescribed", save_path=tmp_path / "x.rrd")
    with pytest.raises(ValueError, match="not both"):
        rec.log_reference("coupler_mid", "x", t=[0.0], angle=[0.0], bending_ue=[1.0])
    with pytest.raises(ValueError, match="bending_ue"):
        rec.log_reference("coupler_mid", "x", t=[0.0])
    with pytest.raises(ValueError, match="has 2 values"):
        rec.log_reference("coupler_mid", "x", t=[0.0, 1.0, 2.0], bending_ue=[1.0, 2.0])
    rec.close()
    with pytest.raises(RuntimeError, match="closed"):
        rec.log_text("a", "b")


# -- issue 31: summary recordings of two runs opened together stay two ------------------------------
def _ids(path):
    from rerun.chunk import RrdReader
    store = RrdReader(str(path)).recordings()[0]
    return store.application_id, store.recording_id


def test_summary_recordings_of_two_runs_have_their_own_ids(tmp_path):
    """Sweep, uncertainty and identification recordings had fixed recording ids ('<name>-sweep'
    ...), so two of them opened in one viewer merged. Two runs of the same scenario, into folders
    of the same name (``--out`` elsewhere), must differ; the application id stays fixed."""
    from cosim.identify_report import record_rrd
    from cosim.recording.summaries import sweep_recording, uncertainty_recording
    points = [{"rpm": 90.0, "engines": {"tmm": {"gauges": {"g": {"bending_max_ue": 1.0, "bending_min_ue": -1.0}}}}}]
    rows = [{"gauge": "g", "crank_angle_deg": a, "low_ue": -1.0, "high_ue": 1.0, "p5_ue": -0.5, "p95_ue": 0.5,
             "nominal_ue": 0.0} for a in (0.0, 180.0)]
    result = {"calibration_scenarios": ["rig"], "validation_scenarios": [], "predictions": {"rig": {"rpm": 90.0}}}
    write = {"flexlink-bench-sweep": lambda p: sweep_recording(p, "rig", points),
             "flexlink-bench-uncertainty": lambda p: uncertainty_recording(p, "rig", rows, []),
             "flexlink-bench-identify": lambda p: record_rrd(p, result, {"rig": {"gauges": {}}})}
    for app, draw in write.items():
        paths = [tmp_path / run / "rig-run" / "summary.rrd" for run in ("a", "b")]
        for p in paths:
            p.parent.mkdir(parents=True)
            draw(p)
        (app_a, id_a), (app_b, id_b) = _ids(paths[0]), _ids(paths[1])
        assert app_a == app_b == app
        assert id_a != id_b and "rig-run" in id_a, (id_a, id_b)
        for p in paths:
            p.unlink()
            p.parent.rmdir()


def test_chart_tick_values_are_strokes_not_point_labels(tmp_path):
    """Issue 31: a chart's point labels are its two axis titles only; the tick values are line
    strokes (point labels sit below their point, off the grid line)."""
    import rerun as rr

    from cosim.recording import read_static
    from cosim.recording.charts import Chart, Series, log_chart
    rec = rr.RecordingStream("test-charts")
    rec.set_sinks(rr.FileSink(str(tmp_path / "c.rrd")))
    log_chart(rec, Chart("/c", "c", "crank speed [rpm]", "frequency [Hz]",
                         [Series("mode 1 [Hz]", [90.0, 100.0], [79.0, 79.0], (0, 0, 200))], y_range=(0.0, 120.0)))
    rec.flush()
    rec.disconnect()
    assert list(read_static(tmp_path / "c.rrd", "/c/labels", "Points2D:labels")) == ["crank speed [rpm]",
                                                                                    "frequency [Hz]"]
    assert len(read_static(tmp_path / "c.rrd", "/c/ticks", "LineStrips2D:strips")) > 7 * 2
