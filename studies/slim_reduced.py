"""Issue 37, item 5, the gate: the reduced model with one axial coordinate per link
(``ReducedOptions(axial="link")``, a numpy prototype) against today's reduced model (one per
segment, r = 23 on the FE rig) and the full transfer-matrix model at 0.25 deg.

Gate (issue 37): the slim model's peaks within 0.5 % of today's reduced model and within 1 % of the
full TMM at 241, 300, 373 and 400 rpm on the FE rig, and on Alexander-Lawrence and the six-bar
(here at their shipped speeds); the same stability verdicts at 405-455 rpm on the FE rig.

Each case is a periodic steady state (Newton shooting) of a shipped scenario at a prescribed
speed, made with ``Scenario.with_overrides`` and :func:`cosim.overrides.prescribed_speed`:

* ``full``: :func:`tmm_core.periodic.periodic_steady_state` at 0.25 deg (1440 steps a revolution);
* ``segment``: :func:`tmm_core.reduced_periodic.periodic_steady_state_reduced`, shipped options;
* ``link``: the same with ``axial="link"``, numpy backend (no compiled revolution yet).

    python -m studies.slim_reduced run [--cases crank_rocker_373rpm:241,...]   # writes studies/slim_reduced.json
    python -m studies.slim_reduced table                                     # the markdown tables

Peak errors are relative to the reference peak of the same gauge, quantity and sign; the axial
peaks (about 100 microstrain on the FE rig) are listed apart from the bending ones.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from cosim.overrides import prescribed_speed
from cosim.scenario import load
from tmm_core.periodic import periodic_steady_state
from tmm_core.reduced import ReducedOptions
from tmm_core.reduced_periodic import periodic_steady_state_reduced

RESULTS = Path(__file__).with_suffix(".json")
FE = "crank_rocker_373rpm"
#: (scenario, rpm or None for the scenario's own speed): the gate's peak cases.
PEAK_CASES = [(FE, 241.0), (FE, 300.0), (FE, 373.0), (FE, 400.0), ("alexander_lawrence_400rpm", None),
              ("watt_sixbar_600rpm", None)]
#: The gate's stability cases (FE rig): the same verdict from every model.
STABILITY_RPM = [405.0, 415.0, 425.0, 435.0, 445.0, 455.0]
MODELS = ("full", "segment", "link")


def scenario(name: str, rpm: float | None):
    sc = load(name)
    return sc if rpm is None else sc.with_overrides(prescribed_speed(rpm))


def solve(sc, model: str):
    """``(result, wall time [s])`` of one periodic steady state of ``sc`` with ``model``."""
    td = sc.time_domain()
    tic = time.perf_counter()
    if model == "full":
        res = periodic_steady_state(td, sc.drive.speed_rad_s, step_s=sc.revolution_period_s / 1440,
                                    start_angle=sc.drive.start_angle_rad)
    else:
        options = ReducedOptions(modes=sc.tmm.modes, axial=model)
        res = periodic_steady_state_reduced(td, sc.drive.speed_rad_s, start_angle=sc.drive.start_angle_rad,
                                            options=options, backend="numpy" if model == "link" else None)
    return res, time.perf_counter() - tic


def summary_of(res, wall: float) -> dict:
    """Peaks [microstrain] per gauge, the largest multiplier's modulus, size and wall time."""
    peaks = {g: {"bending": [float(b.max() * 1e6), float(b.min() * 1e6)],
                 "axial": [float(a.max() * 1e6), float(a.min() * 1e6)]} for g, (b, a) in res.gauges.items()}
    mu = np.asarray(res.multipliers)
    return {"peaks_ue": peaks, "largest_multiplier": float(np.abs(mu[0])) if mu.size else None,
            "size": res.info.get("size"), "wall_s": wall}


def run(cases: list, results: dict) -> None:
    for name, rpm in cases:
        sc = scenario(name, rpm)
        key = f"{name}:{sc.drive.speed_rpm:g}"
        for model in MODELS:
            try:
                res, wall = solve(sc, model)
                results.setdefault(key, {})[model] = summary_of(res, wall)
            except Exception as exc:          # a case without an orbit is a result of the study
                results.setdefault(key, {})[model] = {"error": f"{type(exc).__name__}: {exc}"}
            print(key, model, json.dumps(results[key][model])[:300], flush=True)
            RESULTS.write_text(json.dumps(results, indent=1))


def errors(got: dict, ref: dict, quantity: str) -> list:
    """Relative errors [%] of every peak of ``quantity`` in ``got`` against ``ref``."""
    out = []
    for g, q in ref["peaks_ue"].items():
        for v, r in zip(got["peaks_ue"][g][quantity], q[quantity]):
            out.append(100.0 * (v - r) / abs(r))
    return out


def table(results: dict) -> str:
    lines = ["| case | r: segment / link | link vs segment, bending (worst) | link vs segment, axial (worst) | "
             "link vs full, bending (worst) | link vs full, axial (worst) | segment vs full, bending / axial (worst) | "
             "largest multiplier: full / segment / link | wall [s]: full / segment (compiled) / link (numpy) |",
             "|---|---|---|---|---|---|---|---|---|"]
    worst = lambda xs: max(xs, key=abs) if xs else float("nan")  # noqa: E731
    for key, r in results.items():
        if any("error" in r.get(m, {"error": "missing"}) for m in MODELS):
            lines.append(f"| {key} | " + " | ".join(r.get(m, {}).get("error", "ok") for m in MODELS) + " | | | | | | |")
            continue
        f, s, k = (r[m] for m in MODELS)
        lines.append(f"| {key} | {s['size']} / {k['size']} | {worst(errors(k, s, 'bending')):+.2f} % | "
                     f"{worst(errors(k, s, 'axial')):+.2f} % | {worst(errors(k, f, 'bending')):+.2f} % | "
                     f"{worst(errors(k, f, 'axial')):+.2f} % | {worst(errors(s, f, 'bending')):+.2f} / "
                     f"{worst(errors(s, f, 'axial')):+.2f} % | "
                     f"{f['largest_multiplier']:.3f} / {s['largest_multiplier']:.3f} / {k['largest_multiplier']:.3f} | "
                     f"{f['wall_s']:.2f} / {s['wall_s']:.2f} / {k['wall_s']:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("command", choices=("run", "table"))
    ap.add_argument("--cases", help="scenario:rpm,... (default: the gate's peak and stability cases)")
    args = ap.parse_args(argv)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    if args.command == "run":
        cases = ([(c.split(":")[0], float(c.split(":")[1])) for c in args.cases.split(",")] if args.cases else
                 PEAK_CASES + [(FE, rpm) for rpm in STABILITY_RPM])
        run(cases, results)
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
