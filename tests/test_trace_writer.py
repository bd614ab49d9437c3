"""traces.csv written in blocks (cosim.samples.SampleCollector -> cosim.traces.TraceWriter): the
file does not depend on how the macro steps were grouped into blocks, a block is on disk once
written, and the block's arrays are the steps' (the recording takes the same blocks)."""
from __future__ import annotations

import numpy as np

from cosim.engines.base import EngineOutput
from cosim.samples import SampleCollector
from cosim.traces import TraceWriter, read_traces


def _steps(n_steps=40, seed=3):
    """Macro steps of two engines with different sampling (one sampling 5 times a step, the
    other once, at the step's end: the rows are the union of their times)."""
    rng = np.random.default_rng(seed)
    h = 1e-3
    steps = []
    for k in range(n_steps):
        t_fine = (k + np.arange(1, 6) / 5) * h
        t_end = np.array([(k + 1) * h])

        def out(t):
            m = len(t)
            return EngineOutput(t, rng.normal(size=m), rng.normal(size=m), rng.normal(size=m),
                                gauges={"g": (rng.normal(size=m) * 1e-4, rng.normal(size=m) * 1e-5)},
                                extras={"loop_closure": ("m", rng.normal(size=m))})
        steps.append({"fine": (out(t_fine), None), "coarse": (out(t_end), None)})
    return steps


def _write(path, steps, per_step):
    """traces.csv of ``steps``: a block per step, or one block of all."""
    w, samples = TraceWriter(path), SampleCollector()
    for s in steps:
        samples.add(s)
        if per_step:
            w.write_block(samples.take())
    w.write_block(samples.take())
    w.close()
    return w


def test_blocks_give_the_same_file_as_a_write_per_step(tmp_path):
    steps = _steps()
    _write(tmp_path / "each.csv", steps, True)
    _write(tmp_path / "block.csv", steps, False)
    assert (tmp_path / "each.csv").read_bytes() == (tmp_path / "block.csv").read_bytes()
    cols, data, note = read_traces(tmp_path / "block.csv")
    assert note is None and len(data) == 40 * 5          # the coarse times are among the fine ones
    assert cols[:2] == ["time_s", "fine.crank_angle_rad"] and "coarse.g.bending_ue" in cols
    coarse = data[:, cols.index("coarse.crank_angle_rad")]
    assert np.isfinite(coarse).sum() == 40 and np.isnan(coarse).sum() == 160
    # values in their units (strain written in microstrain)
    np.testing.assert_allclose(data[4::5, cols.index("coarse.g.bending_ue")],
                               [s["coarse"][0].gauges["g"][0][0] * 1e6 for s in steps], rtol=1e-9)


def test_a_block_holds_the_steps_arrays_and_is_on_disk_once_written(tmp_path):
    steps = _steps(6)
    samples = SampleCollector(every_s=1e9, max_samples=31)
    for s in steps:
        samples.add(s)
    assert samples.samples == 36 and samples.due()      # 6 x (5 + 1) samples: past max_samples
    block = samples.take()
    assert samples.samples == 0 and not samples.due() and samples.take() == {}
    np.testing.assert_array_equal(block["fine"]["t"], np.concatenate([s["fine"][0].t for s in steps]))
    np.testing.assert_array_equal(block["coarse"]["gauges"]["g"][1],
                                  np.concatenate([s["coarse"][0].gauges["g"][1] for s in steps]))
    assert block["fine"]["extras"]["loop_closure"][0] == "m" and block["fine"]["motor"] is None
    path = tmp_path / "t.csv"
    w = TraceWriter(path)
    w.write_block(block)
    assert len(path.read_text().splitlines()) == 1 + 6 * 5 and w.rows == 30     # written and flushed
    w.close()
