"""Accuracy and cost of the reduced transfer-matrix model against the full one (docs/validation.md, "Reduced
model"): the FE rig's periodic steady state at 241 and 373 rpm (rigid crank, the scenarios'
default settings), the +/- bending peaks of both gauges for several mode counts, and the wall
time of each solve (the reduced one with its basis).

    .venv/bin/python -m scenarios.reduced_accuracy                     # the table (a few minutes)
    .venv/bin/python -m scenarios.reduced_accuracy --modes 2,4 --scenarios crank_rocker_241rpm
    .venv/bin/python -m scenarios.reduced_accuracy --single reduced    # one solve (for /usr/bin/time -v)

Writes ``logs/reduced_accuracy-<timestamp>/accuracy.json`` and ``accuracy.csv``.
"""
from __future__ import annotations

import argparse
import csv
import json
import time


def model_of(sc):
    return sc.time_domain()


def peaks(result) -> dict:
    return {g: (float(b.max() * 1e6), float(b.min() * 1e6)) for g, (b, _) in result.gauges.items()}


def full_solve(sc):
    from tmm_core.periodic import periodic_steady_state
    tic = time.perf_counter()
    p = periodic_steady_state(model_of(sc), sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"),
                              start_angle=sc.drive.start_angle_rad)
    return p, time.perf_counter() - tic


def reduced_solve(sc, modes: int):
    from tmm_core.reduced import ReducedOptions, build_basis
    from tmm_core.reduced_periodic import periodic_steady_state_reduced
    tic = time.perf_counter()
    td = model_of(sc)
    options = ReducedOptions(modes=modes)
    basis = build_basis(td, sc.drive.start_angle_rad, options)
    t_basis = time.perf_counter() - tic
    p = periodic_steady_state_reduced(td, sc.drive.speed_rad_s, start_angle=sc.drive.start_angle_rad,
                                      options=options, basis=basis)
    return p, time.perf_counter() - tic, t_basis


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default="crank_rocker_241rpm,crank_rocker_373rpm")
    ap.add_argument("--modes", default="2,4,6,8,12")
    ap.add_argument("--single", choices=("full", "reduced"), help="one solve of the first scenario, then exit")
    ap.add_argument("--out", help="output folder")
    args = ap.parse_args(argv)
    from cosim.runlog import run_folder
    from cosim.scenario import load
    names = args.scenarios.split(",")
    modes = [int(m) for m in args.modes.split(",")]
    if args.single:
        sc = load(names[0])
        if args.single == "full":
            p, t = full_solve(sc)
        else:
            p, t, _ = reduced_solve(sc, modes[0])
        print(json.dumps({"scenario": names[0], "model": args.single, "wall_s": t, "peaks_ue": peaks(p)}))
        return
    from pathlib import Path
    folder = run_folder("reduced_accuracy", Path(args.out) if args.out else None)
    rows, report = [], {}
    for name in names:
        sc = load(name)
        full, t_full = full_solve(sc)
        ref = peaks(full)
        report[name] = {"full": {"wall_s": t_full, "peaks_ue": ref, "steps_per_revolution":
                                 full.info["steps_per_revolution"]}, "reduced": {}}
        print(f"{name}: full TMM {t_full:.2f} s  {ref}", flush=True)
        for m in modes:
            red, t_red, t_basis = reduced_solve(sc, m)
            got = peaks(red)
            err = {g: [got[g][0] / ref[g][0] - 1, got[g][1] / ref[g][1] - 1] for g in ref}
            worst = max(abs(e) for v in err.values() for e in v)
            report[name]["reduced"][m] = {"wall_s": t_red, "basis_s": t_basis, "peaks_ue": got, "error": err,
                                         "worst": worst, "size": red.info["size"],
                                         "newton_iterations": red.info.get("newton_iterations")}
            rows.append({"scenario": name, "modes": m, "size": red.info["size"], "wall_s": round(t_red, 3),
                         "full_wall_s": round(t_full, 3), "worst_error_pct": round(100 * worst, 3),
                         **{f"{g}_{s}_pct": round(100 * err[g][i], 3) for g in err for i, s in enumerate(("max", "min"))}})
            print(f"  {m:2d} modes (r = {red.info['size']}): {t_red:.2f} s (basis {t_basis:.2f} s), worst "
                  f"{100 * worst:.2f} %  " + "  ".join(f"{g} {100 * e[0]:+.2f}/{100 * e[1]:+.2f} %" for g, e in err.items()),
                  flush=True)
    (folder / "accuracy.json").write_text(json.dumps(report, indent=1))
    with open(folder / "accuracy.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"written to {folder}")


if __name__ == "__main__":
    main()
