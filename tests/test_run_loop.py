"""The run loop's console numbers (issue 31): the whole run's length in summary.json and the
printed table, however few revolutions the master holds in memory."""
import logging
import math
from types import SimpleNamespace

import pytest

import cosim.runs as run_module
from cosim.master import CoSimulation
from cosim.metrics import run_change
from cosim.report import comparison_table
from cosim.runs import RunOptions, run_scenario
from cosim.run_progress import RunProgress, toward_steady
from cosim.scenario import load
from tmm_core.compiled.cache import cache_is_cold


@pytest.fixture(scope="module")
def six_revolutions(tmp_path_factory):
    """A fixed 6-revolution prescribed TMM run holding one revolution in memory."""
    mp = pytest.MonkeyPatch()
    mp.setattr(run_module, "KEEP_REVOLUTIONS", 1)
    try:
        out = tmp_path_factory.mktemp("six")
        res = run_scenario("crank_rocker_373rpm", RunOptions(engines=("tmm",), revolutions=6, out=out, viewer="none",
                                                             progress=False, figures=False))
    finally:
        mp.undo()
    return res


def test_a_fixed_run_reports_its_whole_length(six_revolutions):
    summary = six_revolutions.summary
    period = 2 * math.pi / abs(load("crank_rocker_373rpm").drive.speed_rad_s)     # closed form [s]
    e = summary["engines"]["tmm"]
    assert e["revolutions_run"] == pytest.approx(6.0, rel=1e-9)
    assert e["sim_time_s"] == pytest.approx(6 * period, rel=1e-9)
    assert summary["sim_time_s"] == pytest.approx(6 * period, rel=1e-9)
    # what the master held is about one revolution: the numbers above do not come from it
    assert six_revolutions.result["tmm"].run.t[0] > 4 * period
    row = next(line for line in comparison_table(summary).splitlines() if line.startswith("tmm      completed"))
    assert f"{6 * period:.3f}" in row.split() and "6.0" in row.split()


# -- the progress shown (issue 31 e) -------------------------------------------------------------
def _step(k, n, change=None, tolerance=None):
    return SimpleNamespace(step=k, n_steps=n, change=change, steady_tolerance=tolerance)


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_a_fixed_run_estimates_its_remaining_time_from_its_steps_not_its_set_up():
    clock = _Clock()
    p = RunProgress(until_steady=False, clock=clock)
    clock.now = 80.0                     # the first macro step ends after a long set-up (compilation)
    p.update(_step(1, 101))
    assert p.remaining_s is None         # no pace known yet
    clock.now = 81.0                     # then 10 steps a second
    p.update(_step(11, 101))
    assert p.fraction == pytest.approx(11 / 101)
    assert p.remaining_s == pytest.approx(9.0)     # 90 steps at 0.1 s, not ~700 s from 80 s / 11 steps


def test_a_run_until_steady_progresses_toward_the_tolerance_and_ends_at_100_percent():
    p = RunProgress(until_steady=True, clock=_Clock())
    assert p.update(_step(10, 1000)) == pytest.approx(0.01)          # the cap's share before any change
    # a change falling geometrically from 10 % toward 0.1 %: halfway on the log scale at 1 %
    assert p.update(_step(20, 1000, {"tmm": 0.1}, 1e-3)) == pytest.approx(0.02)
    assert p.update(_step(30, 1000, {"tmm": 0.01}, 1e-3)) == pytest.approx(0.5)
    assert p.remaining_s is None                                       # unknown, never invented
    # the slowest engine decides; the bar never goes back
    assert p.update(_step(40, 1000, {"tmm": 0.001, "exudyn": 0.5}, 1e-3)) == pytest.approx(0.5)
    p.close(completed=True)              # stopped before settling (e.g. at the cap): the run has ended
    assert p.fraction == 1.0


def test_toward_steady_is_one_once_every_engine_is_below_the_tolerance():
    assert toward_steady({"a": 4e-3, "b": 1e-3}, {"a": 0.3, "b": 0.2}, 5e-3) == 1.0
    assert toward_steady({}, {}, 5e-3) == 0.0


def test_a_cold_kernel_cache_is_detected_and_any_compiled_source_keys_it(tmp_path, monkeypatch):
    """The compiled layer's cache folder is keyed by all its sources: an edit of a helper file
    (numba checks only the defining file, so it loaded stale kernels) makes the cache cold."""
    pytest.importorskip("numba")
    import shutil

    from tmm_core.compiled import cache as kernel_cache
    sources = tmp_path / "src"
    sources.mkdir()
    for name in kernel_cache.COMPILED_SOURCES:
        (sources / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(kernel_cache.ROOT / name, sources / name)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    assert cache_is_cold(sources)
    index = kernel_cache.cache_dir(sources) / "src_0123" / "march.march-1.py311.nbi"
    index.parent.mkdir(parents=True)
    index.write_bytes(b"index")
    assert not cache_is_cold(sources)
    old = kernel_cache.cache_dir(sources)
    with open(sources / "compiled" / "dense.py", "a", encoding="utf-8") as fh:
        fh.write("\n# an edit\n")
    assert cache_is_cold(sources) and kernel_cache.cache_dir(sources) != old
    kernel_cache.cache_dir(sources).mkdir()
    kernel_cache.remove_stale(kernel_cache.cache_dir(sources))
    assert not old.exists() and kernel_cache.cache_dir(sources).exists()


def test_numba_caches_the_kernels_in_the_keyed_folder():
    numba = pytest.importorskip("numba")
    from tmm_core.compiled import cache as kernel_cache
    assert kernel_cache.numba_module() is numba
    assert numba.config.CACHE_DIR == str(kernel_cache.cache_dir())


def test_the_kernels_compile_from_the_keyed_sources_only():
    """Every module of ``tmm_core/compiled`` but the Python drivers is a keyed source, and the
    keyed sources import nothing else of tmm_core at module level but keyed sources, the errors,
    the cache's own module and the helper processes' (whose code numba does not compile)."""
    import ast

    from tmm_core.compiled import cache as kernel_cache
    names = set(kernel_cache.COMPILED_SOURCES)
    drivers = {"compiled/__init__.py", "compiled/__main__.py", "compiled/ahead.py", "compiled/cache.py",
               "compiled/statics.py"}
    found = {p.relative_to(kernel_cache.ROOT).as_posix() for p in kernel_cache.HERE.glob("*.py")}
    assert found - drivers <= names
    for name in names:
        tree = ast.parse((kernel_cache.ROOT / name).read_text(encoding="utf-8"))
        inside = name.startswith("compiled/")
        for node in tree.body:
            if isinstance(node, ast.ImportFrom) and node.level >= 1:
                package = ("compiled/" if inside and node.level == 1 else "")
                targets = [node.module] if node.module else [a.name for a in node.names]
                for target in targets:
                    allowed = f"{package}{target}.py" in names or target in ("errors", "cache", "ahead")
                    assert allowed, (name, node.level, target)


# -- post-run analyses are bounded in time (issue 31 f) ----------------------------------------
def test_the_natural_frequency_map_is_thinned_to_its_time_bound_over_the_whole_revolution(monkeypatch, caplog):
    import time

    import tmm_core.frequencies
    from cosim import resonance

    def slow(mech, angles, n_modes, f_max_Hz, rtol=1e-10):    # 50 ms per crank angle, frequencies known
        time.sleep(0.05)
        return [[80.0 + math.cos(angles[0]), 114.0][:n_modes]]
    monkeypatch.setattr(tmm_core.frequencies, "fourbar_frequencies", slow)
    sc = load("crank_rocker_373rpm")
    logger = logging.getLogger("cosim")       # the CLI's set-up stops it propagating to the root
    logger.addHandler(caplog.handler)
    try:
        fmap = resonance.frequency_map(sc, n_angles=36, n_modes=2, max_seconds=0.2)
    finally:
        logger.removeHandler(caplog.handler)
    n = len(fmap["angle_rad"])
    assert fmap["capped"] and 1 <= n <= 4 and fmap["f_Hz"].shape == (n, 2)
    assert fmap["angle_rad"][0] == sc.drive.start_angle_rad
    if n > 1:                                         # still spread evenly over the revolution
        assert fmap["angle_rad"][1] - fmap["angle_rad"][0] == pytest.approx(2 * math.pi / n)
    assert f"{n} of 36 crank angles" in caplog.text
    whole = resonance.frequency_map(sc, n_angles=3, n_modes=2, max_seconds=None)
    assert not whole["capped"] and len(whole["angle_rad"]) == 3


# -- the stopping rule's tolerance (issue 31 d) ------------------------------------------------
@pytest.mark.parametrize("value", ["0 %", "-0.1 %", "100 %", "150 %", "0.5 in"])
def test_a_steady_tolerance_outside_0_to_100_percent_is_refused_naming_file_key_and_value(value):
    from cosim.scenario import ScenarioError
    with pytest.raises(ScenarioError) as err:
        load("crank_rocker_373rpm").with_overrides({"output.steady_tolerance": value})
    text = str(err.value)
    assert "crank_rocker_373rpm.toml" in text and "key 'output.steady_tolerance'" in text and repr(value) in text


def test_a_tightened_tolerance_is_what_stops_the_run():
    sc = load("crank_rocker_373rpm").with_overrides({"output.steady_tolerance": "0.1 %"})
    assert sc.output.steady_tolerance == pytest.approx(1e-3)
    res = CoSimulation(sc, ("tmm",), mode="prescribed").run(until_steady=True)
    assert res.stop == "steady" and run_change(res["tmm"].run) < 1e-3
