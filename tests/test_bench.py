"""The side-by-side benchmark (issues 10, 15): it runs (tiny settings; its JSON's structure and
finite values are checked, timings never), its grids sit around the scenarios' defaults, engines
are compared with exudyn's converged answer, and its matched-accuracy search picks the known
cheapest setting of a fake engine."""
import json
import math
import time

import pytest

from tests.benchmarks import bench_table, bench_timing
from tests.benchmarks.bench import cheapest_setting, main
from tests.benchmarks.bench_accuracy import grid_for, vs_exudyn
from tests.benchmarks.bench_timing import CapExceeded, fresh


def test_matched_accuracy_search_picks_the_known_cheapest_setting():
    """A fake engine with error 2 h (first order) and cost 1/h: within 1.2 % of the converged
    answer the cheapest admissible step is the largest h with 2 h <= 0.012, i.e. 0.005."""
    steps = [0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125]
    results = [{"setting": {"h": h}, "metrics": {"g": 1.0 + 2 * h, "f": 5.0 * (1 - h)}, "cost": 1.0 / h} for h in steps]
    reference = {"setting": {"h": 0.0}, "metrics": {"g": 1.0, "f": 5.0}, "cost": 0.0}
    best, errors = cheapest_setting(results, reference, tol=0.012)
    assert best["setting"] == {"h": 0.005}
    assert errors == pytest.approx([2 * h for h in steps])
    none, _ = cheapest_setting(results[:2], reference, tol=0.012)
    assert none is None
    # The cheapest accurate setting marked unsteady (infinite cost) gives way to the next one.
    results[3]["cost"] = float("inf")
    best, _ = cheapest_setting(results, reference, tol=0.012)
    assert best["setting"] == {"h": 0.0025}


def test_a_coarse_setting_that_lands_close_by_chance_is_not_chosen():
    """Two parameters (segments n, step h), error 1/n^2 + 2 h, except that the coarsest step happens
    to land on the answer at n = 4. Within 1 %: n = 16 (error 0.4 %) needs h <= 0.003, so the
    cheapest converged setting is (16, 0.0025); (4, 0.04) is exact but its finer neighbours are not."""
    results = []
    for n in (4, 8, 16):
        for h in (0.04, 0.01, 0.0025):
            err = 0.0 if (n, h) == (4, 0.04) else 1.0 / n ** 2 + 2 * h
            results.append({"setting": {"segments": n, "step": f"{h} s"}, "metrics": {"g": 1.0 + err},
                            "cost": n / h})
    reference = {"setting": {"segments": 64, "step": "0.0001 s"}, "metrics": {"g": 1.0}, "cost": 0.0}
    best, _ = cheapest_setting(results, reference, tol=0.01)
    assert best["setting"] == {"segments": 16, "step": "0.0025 s"}


def _finite_numbers(x, path="") -> list:
    """Paths of the non-finite numbers in a JSON structure (empty when all are finite)."""
    if isinstance(x, dict):
        return [p for k, v in x.items() for p in _finite_numbers(v, f"{path}.{k}")]
    if isinstance(x, list):
        return [p for i, v in enumerate(x) for p in _finite_numbers(v, f"{path}[{i}]")]
    if isinstance(x, float) and not math.isfinite(x):
        return [path]
    return []


def test_benchmark_runs_on_a_tiny_setting(tmp_path):
    out = tmp_path / "bench.json"
    main(["--tiny", "--rigs", "alexander_lawrence_400rpm", "--out", str(out)])
    data = json.loads(out.read_text())
    assert data["status"] == "completed"
    block = data["rigs"]["alexander_lawrence_400rpm"]
    for engine in ("tmm", "exudyn", "mujoco"):
        assert block[engine]["reference"]["metrics"]
        chosen = block[engine]["chosen"]
        assert chosen["setting"] and chosen["metrics"]
        for key in ("error_vs_reference", "first_call_s", "setup_s", "march_per_sim_s", "wall_per_sim_s",
                    "peak_memory_MB"):
            # Non-finite values are stored as null: a number here is a finite one.
            assert isinstance(chosen[key], (int, float)), (engine, key, chosen[key])
        vs = block["vs_exudyn"][engine]
        assert set(vs["chosen"]) == set(block["exudyn"]["reference"]["metrics"]) and "converged_max" in vs
    assert set(block["ratios_vs_tmm"]) == {"exudyn", "mujoco"}
    assert {"march", "wall"} <= set(block["ratios_vs_tmm"]["exudyn"])
    assert data["quasi_static"]["fe_crank_rocker_241rpm"]["quasi_static_compiled"]["min_s"] > 0
    assert data["floor"][0]["per_step_s"] > 0 and data["floor"][0]["floor_per_step_s"] == [3e-6, 5e-6]
    assert "finished" in data["sweep"] and data["bench_overhead"] and data["tmm_scaling"]["by_segments"]
    # A part that raised is stored as {"error": ...}: the tiny run must not hide one.
    overhead = data["bench_overhead"]
    assert "error" not in overhead, overhead.get("error")
    assert all("streaming_paired_loop_median_fraction" in row for row in overhead.values())
    assert set(data["elapsed_s"]) >= {"engines:alexander_lawrence_400rpm", "quasi_static", "floor", "scaling",
                                      "overhead", "sweep", "total"}
    assert not _finite_numbers(data)      # (the JSON writer stores NaN as null; this guards a raw dump)
    text = bench_table.main([str(out)])
    assert "vs exudyn converged" in text and "first call" in text and "per step [us]" in text


def test_grids_are_built_around_the_scenario_defaults():
    """FE rig: TMM default 8 segments at 0.5 deg, exudyn 16 elements at 0.2 deg (its file's settings);
    the converged answer is the default refined once in every direction."""
    grid, ref = grid_for("crank_rocker_373rpm", "tmm")
    assert {"segments": 8, "step": "0.5 deg"} in grid and ref == {"segments": 16, "step": "0.25 deg"}
    assert ref not in grid and len(grid) == 8 and {"segments": 4, "step": "1 deg"} in grid
    grid, ref = grid_for("crank_rocker_373rpm", "exudyn", quick=True)
    assert grid == [{"elements": 16, "step": "0.2 deg"}, {"elements": 8, "step": "0.2 deg"},
                    {"elements": 16, "step": "0.4 deg"}] and ref == {"elements": 32, "step": "0.1 deg"}
    grid, ref = grid_for("watt_sixbar_600rpm", "mujoco")
    assert grid == [{"step": "0.8 deg"}, {"step": "0.4 deg"}, {"step": "0.2 deg"}] and ref == {"step": "0.1 deg"}


def test_engines_are_compared_with_exudyns_converged_answer():
    block = {"exudyn": {"reference": {"metrics": {"a": 100.0, "b": 50.0}, "steady": True},
                        "chosen": {"metrics": {"a": 101.0, "b": 50.0}}},
             "tmm": {"reference": {"metrics": {"a": 98.0, "b": 55.0}}, "chosen": {"metrics": {"a": 97.0, "b": 55.0}}},
             "mujoco": {"reference": {"metrics": {"a": 50.0, "b": 25.0}}, "chosen": None}}
    vs = vs_exudyn(block)
    assert vs["tmm"]["chosen"] == pytest.approx({"a": -0.03, "b": 0.1})
    assert vs["tmm"]["chosen_max"] == pytest.approx(0.1)
    assert vs["exudyn"]["converged_max"] == 0.0 and vs["exudyn"]["chosen_max"] == pytest.approx(0.01)
    assert "chosen" not in vs["mujoco"] and vs["mujoco"]["converged_max"] == pytest.approx(0.5)


def test_a_process_past_its_cap_is_stopped(monkeypatch):
    monkeypatch.setattr(bench_timing, "FRESH", True)      # a --tiny run in this process turns it off
    with pytest.raises(CapExceeded, match="not finished in 1 s"):
        fresh(time.sleep, 30, cap_s=1.0)


@pytest.mark.parametrize("argv, field", [(["--rigs", "nope"], "--rigs"), (["--engines", "ansys"], "--engines"),
                                         (["--tol", "0"], "--tol")])
def test_bad_arguments_are_refused_naming_the_field(argv, field, capsys):
    with pytest.raises(SystemExit):
        main(argv)
    assert field in capsys.readouterr().err
