"""The experiment that isolated why the transfer-matrix model and exudyn disagreed near buckling.

FE crank-rocker (rigid crank) at 373 rpm, where the rocker carries about 65 % of its Euler load:
the transfer-matrix model is run with each physical term switched on or off, and every variant is
compared with exudyn's geometrically exact model of the same scenario at steady state. The
terms:

* axial force in the bending equations: the quasi-static (rigid-body) estimate of each crank
  position (``quasi_static``), or the step's own axial force (``dynamic`` with 'axial_force');
* the axial shortening from bending (``dynamic`` with 'shortening');
* the rotating-frame terms of the elastic motion (Coriolis, centrifugal, angular acceleration).

Result (docs/validation.md, "Engines that agree"): neither the step's own axial force nor the shortening
alone closes the gap; both together leave 2-4 %, and the rotating-frame terms the rest.

Writes ``table.csv`` and ``summary.json`` to ``logs/engines_agree_experiment-<timestamp>/``.

    python -m scenarios.engines_agree_experiment [--segments 16] [--step-deg 0.25] [--rpm 373]
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

from cosim.engines import make_engine
from cosim.master import run_prescribed
from tmm_core.revolution import last_revolution
from cosim.runlog import run_folder, write_csv, write_json
from cosim.scenario import load
from tmm_core import Coupling, CrankMotion, TimeDomain

VARIANTS = (
    ("quasi-static axial force (the earlier default)", "quasi_static", (), Coupling()),
    ("quasi-static axial force + rotating-frame terms", "quasi_static", (), Coupling.all()),
    ("step's own axial force only + rotating-frame terms", "dynamic", ("axial_force",), Coupling.all()),
    ("shortening from bending only + rotating-frame terms", "dynamic", ("shortening",), Coupling.all()),
    ("own axial force + shortening, no rotating-frame terms", "dynamic", ("shortening", "axial_force"), Coupling()),
    ("own axial force + shortening + rotating-frame terms (second order)", "dynamic", ("shortening", "axial_force"),
     Coupling.all()),
)


def _peaks(t, angle, gauges):
    m = last_revolution(angle)
    return {g: (float(b[m].max() * 1e6), float(b[m].min() * 1e6)) for g, (b, _) in gauges.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rpm", type=float, default=373.0, help="crank speed [rpm]")
    ap.add_argument("--segments", type=int, default=16, help="TMM segments per link")
    ap.add_argument("--step-deg", type=float, default=0.25, help="TMM crank-angle step [deg]")
    ap.add_argument("--elements", type=int, default=16, help="exudyn elements per link")
    ap.add_argument("--exudyn-step-deg", type=float, default=0.1, help="exudyn crank-angle step [deg]")
    ap.add_argument("--out", type=Path, default=None, help="output folder")
    args = ap.parse_args(argv)
    sc = load("crank_rocker_373rpm")
    speed = args.rpm * np.pi / 30
    sc = dataclasses.replace(sc, drive=dataclasses.replace(sc.drive, speed_rad_s=speed),
                             exudyn=dataclasses.replace(sc.exudyn, elements=args.elements,
                                                        step_s=np.radians(args.exudyn_step_deg) / speed))
    folder = run_folder("engines_agree_experiment", args.out)
    exu = run_prescribed(make_engine("exudyn"), sc)
    reference = _peaks(exu.t, exu.crank_angle, exu.gauges)
    mech = dataclasses.replace(sc.mechanism, **{l.name: dataclasses.replace(l, n_segments=args.segments)
                                                for l in sc.mechanism.links()})
    rows = [{"model": f"exudyn ({args.elements} elements, {args.exudyn_step_deg} deg)",
             **{f"{g}_{k}_ue": v for g, p in reference.items() for k, v in zip(("max", "min"), p)}}]
    for label, axial, terms, coupling in VARIANTS:
        td = TimeDomain(mech, integrator=sc.tmm.integrator, coupling=coupling, gravity=sc.gravity, gauges=sc.gauges,
                        axial_force=axial, **({"dynamic_terms": terms} if axial == "dynamic" else {}))
        r = td.run(CrankMotion.constant_speed(speed, step_deg=args.step_deg, revolutions=40), start="quasi_static",
                   steady_tol=sc.output.steady_tolerance, record_displacements=False)
        peaks = _peaks(r.t, r.crank_angle, r.gauges)
        row = {"model": label, "steady": r.steady}
        for g, (hi, lo) in peaks.items():
            ref_hi, ref_lo = reference[g]
            row.update({f"{g}_max_ue": hi, f"{g}_min_ue": lo, f"{g}_max_error": hi / ref_hi - 1,
                        f"{g}_min_error": lo / ref_lo - 1})
        rows.append(row)
        print(f"{label:62s} " + "  ".join(f"{g} {row[f'{g}_max_ue']:7.0f} ({100 * row[f'{g}_max_error']:+5.1f} %) "
                                          f"{row[f'{g}_min_ue']:7.0f} ({100 * row[f'{g}_min_error']:+5.1f} %)"
                                          for g in peaks), flush=True)
        write_csv(folder / "table.csv", rows)
    write_json(folder / "summary.json", {"rpm": args.rpm, "tmm": {"segments": args.segments, "step_deg": args.step_deg},
                                         "exudyn": {"elements": args.elements, "step_deg": args.exudyn_step_deg},
                                         "rows": rows})
    print(f"exudyn: " + "  ".join(f"{g} {hi:.0f} / {lo:.0f}" for g, (hi, lo) in reference.items()) + " [microstrain]")
    print(f"written to {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
