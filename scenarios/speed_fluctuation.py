"""Crank speed fluctuation of the motor-driven rigs at their test speeds.

Runs every scenario that has a [motor] table through the co-simulation master with the declared
motor (MuJoCo rigid-body engine by default; ``--engine`` for another), starting steady at the
set-point, and reports per rig the mean speed and the fluctuation (max - min) / mean of the last
revolution, with and without the flywheels. Writes ``fluctuation.csv`` and ``summary.json`` to
``logs/speed_fluctuation-<timestamp>/``.

    python -m scenarios.speed_fluctuation [--revolutions 6] [--engine mujoco] [scenario ...]
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import sys

from cosim import scenario as sc
from cosim.master import CoSimulation
from cosim.runlog import run_folder, write_csv, write_json


def fluctuation(scenario, engine: str, revolutions: float) -> dict:
    scenario = dataclasses.replace(scenario, gauges=())      # speed only: skip the strain outputs
    ch = CoSimulation(scenario, (engine,), mode="motor").run(revolutions=revolutions)[engine]
    if ch.status != "completed":
        return {"status": ch.status, "error": ch.error}
    f = ch.speed_fluctuation()
    return {"status": "completed", "mean_rpm": float(f["mean"][-1] * 30 / math.pi),
            "fluctuation": float(f["fluctuation"][-1]), "min_rpm": float(f["min"][-1] * 30 / math.pi),
            "max_rpm": float(f["max"][-1] * 30 / math.pi)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenarios", nargs="*", help="scenario names (default: every scenario with a [motor] table)")
    ap.add_argument("--engine", default="mujoco", choices=("mujoco", "exudyn", "tmm"))
    ap.add_argument("--revolutions", type=float, default=6.0, help="revolutions to run (the last one is reported)")
    args = ap.parse_args(argv)
    names = args.scenarios or [n for n in sc.scenario_names() if sc.load(n).motor is not None]
    rows = []
    for name in names:
        s = sc.load(name)
        if s.motor is None:
            print(f"{name}: no [motor] table, skipped", file=sys.stderr)
            continue
        bare = s.with_overrides({"motor.flywheels": []})
        for label, scen in (("with flywheels", s), ("without flywheels", bare)):
            r = fluctuation(scen, args.engine, args.revolutions)
            rows.append({"scenario": name, "flywheels": label, "setpoint_rpm": abs(s.drive.speed_rad_s) * 30 / math.pi,
                         "drive_inertia_kg_m2": scen.motor.crank_inertia_kg_m2, **r})
            shown = (f"mean {r['mean_rpm']:.2f} rpm, fluctuation {100 * r['fluctuation']:.1f} %"
                     if r["status"] == "completed" else f"{r['status']}: {r['error']}")
            print(f"{name:28s} {label:18s} {shown}", flush=True)
    folder = run_folder("speed_fluctuation")
    write_csv(folder / "fluctuation.csv", rows)
    write_json(folder / "summary.json", {"engine": args.engine, "revolutions": args.revolutions, "rows": rows})
    print(f"written to {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
