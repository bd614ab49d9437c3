"""Regenerate the pinned numbers of tests/test_shipped_scenarios.py from their independent
references (issue 36: every pinned number has a script that regenerates it).

* ``EXUDYN_REFINED``: exudyn's steady +/- bending peak over the last revolution, at twice the
  scenario's elements and half its step (an independent, geometrically exact engine, refined),
  run until steady; except the light-damping variants (``FROM_REST_REVOLUTIONS``), pinned to
  exudyn at the scenario's own setting run from rest for a fixed number of revolutions
  (docs/light_damping.md's exudyn references): a run stopped by the 0.5 % steady tolerance ends
  before its peaks settle at 1 %, and at 0.5 % the refined run stays in the large irregular
  response that coexists with the steady one;
* ``TMM_REFINED`` (Wang's rigs, which exudyn cannot carry): the transfer-matrix model at twice the
  segments and a quarter of the step, a convergence study;
* the weak drive's speed fluctuation: the rigid linkage and the motor as one ODE
  (tests/monolithic.py, scipy DOP853), per revolution;
* the flexible-crank variant's first natural frequency at crank angle 0, from exudyn's
  constrained eigenvalue analysis.

Not part of the test run: on 2026-11-28 the refined exudyn runs took 5-45 s each, the
light-damping variants 50 and 105 s, Wang's refined TMM runs 90 s together (about 7 minutes for
all; a loaded machine takes several times longer). Each result is printed beside the number
pinned now, so a change of engine version or scenario shows at once::

    python -m tests.benchmarks.pinned_references                       # everything
    python -m tests.benchmarks.pinned_references --only crank_rocker_95rpm,flexible_crank
    python -m tests.benchmarks.pinned_references --only tmm_refined    # one table
    python -m tests.benchmarks.pinned_references --json logs/pinned.json

``PINNED`` names the test constant each ``--only`` name regenerates (a table's name also selects
all its scenarios); the sibling scripts (frequency_references, kinematics_references,
elastica_references) follow the same form, and tests/test_pinned_references.py checks that every
constant they name exists.
"""
from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path

import numpy as np

from tests.benchmarks.bench_accuracy import default_setting, scaled, scenario_for

WEAK_DRIVE, FLEXIBLE_CRANK = "crank_rocker_373rpm_weak_drive", "crank_rocker_373rpm_flexible_crank"
#: Light-damping variants pinned to exudyn at the scenario's own setting, from rest, after this
#: many revolutions (where its last two revolutions agree to 1e-8 and 2e-6).
FROM_REST_REVOLUTIONS = {"crank_rocker_373rpm_damping_1pct": 30, "crank_rocker_373rpm_damping_0p5pct": 50}
SHIPPED = "tests.test_shipped_scenarios"
#: ``--only`` name -> (test module, module-level constant) that it regenerates.
PINNED = {"exudyn_refined": (SHIPPED, "EXUDYN_REFINED"), "tmm_refined": (SHIPPED, "TMM_REFINED"),
          "weak_drive": (SHIPPED, "WEAK_DRIVE_FLUCTUATION"), "flexible_crank": (SHIPPED, "FLEXIBLE_CRANK_FIRST_HZ")}


def pinned(registry: dict, name: str):
    """The pinned value (a test module's constant) that ``registry[name]`` names."""
    module, constant = registry[name]
    return getattr(importlib.import_module(module), constant)


def selection(argv, registry: dict, prog: str, doc: str):
    """Parsed ``--only`` / ``--json`` arguments and a predicate: is a name wanted?"""
    ap = argparse.ArgumentParser(prog=prog, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", default="", help=f"comma-separated names: {', '.join(registry)}")
    ap.add_argument("--json", type=Path, help="also write the results to this file")
    args = ap.parse_args(argv)
    only = set(filter(None, args.only.split(",")))
    return args, (lambda *names: not only or bool(only & set(names)))


def write_json(path: Path | None, out: dict) -> None:
    """Write the results to ``path`` (if given), creating its folder."""
    if path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(out, indent=1, default=float))


def _peaks(engine: str, sc, gauge: str, revolutions=None) -> dict:
    """``engine``'s +/- bending peak [microstrain] of ``gauge`` over the last revolution of a
    prescribed-speed run of ``sc``, run until steady (or for ``revolutions``)."""
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    from cosim.metrics import run_change
    from tmm_core.revolution import last_revolution
    run = run_prescribed(make_engine(engine), sc, revolutions=revolutions)
    bending = run.gauges[gauge][0][last_revolution(run.crank_angle)] * 1e6
    change = float(run_change(run))
    return {"plus": float(bending.max()), "minus": float(bending.min()),
            "revolution_change": change, "steady": change < sc.output.steady_tolerance}


def refined_peaks(name: str, engine: str, gauge: str, count: float, step: float) -> dict:
    """``engine``'s steady +/- bending peak [microstrain] of ``gauge`` at the scenario's setting
    with its count times ``count`` and its step times ``step`` (the macro step equal to it), run
    until steady."""
    setting = scaled(default_setting(name, engine), count=count, step=step)
    return {"setting": setting, **_peaks(engine, scenario_for(name, engine, setting), gauge)}


def shipped_from_rest_peaks(name: str, gauge: str, revolutions: int) -> dict:
    """exudyn's +/- bending peak [microstrain] of ``gauge`` in the shipped scenario as it is (its
    own mesh, step and macro step), from rest, after ``revolutions``. At 0.5 % damping the macro
    step matters: with the macro step equal to the step (as in ``refined_peaks``) the run ends in
    the coexisting irregular response."""
    from cosim.scenario import load
    return {"setting": f"the scenario's own, {revolutions} revolutions",
            **_peaks("exudyn", load(name), gauge, revolutions)}


def weak_drive_fluctuation(revolutions: int = 6) -> dict:
    """(max - min) / mean of the crank speed in each revolution of the monolithic rigid
    linkage-and-motor ODE, from the scenario's steady start."""
    from cosim.scenario import load
    from tests.monolithic import RigidFourBarWithMotor
    sc = load(WEAK_DRIVE)
    ref = RigidFourBarWithMotor(sc.mechanism, sc.motor).solve(revolutions * sc.revolution_period_s, scenario=sc)
    turned = np.abs(ref["angle"] - ref["angle"][0]) / (2 * math.pi)
    per_revolution = []
    for k in range(revolutions):
        window = (turned >= k) & (turned < k + 1)
        w = ref["speed"][window]
        if w.size:
            per_revolution.append(float((w.max() - w.min()) / w.mean()))
    return {"fluctuation_per_revolution": per_revolution}


def flexible_crank_frequency() -> dict:
    """exudyn's first natural frequency [Hz] of the flexible-crank variant at crank angle 0."""
    from cosim.engines.exudyn import natural_frequencies
    from cosim.scenario import load
    return {"first_frequency_Hz": float(natural_frequencies(load(FLEXIBLE_CRANK), 0.0, 1)[0])}


def main(argv=None) -> dict:
    args, wanted = selection(argv, PINNED, "python -m tests.benchmarks.pinned_references", __doc__)
    out = {}
    for key, engine, count, step in (("exudyn_refined", "exudyn", 2, 0.5), ("tmm_refined", "tmm", 2, 0.25)):
        for name, (gauge, hi, lo, _tol) in pinned(PINNED, key).items():
            if not wanted(key, name):
                continue
            revolutions = FROM_REST_REVOLUTIONS.get(name)
            out[name] = (shipped_from_rest_peaks(name, gauge, revolutions) if revolutions else
                         refined_peaks(name, engine, gauge, count, step))
            print(f"{name} ({engine}, {out[name]['setting']}): {gauge} {out[name]['plus']:+.2f} / "
                  f"{out[name]['minus']:+.2f} microstrain, steady {out[name]['steady']} "
                  f"(pinned {hi:+.2f} / {lo:+.2f})", flush=True)
    if wanted("weak_drive"):
        out["weak_drive"] = weak_drive_fluctuation()
        print(f"{WEAK_DRIVE}: speed fluctuation per revolution "
              f"{', '.join(f'{f:.4f}' for f in out['weak_drive']['fluctuation_per_revolution'])} "
              f"(pinned {pinned(PINNED, 'weak_drive'):.4f})")
    if wanted("flexible_crank"):
        out["flexible_crank"] = flexible_crank_frequency()
        print(f"{FLEXIBLE_CRANK}: first natural frequency at crank angle 0 "
              f"{out['flexible_crank']['first_frequency_Hz']:.2f} Hz (pinned {pinned(PINNED, 'flexible_crank'):.2f})")
    write_json(args.json, out)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
