"""Regenerate the pinned natural frequencies of tests/test_frequencies.py with an independent
engine: exudyn's constrained eigenvalue analysis (``cosim.engines.exudyn.natural_frequencies``:
planar ANCF cable elements, the crank held at its angle, undamped, at rest) of the same rigs
(``scenarios.rigs``), at the scenario's exudyn mesh and at twice it (a convergence check).

* ``fe_rig``: the FE thesis's rig with a strip crank, no lumped masses, first three modes at
  the crank angles of ``FE_RIG_ANGLES_DEG`` (pinned from a finite-element model with one quintic
  element per link);
* ``fe_rig_bearings``: the same with 0.13128 lbf at each coupler end, crank angle 0;
* ``wang_steel``, ``wang_composite``: Wang's linkages' first mode at ``WANG_ANGLES_DEG``. exudyn
  refuses mass-proportional damping and viscoelastic links, so both are taken out: undamped
  frequencies do not depend on damping, and the transfer-matrix search uses the elastic modulus
  (the composite's instantaneous one, set to each pinned modulus here);
* ``alexander_lawrence``: the range of the coupler's first mode over a revolution (every 45 deg)
  against the test's bounds.

Not part of the test run (exudyn is a reference engine); about half a minute for all::

    python -m tests.benchmarks.frequency_references
    python -m tests.benchmarks.frequency_references --only wang_steel --json logs/frequencies.json
"""
from __future__ import annotations

import sys

import numpy as np

from scenarios.rigs import alexander_lawrence_scenario, fe_crank_rocker_scenario, wang_composite_scenario, \
    wang_steel_scenario
from tests.benchmarks.pinned_references import pinned, selection, write_json
from tests.test_frequencies import FE_RIG_ANGLES_DEG, WANG_ANGLES_DEG

TESTS = "tests.test_frequencies"
#: ``--only`` name -> (test module, module-level constant) that it regenerates.
PINNED = {"fe_rig": (TESTS, "FE_RIG_BARE_HZ"), "fe_rig_bearings": (TESTS, "FE_RIG_BEARINGS_HZ"),
          "wang_steel": (TESTS, "WANG_STEEL_FIRST_HZ"), "wang_composite": (TESTS, "WANG_COMPOSITE_FIRST_HZ"),
          "alexander_lawrence": (TESTS, "AL_FIRST_MODE_BOUNDS_HZ")}
PSI = 6894.757293168361            # Pa


def exudyn_frequencies(scenario, angles_deg, n_modes: int, refine: int = 1) -> np.ndarray:
    """exudyn's first ``n_modes`` natural frequencies [Hz] of ``scenario`` at each crank angle
    [deg], with ``refine`` times the scenario's elements per span; shape (angles, n_modes)."""
    from cosim.engines.exudyn import natural_frequencies
    sc = scenario.with_overrides({"solver.exudyn.elements": refine * scenario.exudyn.elements})
    return np.array([natural_frequencies(sc, np.radians(a), n_modes) for a in angles_deg])


def converged(scenario, angles_deg, n_modes: int) -> dict:
    """Frequencies [Hz] at the scenario's exudyn mesh and at twice it, and their largest relative
    change."""
    f1, f2 = exudyn_frequencies(scenario, angles_deg, n_modes), exudyn_frequencies(scenario, angles_deg, n_modes, 2)
    return {"angles_deg": [float(a) for a in angles_deg], "Hz": f2.tolist(),
            "mesh_change": float(np.max(np.abs(f2 / f1 - 1)))}


def fe_rig(angles_deg, bearings: bool) -> dict:
    """The FE rig with a strip crank (the strip's modulus), with the scenario's bearing weight at
    each coupler end or none: first three frequencies [Hz] at each crank angle [deg]."""
    sc = fe_crank_rocker_scenario(crank_stiffness_factor=1.0) if bearings else \
        fe_crank_rocker_scenario(bearing_lbf=0.0, crank_stiffness_factor=1.0)
    return converged(sc, angles_deg, 3)


def wang_steel(angles_deg) -> dict:
    """Wang's steel linkage (depth 0.062 in), damping removed: first frequency [Hz] per angle [deg]."""
    sc = wang_steel_scenario().with_overrides({"links.coupler.damping": None, "links.rocker.damping": None})
    return converged(sc, angles_deg, 1)


def wang_composite(E_psi: float, angles_deg) -> dict:
    """Wang's composite linkage as elastic with modulus ``E_psi`` [psi]: first frequency [Hz] per
    crank angle [deg]."""
    sc = wang_composite_scenario().with_overrides({"materials.composite.viscoelastic": None,
                                                   "materials.composite.E": f"{E_psi * PSI} Pa"})
    return converged(sc, angles_deg, 1)


def alexander_lawrence() -> dict:
    """Alexander-Lawrence (Shin's flexible crank, no damping): the first mode [Hz] every 45 deg."""
    return converged(alexander_lawrence_scenario(), np.arange(0.0, 360.0, 45.0), 1)


def _show(name: str, result: dict, pinned_value) -> None:
    """Print the regenerated frequencies beside the pinned ones (or bounds) and their difference."""
    f = np.asarray(result["Hz"])
    if name == "alexander_lawrence":
        gap = f"range {f.min():.2f}-{f.max():.2f} Hz"
    else:
        gap = f"largest difference {100 * np.max(np.abs(np.asarray(pinned_value) / f - 1)):.2f} %"
    print(f"{name}: exudyn {np.round(f, 2).tolist()} Hz at {result['angles_deg']} deg (mesh x2 changes it by "
          f"{result['mesh_change']:.1e}); pinned {pinned_value}; {gap}", flush=True)


def main(argv=None) -> dict:
    args, wanted = selection(argv, PINNED, "python -m tests.benchmarks.frequency_references", __doc__)
    jobs = {"fe_rig": lambda: fe_rig(FE_RIG_ANGLES_DEG, False), "fe_rig_bearings": lambda: fe_rig([0.0], True),
            "wang_steel": lambda: wang_steel(WANG_ANGLES_DEG), "alexander_lawrence": alexander_lawrence}
    out = {}
    for name, job in jobs.items():
        if wanted(name):
            out[name] = job()
            _show(name, out[name], pinned(PINNED, name))
    if wanted("wang_composite"):
        for E, expected in pinned(PINNED, "wang_composite").items():
            key = f"wang_composite_E{E:.4g}psi"
            out[key] = wang_composite(E, WANG_ANGLES_DEG)
            _show(key, out[key], expected)
    write_json(args.json, out)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
