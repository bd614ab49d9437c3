"""traces.csv written in blocks (cosim.traces.TraceWriter): the file does not depend on how the
macro steps were grouped into writes, a step is on disk once its block is written, and closing
writes what is pending."""
from __future__ import annotations

import numpy as np

from cosim.engines.base import EngineOutput
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


def _write(path, steps, flush_every_s, close=True):
    w = TraceWriter(path, flush_every_s=flush_every_s)
    for s in steps:
        w.write_step(s)
    if close:
        w.close()
    return w


def test_blocks_give_the_same_file_as_a_write_per_step(tmp_path):
    steps = _steps()
    _write(tmp_path / "each.csv", steps, 0.0)            # a write after every step
    _write(tmp_path / "block.csv", steps, 1e9)           # one block, written at close
    assert (tmp_path / "each.csv").read_bytes() == (tmp_path / "block.csv").read_bytes()
    cols, data, note = read_traces(tmp_path / "block.csv")
    assert note is None and len(data) == 40 * 5          # the coarse times are among the fine ones
    assert cols[:2] == ["time_s", "fine.crank_angle_rad"] and "coarse.g.bending_ue" in cols
    coarse = data[:, cols.index("coarse.crank_angle_rad")]
    assert np.isfinite(coarse).sum() == 40 and np.isnan(coarse).sum() == 160
    # values in their units (strain written in microstrain)
    np.testing.assert_allclose(data[4::5, cols.index("coarse.g.bending_ue")],
                               [s["coarse"][0].gauges["g"][0][0] * 1e6 for s in steps], rtol=1e-9)


def test_a_step_is_on_disk_after_its_block_and_close_writes_the_rest(tmp_path):
    steps = _steps(6)
    path = tmp_path / "t.csv"
    w = _write(path, steps, 1e9, close=False)
    assert len(path.read_text().splitlines()) == 1      # the header only: the block is pending
    w.flush()
    assert len(path.read_text().splitlines()) == 1 + 6 * 5
    w.write_step(_steps(7)[6])
    w.close()
    assert len(path.read_text().splitlines()) == 1 + 7 * 5 and w.rows == 35
