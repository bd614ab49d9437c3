"""Issue 18 items 6 and 8: results in Python (`cosim.load_run`, traces.parquet, the notebook) and a
figure per run (strains.png/.svg), sweep and band figures with readable names and records."""
import json
import math
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.figures import gauge_label
from cosim.results import COLUMNS, parse_column
from cosim.runs import RunOptions, run_scenario
from cosim.traces import read_traces

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def run95(tmp_path_factory):
    """crank_rocker_95rpm through tmm and mujoco, two revolutions from rest (not steady)."""
    out = tmp_path_factory.mktemp("results") / "r95"
    res = run_scenario("crank_rocker_95rpm", RunOptions(engines=("tmm", "mujoco"), revolutions=2, out=out,
                                                        viewer="none", progress=False))
    assert res.summary["status"] == "completed", res.summary
    return res


def test_a_run_writes_parquet_and_the_strain_figure(run95):
    folder = run95.folder
    for f in ("traces.csv", "traces.parquet", "strains.png", "strains.svg"):
        assert (folder / f).stat().st_size > 1000, f
    files = json.loads((folder / "summary.json").read_text())["files"]
    assert files["traces_parquet"] == "traces.parquet" and files["figures"] == ["strains.png", "strains.svg"]
    notes = run95.summary.get("notes", [])
    assert not any("not drawn" in n or "not written" in n for n in notes), notes


def test_the_svg_keeps_text_editable_with_readable_names_units_and_the_unsteady_mark(run95):
    svg = (run95.folder / "strains.svg").read_text(encoding="utf-8")
    assert svg.count("<text") > 10                       # svg.fonttype = 'none': text, not glyph paths
    assert "coupler, mid-span" in svg and "rocker, mid-span" in svg and "coupler_mid" not in svg
    assert "µε" in svg and "crank angle [deg]" in svg
    assert "NOT STEADY" in svg and "not steady (a transient)" in svg        # two revolutions from rest
    assert "FE crank-rocker thesis, TABLE I (measurement) +peak" in svg      # Table I at 95 rpm


def test_load_run_gives_the_long_table_in_microstrain_matching_the_csv(run95):
    run = cosim.load_run(run95.folder)
    assert list(run.traces.columns) == COLUMNS
    assert run.summary["scenario"] == "crank_rocker_95rpm" and set(run.engines) == {"tmm", "mujoco"}
    assert run.gauges == ["coupler_mid", "rocker_mid"]
    t = run.traces
    units = {q: set(t[t.quantity == q].unit.astype(str)) for q in ("bending", "axial", "drive_torque", "crank_speed")}
    assert units == {"bending": {"µε"}, "axial": {"µε"}, "drive_torque": {"N m"}, "crank_speed": {"rad/s"}}
    assert "crank_angle" not in set(t.quantity.astype(str))          # it is the crank_angle_deg column
    cols, data, _ = read_traces(run95.folder / "traces.csv")
    j, ja = cols.index("tmm.coupler_mid.bending_ue"), cols.index("tmm.crank_angle_rad")
    ok = np.isfinite(data[:, j])
    rows = t[(t.engine == "tmm") & (t.gauge == "coupler_mid") & (t.quantity == "bending")].sort_values("time_s")
    np.testing.assert_allclose(rows.value.to_numpy(), data[ok, j])
    np.testing.assert_allclose(rows.crank_angle_deg.to_numpy(), np.degrees(data[ok, ja]))
    # the summary's extremes are the long table's last revolution
    last = run.last_revolution("mujoco")
    b = last[(last.gauge == "rocker_mid") & (last.quantity == "bending")].value
    g = run.summary["engines"]["mujoco"]["gauges"]["rocker_mid"]
    assert b.max() == pytest.approx(g["bending_max_ue"], rel=1e-8)
    assert b.min() == pytest.approx(g["bending_min_ue"], rel=1e-8)
    assert last.crank_angle_deg.between(0, 360).all()
    assert run.steady("tmm") is False


def test_load_run_reads_the_csv_of_a_killed_run(run95, tmp_path):
    folder = tmp_path / "killed"
    shutil.copytree(run95.folder, folder)
    (folder / "traces.parquet").unlink()
    text = (folder / "traces.csv").read_text()
    (folder / "traces.csv").write_text(text[: len(text) - 40])        # the last line cut by a kill
    summary = json.loads((folder / "summary.json").read_text())
    summary["status"] = "incomplete"
    (folder / "summary.json").write_text(json.dumps(summary))
    run = cosim.load_run(folder)
    assert any("cut off" in n for n in run.notes) and any("incomplete" in n for n in run.notes)
    full = cosim.load_run(run95.folder).traces
    assert 0 < len(full) - len(run.traces) <= 20                     # one CSV row of ~18 traces lost


def test_the_parquet_file_holds_the_table_built_from_the_csv(run95, tmp_path):
    """traces.parquet is written from arrow arrays, the CSV's table through pandas: same rows."""
    import pandas as pd
    folder = tmp_path / "csv_only"
    shutil.copytree(run95.folder, folder)
    (folder / "traces.parquet").unlink()
    from_csv = cosim.load_run(folder).traces
    from_parquet = cosim.load_run(run95.folder).traces
    assert len(from_csv) > 1000
    # the parquet file is converted in chunks of rows: the same rows, in another order
    key = ["engine", "gauge", "quantity", "time_s"]
    pd.testing.assert_frame_equal(from_parquet.sort_values(key).reset_index(drop=True),
                                  from_csv.sort_values(key).reset_index(drop=True))


def test_load_run_names_what_is_missing(tmp_path):
    with pytest.raises(FileNotFoundError, match="no summary.json"):
        cosim.load_run(tmp_path)
    (tmp_path / "summary.json").write_text(json.dumps({"scenario": "x", "status": "completed"}))
    with pytest.raises(FileNotFoundError, match="no traces.csv"):
        cosim.load_run(tmp_path)


@pytest.mark.parametrize("column, parsed", [
    ("tmm.coupler_mid.bending_ue", ("tmm", "coupler_mid", "bending", "µε")),
    ("mujoco.drive_torque_Nm", ("mujoco", "", "drive_torque", "N m")),
    ("exudyn.crank_speed_rad_s", ("exudyn", "", "crank_speed", "rad/s")),
    ("motor.tmm.current_A", ("tmm", "", "motor_current", "A")),
    ("motor.tmm.motor_speed_rad_s", ("tmm", "", "motor_speed", "rad/s")),
    ("motor.mujoco.electrical_power_W", ("mujoco", "", "motor_electrical_power", "W")),
    ("mujoco.loop_closure_m", ("mujoco", "", "loop_closure", "m")),
])
def test_trace_columns_parse_to_engine_gauge_quantity_unit(column, parsed):
    assert parse_column(column) == parsed


def test_readable_gauge_names():
    assert gauge_label("coupler_mid") == "coupler, mid-span"
    assert gauge_label("follower_mid") == "follower, mid-span"
    assert gauge_label("crank") == "crank"


def test_a_failing_figure_is_a_note_and_never_loses_the_run(tmp_path, monkeypatch):
    import cosim.figures

    def broken(*args, **kwargs):
        raise RuntimeError("no fonts today")
    monkeypatch.setattr(cosim.figures, "write_run_figures", broken)
    res = run_scenario("crank_rocker_95rpm", RunOptions(engines=("tmm",), revolutions=0.3, out=tmp_path / "r",
                                                        viewer="none", progress=False))
    # issue 32: a run missing one of its files no longer reads 'completed' (was the expected status)
    assert res.summary["status"] == "completed with missing outputs"
    assert res.summary["missing"][0]["what"] == "strains.png"
    assert any("strain figure not drawn: RuntimeError: no fonts today" in n for n in res.summary["notes"])
    saved = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert saved["notes"] == res.summary["notes"] and (tmp_path / "r" / "traces.parquet").exists()


def test_history_records_are_drawn_as_curves(run95, tmp_path):
    from cosim.figures import plot_strains, record_histories
    from cosim.scenario import load
    hist = record_histories(load("crank_rocker_373rpm"))       # the thesis's Table II over crank angle
    assert set(hist) >= {"coupler_mid", "rocker_mid"}
    paths = plot_strains(run95.folder, hist, folder=tmp_path)
    svg = paths[1].read_text(encoding="utf-8")
    assert "FE crank-rocker thesis, TABLE II (published model) bending" in svg


def test_sweep_figure_shows_measured_peaks_and_campbell_labels_do_not_overlap(tmp_path):
    from cosim.figures import peaks_by_speed
    from cosim.resonance import harmonic_labels, plot_sweep
    peaks = peaks_by_speed("fe_crank_rocker", 90, 400)
    assert {p["rpm"] for p in peaks} == {95.0, 241.0, 373.0}
    points = [{"rpm": r, "engines": {"tmm": {"status": "completed", "gauges": {
        "coupler_mid": {"bending_max_ue": r / 4, "bending_min_ue": -r / 3},
        "rocker_mid": {"bending_max_ue": r / 2, "bending_min_ue": -r / 2}}}}} for r in (100.0, 250.0, 400.0)]
    angle = np.radians(np.arange(36) * 10.0)
    fmap = {"angle_rad": angle, "f_Hz": np.stack([79 + np.sin(angle), 114 + 2 * np.cos(angle)], 1)}
    paths = plot_sweep(tmp_path, "fe", points, fmap, marks_rpm=[373], record_peaks=peaks)
    svg = (tmp_path / "sweep_peaks.svg").read_text(encoding="utf-8")
    assert "FE crank-rocker thesis, TABLE I (measurement), rocker, mid-span +peak" in svg
    assert "crank_mid" not in svg and "crank, mid-span" not in svg     # Table II's crank: no curve to compare
    assert {p.name for p in paths} == {"sweep_peaks.png", "sweep_peaks.svg", "campbell.png", "campbell.svg"}
    # labels of 20 harmonics on a 100-400 rpm axis: none overprints another
    from cosim.figures import new_figure
    fig = new_figure(figsize=(6, 4.5))
    ax = fig.subplots()
    ax.set_xlim(100, 400)
    ax.set_ylim(0, 130)
    harmonic_labels(ax, 100, 400, 130, 20)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    renderer = FigureCanvasAgg(fig).get_renderer()
    boxes = [t.get_window_extent(renderer) for t in ax.texts]
    assert len(boxes) >= 4
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_band_figure_uses_readable_names(tmp_path):
    from cosim.uncertainty import plot_band
    rows = [{"gauge": g, "crank_angle_deg": a, "nominal_ue": math.sin(math.radians(a)) * 100, "low_ue": -120.0,
             "high_ue": 120.0, "p5_ue": -110.0, "p95_ue": 110.0} for g in ("coupler_mid", "rocker_mid")
            for a in range(0, 360, 10)]
    records = [{"record": "fe_table1", "title": "FE crank-rocker thesis, TABLE I (measurement)", "gauge": "coupler_mid",
                "peak": "+", "recorded_ue": 79.3, "band_ue": [60, 90], "inside": True}]
    plot_band(tmp_path, "crank_rocker_373rpm", rows, records)
    svg = (tmp_path / "band.svg").read_text(encoding="utf-8")
    assert "coupler, mid-span" in svg and "FE crank-rocker thesis, TABLE I (measurement) +peak (inside the band)" in svg
    assert "fe_table1" not in svg and "coupler_mid" not in svg


def run_cell_as_jupyter(source: str, name: str, namespace: dict) -> list:
    """Run a code cell as Jupyter with matplotlib's inline backend would, and return the figures
    it displays, once per display: the cell's value when it is a figure (the last line an
    expression), every open figure at ``plt.show()`` (which then closes them), and every figure
    still open at the end of the cell."""
    import ast

    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure
    shown = []

    def show(*args, **kwargs):
        shown.extend(plt.figure(n) for n in plt.get_fignums())
        plt.close("all")
    namespace["plt"] = plt
    tree = ast.parse(source)
    last = tree.body.pop() if tree.body and isinstance(tree.body[-1], ast.Expr) else None
    real_show, plt.show = plt.show, show
    try:
        exec(compile(tree, name, "exec"), namespace)
        value = eval(compile(ast.Expression(last.value), name, "eval"), namespace) if last else None
    finally:
        plt.show = real_show
    shown += [value] if isinstance(value, Figure) else []
    shown += [plt.figure(n) for n in plt.get_fignums()]
    plt.close("all")
    return shown


def test_the_notebook_runs_and_loads_the_run(tmp_path, monkeypatch):
    """scenarios/notebooks/compare_engines.ipynb, code cells in order in a fresh namespace (no
    Jupyter kernel), matplotlib on Agg, from a temporary working directory (its ./logs). Issue 31:
    its figure was shown twice (plt's inline display and the cell's value ``fig``); once now."""
    import matplotlib
    import nbformat
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    nb = nbformat.read(ROOT / "scenarios" / "notebooks" / "compare_engines.ipynb", as_version=4)
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__notebook__"}
    tic = time.perf_counter()
    displayed = []
    for i, cell in enumerate(c for c in nb.cells if c.cell_type == "code"):
        displayed += run_cell_as_jupyter(cell.source, f"compare_engines.ipynb cell {i}", namespace)
    assert time.perf_counter() - tic < 60
    assert len(displayed) == 1 and displayed[0] is namespace["fig"], displayed      # the figure, once
    run = namespace["run"]
    assert isinstance(run, cosim.RunData) and set(run.engines) == {"tmm", "mujoco"}
    assert Path(namespace["result"].folder).parent == tmp_path / "logs"
    fig = namespace["fig"]
    assert len(fig.axes) == 2 and all(ax.get_ylabel() == "bending strain [µε]" for ax in fig.axes)
    plt.close("all")


def test_an_engine_without_results_is_named_on_the_figure(run95, tmp_path):
    from cosim.figures import plot_strains
    folder = tmp_path / "r"
    shutil.copytree(run95.folder, folder)
    summary = json.loads((folder / "summary.json").read_text())
    summary["engines"]["exudyn"] = {"status": "unavailable", "error": "exudyn is not installed"}
    (folder / "summary.json").write_text(json.dumps(summary))
    svg = plot_strains(folder)[1].read_text(encoding="utf-8")
    assert "no result: exudyn (unavailable)" in svg


def test_band_figure_says_the_nominal_is_not_a_sample(tmp_path):
    """Issue 31: the nominal curve left the envelope with no word why. It is the scenario as
    written (at 373 rpm a constant crank speed, an infinite drive inertia outside the declared
    range), not a sample; the figure says so."""
    from cosim.scenario import load
    from cosim.uncertainty import nominal_note, plot_band
    from cosim.unknowns import declared
    sc = load("crank_rocker_373rpm")
    note = nominal_note(declared(sc.raw, str(sc.path))[2])
    assert "not one of the samples" in note and "infinite drive inertia" in note and "'drive_inertia'" in note
    rows = [{"gauge": "coupler_mid", "crank_angle_deg": a, "nominal_ue": 300.0, "low_ue": -120.0, "high_ue": 120.0,
             "p5_ue": -110.0, "p95_ue": 110.0} for a in range(0, 360, 10)]
    plot_band(tmp_path, "crank_rocker_373rpm", rows, [], note)
    svg = (tmp_path / "band.svg").read_text(encoding="utf-8")
    assert "nominal (scenario as written, not a sample)" in svg and "envelope of the samples" in svg
    assert "infinite drive inertia" in svg


def test_the_nominal_note_names_no_drive_inertia_when_none_is_declared():
    from cosim.uncertainty import nominal_note
    assert "inertia" not in nominal_note({})
