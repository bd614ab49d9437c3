"""The recording's pure parts, without a recording: the blueprint as a function of the spec, the
linkage drawing and its factor, the timelines, record alignment, chart ticks, the CLI flags."""
import dataclasses
import math

import numpy as np
import pytest

from cosim import alignment
from cosim.motor import MotorTrace
from cosim.recording import linkage
from cosim.recording.blueprint import run_blueprint, views
from cosim.recording.layout import angle_indexes, motor_groups, motor_label, nice_factor
from cosim.recording.spec import GaugeSpec, RecordingSpec

SPEC = RecordingSpec("rig", "prescribed", gauges=(GaugeSpec("coupler_mid", "coupler", 0.127, "top"),
                                                  GaugeSpec("rocker_mid", "rocker", 0.1524, "top")),
                     links=(("crank", 0.18), ("coupler", 0.25), ("rocker", 0.30)), engines=("tmm", "exudyn"),
                     bounds=((-0.1, 0.4), (-0.1, 0.3)))


def test_blueprint_is_a_pure_function_of_the_spec():
    a, b = views(run_blueprint(SPEC, (), 20.0)), views(run_blueprint(SPEC, (), 20.0))
    assert [(v["name"], v["class"], v["contents"]) for v in a] == [(v["name"], v["class"], v["contents"]) for v in b]
    by_name = {v["name"]: v for v in a}
    for g in ("coupler_mid", "rocker_mid"):
        (view,) = [v for v in a if v["name"].startswith(f"bending strain {g} ")]
        assert view["class"] == "TimeSeries" and f"/records/strain/{g}/**" in view["contents"]
        assert {"/tmm/strain/" + g, "/exudyn/strain/" + g, "/mujoco/strain/" + g} <= set(view["contents"])
    (linkage_view,) = [v for v in a if v["class"] == "2D"]
    assert "×20" in linkage_view["name"] and "/tmm/linkage/**" in linkage_view["contents"]
    assert "axial strains [µε]" in by_name and any(n.startswith("drive power") for n in by_name)
    assert not any(n.startswith("motor ") for n in by_name)          # prescribed: no motor views
    motor = views(run_blueprint(dataclasses.replace(SPEC, mode="motor"), ("other",), None))
    names = {v["name"] for v in motor}
    assert {"motor current [A]", "motor voltage [V]", "motor torque [N m]"} <= names
    assert any("/other/strain/coupler_mid" in v["contents"] for v in motor)      # an engine not in the spec
    assert "no elastic deformation drawn yet" in next(v["name"] for v in motor if v["class"] == "2D")


def test_straight_links_are_drawn_as_they_are_and_offsets_are_exaggerated():
    x = np.linspace(0.0, 0.3, 7)
    straight = np.column_stack([0.1 + x * 0.6, 0.2 + x * 0.8])            # a link at an angle
    s, d, names = linkage.frame({"rocker": straight}, {"rocker": x}, 50.0)
    np.testing.assert_allclose(d[0], straight, atol=1e-15)
    np.testing.assert_allclose(s[0], straight[[0, -1]])
    bent = straight + np.outer(np.sin(math.pi * x / 0.3), [-0.8, 0.6]) * 1e-3     # 1 mm off the line
    _, d, _ = linkage.frame({"rocker": bent}, {"rocker": x}, 50.0)
    np.testing.assert_allclose(d[0] - straight, 50.0 * (bent - straight), atol=1e-12)
    assert linkage.largest_offset({"rocker": bent}, {"rocker": x}) == pytest.approx(1e-3)
    # Without stations (or the wrong number of them) the nodes count as evenly spaced.
    np.testing.assert_allclose(linkage.fractions(None, 3), [0.0, 0.5, 1.0])
    np.testing.assert_allclose(linkage.fractions([0.0, 1.0], 3), [0.0, 0.5, 1.0])


@pytest.mark.parametrize("offset, factor", [(1e-4, 100.0), (1e-3, 10.0), (3e-3, 5.0), (0.02, 1.0), (0.0, 1.0)])
def test_automatic_factor_draws_the_largest_offset_at_about_five_percent(offset, factor):
    assert linkage.auto_factor(offset, 0.3) == factor


def test_nice_factor():
    assert [nice_factor(x) for x in (0.5, 1.0, 1.9, 2.0, 4.9, 7.0, 10.0, 149.9, 1e4 + 1)] == \
        [1.0, 1.0, 1.0, 2.0, 2.0, 5.0, 10.0, 100.0, 1e4]


def test_wrapped_angle_and_revolution():
    m, wrapped, rev = angle_indexes(np.radians([-0.5, 0.0, 359.9995, 360.0, 725.0]))
    np.testing.assert_array_equal(m, [-500, 0, 360000, 360000, 725000])     # rounded to mdeg first
    np.testing.assert_array_equal(wrapped, [359500, 0, 0, 0, 5000])
    np.testing.assert_array_equal(rev, [-1, 0, 1, 1, 2])


def test_motor_series_words():
    fields = [f.name for f in dataclasses.fields(MotorTrace)]
    labels = [motor_label(f) for f in fields]
    assert not any(w.count("motor") > 1 for w in labels)                  # never "motor motor speed"
    groups = motor_groups(fields)
    assert groups["speed"] == ["motor_speed_rad_s", "crank_speed_rad_s", "setpoint_rad_s"]
    assert "crank_angle_rad" not in {f for fs in groups.values() for f in fs}            # a timeline
    assert groups["crank_acceleration_rad_s2"] == ["crank_acceleration_rad_s2"]


def test_record_alignment():
    t_hist = np.linspace(0.0, 1.0, 11)
    a_hist = 2.0 * t_hist + 0.5                                       # crank at 2 rad/s from 0.5 rad
    np.testing.assert_allclose(alignment.angle_at([0.25, 2.0, -1.0], t_hist, a_hist, 2.0, 0.5), [1.0, 4.5, -1.5])
    np.testing.assert_allclose(alignment.time_at([1.0, 4.5], t_hist, a_hist, 2.0, 0.5), [0.25, 2.0])
    # A crank that turns back has no unique time for an angle: the nominal speed is used.
    np.testing.assert_allclose(alignment.time_at([1.5], t_hist, np.sin(t_hist * 6), 2.0, 0.5), [0.5])
    angles, values = alignment.repeat_revolution([0.0, math.pi], [[1.0], [2.0]], 0.5, 3 * math.pi)
    np.testing.assert_allclose(angles, [math.pi, 2 * math.pi, 3 * math.pi])
    np.testing.assert_allclose(values[:, 0], [2.0, 1.0, 2.0])
    assert alignment.extent([], 2.0, 0.5) == (0.0, math.pi, 0.5, 0.5 + 2 * math.pi)


def test_chart_ticks():
    from cosim.recording.charts import ticks
    np.testing.assert_allclose(ticks(300.0, 400.0), [300, 320, 340, 360, 380, 400])
    np.testing.assert_allclose(ticks(-2600.0, 1800.0), [-2000, -1000, 0, 1000])


def test_y_tick_values_are_centred_on_their_grid_lines():
    """Issue 31: rerun draws a point's label below the point, so the y values of the sweep and
    band charts sat under their grid lines (79 Hz read as 100). Drawn as strokes, each value's
    figure is centred on its own grid line (and each x value under its tick)."""
    from cosim.recording.charts import HEIGHT, WIDTH, tick_labels

    def to_view(x, y):                     # the chart's frame: (0, 0) bottom left, y down in view units
        return np.column_stack([np.asarray(x, float) / 360.0 * WIDTH, -np.asarray(y, float) / 120.0 * HEIGHT])
    labels = tick_labels(to_view, (0.0, 360.0), (0.0, 120.0), x_ticks=(0.0, 90.0, 180.0, 270.0, 360.0))
    ys = {text: strokes for axis, _, text, strokes in labels if axis == "y"}
    assert sorted(ys, key=float) == ["0", "20", "40", "60", "80", "100", "120"]
    for text, strokes in ys.items():
        pts = np.concatenate(strokes)
        line = -float(text) / 120.0 * HEIGHT
        assert (pts[:, 1].min() + pts[:, 1].max()) / 2 == pytest.approx(line, abs=1e-12), text
        assert pts[:, 1].min() < line < pts[:, 1].max() and pts[:, 0].max() < 0      # across it, left of the frame
    xs = {text: strokes for axis, _, text, strokes in labels if axis == "x"}
    assert list(xs) == ["0", "90", "180", "270", "360"]
    for text, strokes in xs.items():
        pts = np.concatenate(strokes)
        # the figures' box is centred; the ink of a '1' sits at its box's right: within 0.02 (ticks 0.4 apart)
        assert (pts[:, 0].min() + pts[:, 0].max()) / 2 == pytest.approx(float(text) / 360.0 * WIDTH, abs=0.02)
        assert pts[:, 1].min() > 0                                                      # below the frame


def test_tick_figures_have_their_segments():
    from cosim.recording.charts import figure_strokes
    assert len(figure_strokes("8", 0.0, 0.0)) == 7 and len(figure_strokes("1", 0.0, 0.0)) == 2
    assert len(figure_strokes("-1.5", 0.0, 0.0)) == 1 + 2 + 1 + 5          # minus, one, point, five
    right = max(p[:, 0].max() for p in figure_strokes("120", -0.03, 0.0))
    assert right == pytest.approx(-0.03)                                    # right-aligned at the anchor


@pytest.mark.parametrize("argv, viewer, url, save, stdout", [
    ([], "save", None, None, False),
    (["--headless"], "save", None, None, False),
    (["--spawn"], "spawn", None, None, False),
    (["--connect"], "connect", "rerun+http://127.0.0.1:9876/proxy", None, False),
    (["--connect", "rerun+http://h:1/proxy"], "connect", "rerun+http://h:1/proxy", None, False),
    (["--url", "rerun+http://h:2/proxy"], "connect", "rerun+http://h:2/proxy", None, False),
    (["--serve-web", "--save", "x.rrd"], "serve", None, "x.rrd", False),
    (["--save", "--stdout"], "save", None, None, True),
])
def test_viewer_flags(argv, viewer, url, save, stdout):
    from cosim.cli import build_parser
    from cosim.recording.options import viewer_from_args
    options, path = viewer_from_args(build_parser().parse_args(["run", "x", *argv]))
    assert (options.viewer, options.url, None if path is None else str(path), options.stdout) == \
        (viewer, url, save, stdout)
    assert viewer_from_args(build_parser().parse_args(["sweep", "x", "--rpm", "1", "--no-record"])) == (None, None)


def test_linkage_animation_gif(tmp_path):
    """``--animation``: a GIF of the last revolution from the engines' nodes."""
    from types import SimpleNamespace

    from cosim.recording.animation import write_gif
    angle = np.linspace(0.0, 2.5 * math.pi, 200)
    x = np.linspace(0.0, 0.3, 5)
    line = np.stack([np.outer(np.cos(angle), x), np.outer(np.sin(angle), x)], -1)     # a spinning link
    bent = line + np.stack([np.zeros_like(line[..., 0]), 1e-3 * np.sin(np.pi * x / 0.3) * np.ones((200, 1))], -1)
    run = SimpleNamespace(t=angle / 10.0, crank_angle=angle, nodes={"crank": bent})
    path = write_gif(tmp_path / "linkage.gif", {"tmm": run}, {"tmm": {"crank": x}}, frames=6)
    assert path.exists() and path.read_bytes()[:6] == b"GIF89a"


def test_frames_drawn_in_one_batch_equal_the_frame_by_frame_drawing():
    rng = np.random.default_rng(5)
    stations = {"coupler": np.linspace(0.0, 0.3, 5), "rocker": np.linspace(0.0, 0.2, 4)}
    frames_nodes = [{"crank": rng.normal(size=(2, 2)), "coupler": rng.normal(size=(5, 2)),
                     "rocker": rng.normal(size=(4, 2))} for _ in range(7)]
    frames_nodes[3]["rocker"][1, 0] = np.nan            # a non-finite link is left out of its frame
    stacked = {link: np.array([f[link] for f in frames_nodes]) for link in frames_nodes[0]}
    straight, deformed, counts = linkage.block_strips(stacked, len(frames_nodes), stations, 20.0)
    expected = [linkage.frame(f, stations, 20.0) for f in frames_nodes]
    assert counts == [len(s) for s, _, _ in expected] and counts[3] == 2
    for got, want in ((straight, [a for s, _, _ in expected for a in s]),
                      (deformed, [a for _, d, _ in expected for a in d])):
        assert len(got) == len(want)
        for g, w in zip(got, want):
            np.testing.assert_allclose(g, w, rtol=1e-13, atol=1e-15)
    # Frames whose links differ go in blocks of their own (cosim.recording.batch.frame_blocks).
    from cosim.recording.batch import frame_blocks
    mixed = frames_nodes[:2] + [{"crank": rng.normal(size=(2, 2))}]
    blocks = frame_blocks([(float(i), 0.0, f) for i, f in enumerate(mixed)])
    assert [c for b in blocks for c in linkage.block_strips(b.nodes, len(b.t), stations, 2.0)[2]] == [3, 3, 1]


def test_frames_are_stacked_in_blocks_and_drawn_as_frame_by_frame():
    """A batch's linkage frames travel stacked per link (few arrays to pickle); a new block starts
    where the links or a link's node count change, and the blocks draw as the frames do."""
    from cosim.recording.batch import frame_blocks
    rng = np.random.default_rng(7)
    frames = [(0.1 * i, 0.2 * i, {"coupler": rng.normal(size=(5 if i < 3 else 6, 2)), "rocker": rng.normal(size=(4, 2))})
              for i in range(5)]
    frames.append((0.5, 1.0, {"coupler": rng.normal(size=(6, 2))}))
    blocks = frame_blocks(frames)
    assert [len(b.t) for b in blocks] == [3, 2, 1]
    assert [sorted(b.nodes) for b in blocks] == [["coupler", "rocker"]] * 2 + [["coupler"]]
    np.testing.assert_array_equal(np.concatenate([b.t for b in blocks]), [f[0] for f in frames])
    np.testing.assert_array_equal(np.concatenate([b.angle for b in blocks]), [f[1] for f in frames])
    np.testing.assert_array_equal(blocks[1].nodes["coupler"][1], frames[4][2]["coupler"])
    stations = {"rocker": np.linspace(0.0, 0.2, 4)}
    for block, group in zip(blocks, (frames[:3], frames[3:5], frames[5:])):
        got = linkage.block_strips(block.nodes, len(block.t), stations, 5.0)
        want = [linkage.frame(f[2], stations, 5.0) for f in group]
        assert got[2] == [len(w[0]) for w in want]
        for g, w in zip(got[0] + got[1], [a for w in want for a in w[0]] + [a for w in want for a in w[1]]):
            np.testing.assert_allclose(g, w, rtol=1e-13, atol=1e-15)
    assert frame_blocks([]) == []
    assert len(frame_blocks(frames[:3])) == 1


def test_line_strips_built_in_one_piece_equal_rerun_s_own_conversion():
    rr = pytest.importorskip("rerun")
    from cosim.recording.writer import strips_array
    rng = np.random.default_rng(6)
    strips = [rng.normal(size=(n, 2)) for n in (2, 5, 3, 2)]
    assert strips_array(strips).equals(rr.components.LineStrip2DBatch(strips).pa_array)
