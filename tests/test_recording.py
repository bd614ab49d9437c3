"""The rerun recording of a co-simulation run (cosim.recording), read back with rerun's own reader.

The macro steps are fabricated with numpy (no engine runs): three engines with different sample
counts per macro step, motor traces, records and text.
"""
import dataclasses
import math

import numpy as np
import pytest

from cosim import scenario as scenarios
from cosim.engines.base import EngineOutput
from cosim.master import MacroStep
from cosim.motor import MotorTrace
from cosim.recording import CRANK_ANGLE, Recorder, read_back, read_blueprint, read_scalars

SAMPLES = {"tmm": 4, "exudyn": 1, "mujoco": 6}      # samples per macro step, as the engines differ
N_STEPS = 6
MOTOR_ENTITIES = ("current", "voltage", "torque", "speed", "power", "energy")


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
    return 1e-4 * np.sin(math.pi * x / x[-1])[None, :] * np.sin(3 * angle)[:, None]


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


def series_names(path):
    """{entity: static series names} straight from the file."""
    from rerun.chunk import RrdReader

    out = {}
    for chunk in RrdReader(str(path)).stream():
        batch = chunk.to_record_batch()
        if chunk.is_static and "SeriesLines:names" in batch.schema.names:
            out[chunk.entity_path] = batch.column(batch.schema.get_field_index("SeriesLines:names")).to_pylist()[-1]
    return out


def record_run(sc, path, mode="motor", **kwargs):
    engines = stations_of(sc)
    rec = Recorder(sc, engines, mode, save_path=path, **kwargs)
    rec.flush_every_steps = 4              # several sends per entity, and a flush at close
    for step in fake_steps(sc, engines, motor=(mode == "motor")):
        rec.log_macro_step(step)
    return rec, engines


def test_layout_counts_and_blueprint(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path)
    angle = np.linspace(0.0, 2 * math.pi, 37)
    rec.log_reference("coupler_mid", "Table II", angle=angle, bending_ue=250 * np.sin(angle),
                      axial_ue=15 * np.cos(angle), kind="published model")
    rec.log_reference("coupler_mid", "Table I", bending_ue=(310.0, -290.0), axial_ue=(20.0, -18.0))
    rec.log_text("resolved_scenario.toml", "[drive]\nspeed_rpm = 373\n")
    rec.close()
    rec.close()                            # idempotent

    counts = read_back(path)
    roots = {e.split("/")[1] for e in counts}
    assert {"tmm", "exudyn", "mujoco", "motor", "records", "scenario"} <= roots

    gauges = [g.name for g in sc.gauges]
    for engine, m in SAMPLES.items():
        for g in gauges:
            assert counts[f"/{engine}/strain/{g}"] == N_STEPS * m
        assert counts[f"/{engine}/drive_torque"] == N_STEPS * m
        assert counts[f"/{engine}/crank_speed"] == N_STEPS * m
        assert counts[f"/{engine}/linkage/rigid"] == N_STEPS          # once per macro step
        assert counts[f"/{engine}/linkage/deformed"] == N_STEPS
        for q in MOTOR_ENTITIES:
            assert counts[f"/motor/{engine}/{q}"] == N_STEPS * m
    assert counts["/mujoco/extras/loop_closure_m"] == N_STEPS * SAMPLES["mujoco"]
    assert counts["/records/strain/coupler_mid/Table_I"] == 2          # a line: two ends
    assert counts["/records/strain/coupler_mid/Table_II"] > 0
    assert counts["/scenario/resolved_scenario.toml"] == 1
    assert counts["/scenario/linkage_drawing"] == 1

    names = series_names(path)
    assert names["/exudyn/strain/coupler_mid"] == ["exudyn bending [µε]", "exudyn axial [µε]"]
    assert names["/motor/tmm/current"] == ["tmm motor current [A]"]
    assert names["/records/strain/coupler_mid/Table_I"][0] == "Table I (measurement) bending +peak [µε]"

    views = read_blueprint(path)
    assert views, "the default blueprint is not in the file"
    by_name = {v["name"]: v for v in views}
    for g in gauges:
        (view,) = [v for v in views if v["name"].startswith(f"strain {g} ")]
        assert view["class"] == "TimeSeries"
        assert set(view["contents"]) == {f"/{e}/strain/{g}" for e in SAMPLES} | {f"/records/strain/{g}/**"}
    linkage = [v for v in views if v["class"] == "2D"]
    assert len(linkage) == 1 and set(linkage[0]["contents"]) == {f"/{e}/linkage/**" for e in SAMPLES}
    assert "×20" in linkage[0]["name"]                                  # exaggeration declared
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
        assert values.shape == (len(t), 2)
        np.testing.assert_allclose(t_read, t, atol=1e-9)               # sim_time is stored in ns
        np.testing.assert_allclose(values[:, 0], bending * 1e6, rtol=1e-12)   # microstrain
        np.testing.assert_allclose(values[:, 1], axial * 1e6, rtol=1e-12)

        mdeg, _ = read_scalars(path, f"/{engine}/strain/{gauge}", timeline=CRANK_ANGLE)
        np.testing.assert_array_equal(mdeg, np.rint(np.degrees(angle) * 1000).astype(np.int64))

    _, current = read_scalars(path, "/motor/tmm/current")
    tmm_angle = np.concatenate([s.outputs["tmm"][1].crank_angle_rad for s in steps])
    np.testing.assert_allclose(current[:, 0], 2.0 + np.sin(tmm_angle), rtol=1e-12)


def test_records_span_the_run(sc, tmp_path):
    path = tmp_path / "run.rrd"
    rec, _ = record_run(sc, path, mode="prescribed")
    angle = np.linspace(0.0, 2 * math.pi, 37)
    rec.log_reference("rocker_mid", "history", angle=angle, bending_ue=100 * np.cos(angle))
    rec.log_reference("rocker_mid", "peaks", bending_ue=(120.0, -80.0))
    rec.log_reference("rocker_mid", "lab", t=[0.0, 0.01, 0.02], axial_ue=[1.0, 2.0, 3.0], kind="synthetic")
    rec.close()

    counts = read_back(path)
    # Prescribed: no motor traces, only the drive power demand (torque x crank speed).
    assert {e for e in counts if e.startswith("/motor")} <= {f"/motor/{e}/power_demand" for e in ("tmm", "exudyn", "mujoco")}
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
    t_lab, lab = read_scalars(path, "/records/strain/rocker_mid/lab")
    np.testing.assert_allclose(t_lab, [0.0, 0.01, 0.02], atol=1e-9)
    np.testing.assert_allclose(lab[:, 0], [1.0, 2.0, 3.0])

    names = {v["name"] for v in read_blueprint(path)}
    assert not any(n.startswith("motor ") for n in names)


def test_linkage_every_and_exaggeration(sc, tmp_path):
    from rerun.chunk import RrdReader

    path = tmp_path / "run.rrd"
    rec, engines = record_run(sc, path, mode="prescribed", exaggeration=50.0, linkage_every=4)
    rec.close()
    counts = read_back(path)
    # Steps 1 and 5 by the stride; the last step (6) is always drawn.
    assert counts["/tmm/linkage/rigid"] == counts["/tmm/linkage/deformed"] == 3

    rows = []
    for chunk in RrdReader(str(path)).stream():
        if chunk.entity_path == "/tmm/linkage/deformed" and not chunk.is_static:
            batch = chunk.to_record_batch()
            t = batch.column(batch.schema.get_field_index("sim_time")).cast("int64").to_numpy()
            rows += zip(t, batch.column(batch.schema.get_field_index("LineStrips2D:strips")).to_pylist())
    t_ns, strips = max(rows, key=lambda r: r[0])
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
    assert counts["/mujoco/linkage/rigid"] == 2
    assert counts["/mujoco/strain/coupler_mid"] == 2 * SAMPLES["mujoco"]
    (view,) = [v for v in read_blueprint(path) if v["name"].startswith("strain coupler_mid ")]
    assert "/mujoco/strain/coupler_mid" in view["contents"]


def test_needs_a_destination(sc):
    with pytest.raises(ValueError, match="save_path"):
        Recorder(sc, {"tmm": {}}, "prescribed")


@pytest.mark.parametrize("kwargs", [dict(exaggeration=0.0), dict(linkage_every=0)])
def test_bad_settings(sc, tmp_path, kwargs):
    with pytest.raises(ValueError):
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
