"""A first run on a cold kernel cache (cosim.kernel_warmup): the transfer-matrix engine runs in
numpy while a second process compiles the kernels, the run waits for it at the end, and the
numpy run's results are the compiled run's."""
from __future__ import annotations

import json

import pytest

import cosim.kernel_warmup as warmup_module
import cosim.runs as runs_module
from cosim.kernel_warmup import KernelWarmup, first_run_in_numpy
from cosim.runs import RunOptions, run_scenario
from cosim.scenario import load

pytest.importorskip("numba")


def test_a_short_run_on_a_cold_cache_runs_in_numpy_and_a_long_one_compiles_first(monkeypatch):
    """The rule: numba installed, its cache cold, and the numpy path's estimate for the run's
    planned length within the compilation's estimate (50 s). The FE rig at 373 rpm has 720 steps a
    revolution at 1.5 ms each in numpy: 1 revolution is about 1 s, 1000 are about 18 min."""
    sc = load("crank_rocker_373rpm")
    one = sc.revolution_period_s
    monkeypatch.setattr(warmup_module, "cache_is_cold", lambda: True)
    assert first_run_in_numpy(sc, {"tmm": None, "exudyn": None}, one)
    assert not first_run_in_numpy(sc, {"tmm": None}, 1000 * one)
    assert not first_run_in_numpy(sc, {"exudyn": None, "mujoco": None}, one)      # nothing to compile
    monkeypatch.setattr(warmup_module, "cache_is_cold", lambda: False)
    assert not first_run_in_numpy(sc, {"tmm": None}, one)


def _peaks(folder):
    gauges = json.loads((folder / "summary.json").read_text())["engines"]["tmm"]["gauges"]
    return {(g, k): v for g, d in gauges.items() for k, v in d.items()}


def test_a_first_run_answers_in_numpy_with_the_compiled_runs_results(tmp_path, monkeypatch):
    """The run's transfer-matrix engine runs in numpy, a second process compiles (here it loads
    the kernels this session already compiled), the run waits for it and says so in its notes;
    its gauge peaks are the compiled run's (the two backends are held equal to 1e-12 per step;
    here 1e-9 after a quarter revolution's march)."""
    options = dict(engines=("tmm",), revolutions=0.25, viewer="none", figures=False, progress=False)
    compiled = run_scenario("crank_rocker_95rpm", RunOptions(out=tmp_path / "compiled", **options))
    monkeypatch.setattr(runs_module, "first_run_in_numpy", lambda *args: True)
    first = run_scenario("crank_rocker_95rpm", RunOptions(out=tmp_path / "first", **options))
    assert any("ran in numpy" in n and "compiled beside it" in n for n in first.notes), first.notes
    assert not any("numpy" in n for n in compiled.notes)
    a, b = _peaks(tmp_path / "compiled"), _peaks(tmp_path / "first")
    assert a.keys() == b.keys() and a
    for key in a:
        assert b[key] == pytest.approx(a[key], rel=1e-9, abs=1e-9), key


def test_a_compilation_that_fails_or_is_stopped_is_said_and_leaves_no_process(tmp_path):
    failing = KernelWarmup.start(tmp_path / "missing.toml")
    note = failing.finish()
    assert "failed" in note and "missing.toml" in note, note
    assert failing.process.returncode != 0
    (tmp_path / "bad.toml").write_text("[input]\n")
    stopped = KernelWarmup.start(tmp_path / "bad.toml")
    stopped.stop()
    assert stopped.process.returncode is not None                 # ended, not left running


def test_a_sweep_on_a_cold_cache_says_it_compiles_and_how_long(tmp_path, monkeypatch, caplog):
    """A sweep compiles the periodic solver's kernels too (82 s measured on an empty cache for a
    2-point sweep, against 50 s for a run): it says so before its points, with that estimate."""
    import logging

    import cosim.run_progress as progress_module
    from cosim.sweeps import run_sweep
    from tmm_core.compiled.cache import PERIODIC_COMPILE_ESTIMATE_S
    monkeypatch.setattr(progress_module, "cache_is_cold", lambda: True)
    with caplog.at_level(logging.INFO, logger="cosim.run_progress"):
        run_sweep("crank_rocker_95rpm", [95.0], workers=1, out=tmp_path / "s", progress=False, record=False,
                  resonance=False)
    said = [r.getMessage() for r in caplog.records if "compiling the transfer-matrix kernels" in r.getMessage()]
    assert said and f"about {PERIODIC_COMPILE_ESTIMATE_S:.0f} s" in said[0], said


def test_a_run_folders_resolved_scenario_loads_as_the_scenario_it_ran(tmp_path):
    """``scenario.resolved.toml`` (what the kernels' warm-up reads, and what a user reruns) loads
    as the scenario the run ran, a typed override included; it was refused before ('assumptions':
    unknown key)."""
    import tomli_w

    from cosim.scenario import resolved
    variant = load("crank_rocker_95rpm").with_overrides({"drive.speed": "120 rpm"})
    path = tmp_path / "scenario.resolved.toml"
    path.write_text(tomli_w.dumps(resolved(variant)), encoding="utf-8")
    again = load(path)
    assert again.name == variant.name and again.drive.speed_rpm == pytest.approx(120.0)
    assert [link.length_m for link in again.mechanism.links()] == [link.length_m for link in variant.mechanism.links()]
    assert again.gauges == variant.gauges


def test_the_warm_up_yields_the_cores_to_the_run_beside_it(monkeypatch):
    """The warm-up lowers its scheduling priority before it compiles (its helper processes inherit
    it): the run's own engines come first (a first run's table at 3.5-4.1 s instead of 6.9-7.5 s,
    its end unchanged at about 19-20 s)."""
    calls = []
    monkeypatch.setattr(warmup_module.os, "nice", lambda increment: calls.append(("nice", increment)))
    monkeypatch.setattr(warmup_module, "run_prescribed", lambda *args, **kwargs: calls.append(("run",)))
    monkeypatch.setattr(warmup_module, "make_engine", lambda *args, **kwargs: None)
    monkeypatch.setattr(warmup_module, "load", lambda path: None)
    assert warmup_module.main(["scenario.toml"]) == 0
    assert calls == [("nice", warmup_module.WARMUP_NICENESS), ("run",)] and warmup_module.WARMUP_NICENESS > 0
