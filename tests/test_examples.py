"""The examples under examples/ run, and their numbers match independent values: a closed form,
the FE thesis's published frequency and the full model for the reduced one. Also the curated
public API of tmm_core (issue 33): written out by hand, no submodules, the entry points there."""
import importlib.util
import math
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
