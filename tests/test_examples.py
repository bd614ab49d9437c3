"""The examples under examples/ run, and their numbers match independent values: a closed form,
the FE thesis's published frequency and the full model for the reduced one. Also the curated
public API of tmm_core (issue 33): written out by hand, no submodules, the entry points there; and
cosim's scripting names (issue 35), each resolving, with the cosim_api example run against the
command line."""
import importlib.util
import json
import math
import os
import subprocess
import sys
import types
from pathlib import Path

import pytest

import tmm_core

ROOT = Path(__file__).resolve().parent.parent


def _example(name: str):
    spec = importlib.util.spec_from_file_location(name, ROOT / "examples" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_fourbar_api_example_runs_and_agrees_with_independent_values():
    example = _example("fourbar_api")
    out = example.main()
    # Cantilever tip deflection P L^3 / (3 E I): 1 N on 7 in of the 1 x 1/8 in aluminium strip.
    EI = example.ALUMINIUM.E_Pa * (0.0254 * (0.125 * 0.0254) ** 3 / 12)
    assert out["tip_deflection_mm"] == pytest.approx(1e3 * (7 * 0.0254) ** 3 / (3 * EI), rel=1e-9)
    # The thesis's output-link frequency, 79.07 Hz (FE thesis Ch. IX; scenarios/base/fe_crank_rocker.toml).
    assert out["first_frequency_Hz"] == pytest.approx(79.07, rel=0.01)
    # A damped steady orbit, and the reduced model within 2 % of the full one's peak.
    assert out["largest_floquet_multiplier"] < 1.0
    assert out["reduced_rocker_ue"] == pytest.approx(out["periodic_rocker_ue"], rel=0.02)
    assert all(math.isfinite(v) and v > 0 for v in out.values())


def test_the_public_api_is_curated():
    names = tmm_core.__all__
    assert len(names) == len(set(names))
    assert not [n for n in names if isinstance(getattr(tmm_core, n), types.ModuleType)]
    for entry in ("FourBarMechanism", "LinkageMechanism", "Link", "solve_static", "quasi_static", "TimeDomain",
                  "periodic_steady_state", "fourbar_frequencies", "natural_frequencies", "build_basis",
                  "periodic_steady_state_reduced"):
        assert entry in names
    for internal in ("ConfigurationBatch", "StepMaps", "March", "kernels", "OutputLayout"):
        assert internal not in names


def test_the_cosim_api_example_runs_and_agrees_with_the_command_line(tmp_path):
    """examples/cosim_api.py through ``cosim``'s exported names alone; its numbers against the
    command line's run of the same scenario (``cosim run crank_rocker_373rpm --engines tmm``,
    the same peak to round-off) and a closed form (373 rpm = 373 * 2 pi / 60 rad/s)."""
    out = _example("cosim_api").main(tmp_path / "api")
    assert out["status"] == "completed"
    assert out["crank_speed_rad_s"] == pytest.approx(373 * 2 * math.pi / 60, rel=1e-9)     # traces: 10 digits
    assert out["variant_rpm"] == pytest.approx(241, rel=1e-12)
    # traces.csv keeps 7 significant digits of microstrain (cosim.traces), the summary full precision.
    assert out["peak_traces_ue"] == pytest.approx(out["peak_summary_ue"], rel=1e-6)
    cli = tmp_path / "cli"
    subprocess.run([sys.executable, "-m", "cosim", "run", "crank_rocker_373rpm", "--engines", "tmm", "--no-record",
                    "-q", "--out", str(cli)], cwd=tmp_path, check=True, capture_output=True,
                   env={**os.environ, "PYTHONPATH": str(ROOT)})
    summary = json.loads((cli / "summary.json").read_text())
    # The same run to round-off: BLAS's summation order follows its thread count, which an earlier
    # test in this process may have limited (measured 3e-14 relative between the two).
    assert summary["engines"]["tmm"]["gauges"]["coupler_mid"]["bending_max_ue"] == pytest.approx(
        out["peak_summary_ue"], rel=1e-12)


def test_every_name_cosim_exports_resolves():
    """``cosim.__all__`` is written out by hand; every name in it resolves (imported on first use),
    none is a module, and ``import cosim`` alone imports none of the heavy parts."""
    import cosim
    names = cosim.__all__
    assert len(names) == len(set(names))
    for name in names:
        assert not isinstance(getattr(cosim, name), types.ModuleType), name
    for entry in ("load", "run", "sweep", "CoSimulation", "make_engine", "load_run"):
        assert callable(getattr(cosim, entry)), entry
    code = "import sys, cosim; print(sorted(m for m in ('pandas', 'tmm_core', 'pint') if m in sys.modules))"
    light = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert light.stdout.strip() == "[]"
