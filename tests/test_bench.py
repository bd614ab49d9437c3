"""The side-by-side benchmark (issue 10): it runs (tiny settings, timings not checked), and its
matched-accuracy search picks the known cheapest setting of a fake engine."""
import json

import pytest

from tests.benchmarks.bench import cheapest_setting, main


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


def test_benchmark_runs_on_a_tiny_setting(tmp_path):
    out = tmp_path / "bench.json"
    main(["--tiny", "--rigs", "alexander_lawrence_400rpm", "--out", str(out)])
    data = json.loads(out.read_text())
    block = data["rigs"]["alexander_lawrence_400rpm"]
    for engine in ("tmm", "exudyn", "mujoco"):
        assert block[engine]["reference"]["metrics"]
    assert "ratios_vs_tmm" in block
    assert data["bench_overhead"] and data["tmm_scaling"]["by_segments"]


@pytest.mark.parametrize("argv, field", [(["--rigs", "nope"], "--rigs"), (["--engines", "ansys"], "--engines"),
                                         (["--tol", "0"], "--tol")])
def test_bad_arguments_are_refused_naming_the_field(argv, field, capsys):
    with pytest.raises(SystemExit):
        main(argv)
    assert field in capsys.readouterr().err
