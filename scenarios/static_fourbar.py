"""Static analysis of the Alexander-Lawrence four-bar held at one crank angle (TMM instantaneous structure).

Mechanism (Shin 1986, §8.3): crank 4, coupler 11, rocker 10.5, ground 10 in;
1 in wide aluminium strip, crank 0.167 in and coupler/rocker 0.063 in thick.

Assumptions (not given by the source): E = 10.3e6 psi and weight density 0.1 lb/in^3, typical
of 6061 aluminium; the strengths 90 ksi / 45 ksi are Shin's. The bearing masses only matter
for inertia loads and are left out of this static example. The example load is a static
force at the coupler midpoint plus self-weight; the crank pivot is clamped (it carries the drive
torque) and the rocker pivot is pinned.

Prints node results and writes ``nodes.csv`` and ``summary.json`` to ``logs/static_fourbar-<timestamp>/``.
Run: ``python -m scenarios.static_fourbar [--crank-angle 30] [--load 10] [--mode beam_column]``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from cosim.runlog import run_folder, write_csv, write_json
from scenarios.rigs import alexander_lawrence
from tmm_core import TMMError, external_resultant, solve_static, surface_stresses

def run(crank_angle_deg: float, load_N: float, mode: str, n_segments: int, out_dir: Path | None) -> dict:
    fb = alexander_lawrence(n_segments, bearing_lb=0.0)
    motion = fb.motion(np.radians(crank_angle_deg))
    loads = np.zeros((n_segments + 1, 3))
    loads[n_segments // 2, 1] = -load_N
    case = fb.load_case(motion, {"coupler": loads}, fb.gravity_loads())
    sol = solve_static(fb.structure(), case, beam_column=(mode == "beam_column"),
                       large_deflection=(mode == "large_deflection"))

    rows = []
    for name, r in sol.members.items():
        top, bottom = surface_stresses(r)
        pos, disp, dist = r.node_positions, r.displacement, sol.distortion(name)
        sf = sol.safety_factor(name)
        for j in range(r.member.n_segments + 1):
            rows.append({"link": name, "node": j, "x_m": r.member.stations[j],
                         "X_m": pos[j, 0], "Y_m": pos[j, 1], "dX_m": disp[j, 0], "dY_m": disp[j, 1],
                         "theta_rad": r.theta[j], "distortion_m": dist[j],
                         "M_Nm": r.M[j, 1], "V_N": r.V[j, 1], "N_N": r.N[j, 1],
                         "sigma_top_Pa": top[j, 1], "sigma_bottom_Pa": bottom[j, 1], "safety_factor": sf[j]})
    worst = min(rows, key=lambda row: row["safety_factor"])
    biggest = max(rows, key=lambda row: row["distortion_m"])
    resultant = external_resultant(sol, deformed=mode != "linear")
    summary = {
        "scenario": "static_fourbar", "mode": sol.mode, "iterations": sol.iterations,
        "crank_angle_deg": crank_angle_deg, "coupler_midpoint_load_N": load_N, "segments_per_link": n_segments,
        "drive_torque_Nm": float(sol.reaction_moment("A")),
        "reactions": {j: {"Fx_N": float(v[0]), "Fy_N": float(v[1]), "M_Nm": float(v[2])} for j, v in sol.reactions.items()},
        "max_distortion": {"link": biggest["link"], "node": biggest["node"], "value_m": biggest["distortion_m"]},
        "min_safety_factor": {"link": worst["link"], "node": worst["node"], "value": worst["safety_factor"]},
        "equilibrium_residual": {"Fx_N": float(resultant[0]), "Fy_N": float(resultant[1]), "M_Nm": float(resultant[2])},
    }

    print(f"Alexander-Lawrence four-bar, crank angle {crank_angle_deg:g} deg, {load_N:g} N at coupler midpoint "
          f"+ self-weight, {sol.mode} ({sol.iterations} solve(s))")
    print(f"{'link':8s}{'node':>5s}{'dist [mm]':>11s}{'M [N m]':>11s}{'N [N]':>10s}{'s_top [MPa]':>13s}"
          f"{'s_bot [MPa]':>13s}{'SF':>9s}")
    for row in rows:
        print(f"{row['link']:8s}{row['node']:5d}{row['distortion_m'] * 1e3:11.4f}{row['M_Nm']:11.4f}{row['N_N']:10.3f}"
              f"{row['sigma_top_Pa'] / 1e6:13.3f}{row['sigma_bottom_Pa'] / 1e6:13.3f}{row['safety_factor']:9.3g}")
    print(f"drive torque at crank pivot A: {summary['drive_torque_Nm']:.6g} N m (CCW positive)")
    print(f"max distortion {biggest['distortion_m'] * 1e3:.4f} mm ({biggest['link']} node {biggest['node']}); "
          f"min safety factor {worst['safety_factor']:.3g} ({worst['link']} node {worst['node']})")

    if out_dir is not None:
        write_csv(out_dir / "nodes.csv", rows)
        write_json(out_dir / "summary.json", summary)
        print(f"wrote {out_dir / 'nodes.csv'} and {out_dir / 'summary.json'}")
    return summary


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--crank-angle", type=float, default=30.0, help="crank angle from the ground line [deg]")
    parser.add_argument("--load", type=float, default=10.0, help="downward force at the coupler midpoint [N]")
    parser.add_argument("--mode", choices=("linear", "beam_column", "large_deflection"), default="beam_column")
    parser.add_argument("--segments", type=int, default=8, help="TMM segments per link")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default logs/static_fourbar-<timestamp>)")
    args = parser.parse_args(argv)
    try:
        run(args.crank_angle, args.load, args.mode, args.segments, run_folder("static_fourbar", args.out))
    except TMMError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
