"""Markdown tables of a benchmark result file written by ``tests.benchmarks.bench`` (the README's
table is printed by this, not typed by hand).

    python -m tests.benchmarks.bench_table logs/benchmarks/bench-<timestamp>.json
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


def _setting(s: dict) -> str:
    return ", ".join(f"{v} {k}" if k in ("segments", "elements") else f"{v}" for k, v in s.items())


def engine_rows(data: dict) -> list[str]:
    rows = ["| rig | engine | cheapest setting within 1 % | wall s per simulated s | x TMM | revolutions to steady | "
            "cost to steady [s] | peak memory [MB] | converged p-p [microstrain] |",
            "|---|---|---|---|---|---|---|---|---|"]
    for rig, block in data["rigs"].items():
        tmm = (block.get("tmm") or {}).get("chosen")
        for engine in ("tmm", "exudyn", "mujoco"):
            b = block.get(engine)
            if not isinstance(b, dict):
                continue
            ref = b.get("reference") or {}
            ptp = ", ".join(f"{g} {v:.0f}" for g, v in (ref.get("metrics") or {}).items())
            c = b.get("chosen")
            if not c:
                why = b.get("error") or "no setting within tolerance"
                rows.append(f"| {rig} | {engine} | {why} | | | | | | {ptp} |")
                continue
            ratio = f"{c['wall_per_sim_s'] / tmm['wall_per_sim_s']:.3g}" if tmm else "n/a"
            steady, periodic = c.get("time_to_steady_s"), c.get("periodic_solve_s")
            cost = "" if steady is None else f"{steady:.3g}"
            if isinstance(periodic, str):
                cost += " (periodic solve failed)"
            elif periodic is not None:
                cost += f" (periodic solve {periodic:.3g})"
            rows.append(f"| {rig} | {engine} | {_setting(c['setting'])} | {c['wall_per_sim_s']:.3g} | {ratio} | "
                        f"{c.get('revolutions_to_steady')} | {cost} | {c['peak_memory_MB']:.0f} | {ptp} |")
    return rows


def overhead_rows(data: dict) -> list[str]:
    o = data.get("bench_overhead") or {}
    if "error" in o or not o:
        return [f"bench overhead: {o.get('error', 'not measured')}"]
    rows = ["| engine steps per macro step | engine [s] | master [s] (fraction) | whole run, traces only (fraction) | "
            "whole run, rerun streaming (fraction) |", "|---|---|---|---|---|"]
    for m, r in o.items():
        rows.append(f"| {m} | {r['engine_s']:.3g} | {r['master_s']:.3g} ({100 * r['master_fraction']:.0f} %) | "
                    f"{r['run_traces_only_s']:.3g} ({100 * r['overhead_traces_only_fraction']:.0f} %) | "
                    f"{r['run_stream_s']:.3g} ({100 * r['overhead_stream_fraction']:.0f} %) |")
    return rows


def scaling_rows(data: dict) -> list[str]:
    s = data.get("tmm_scaling") or {}
    if "error" in s or not s:
        return [f"TMM scaling: {s.get('error', 'not measured')}"]
    rows = ["| segments per link | quasi-static revolution [s] | time-domain revolution, default [s] | "
            "time-domain revolution, sweeps only [s] |", "|---|---|---|---|"]

    def cell(x):
        return "" if x is None else f"{x:.3g}"
    for r in s["by_segments"]:
        rows.append(f"| {r['segments']} | {cell(r.get('quasi_static_revolution_s'))} | "
                    f"{cell(r.get('time_domain_revolution_s'))} | {cell(r.get('time_domain_sweeps_revolution_s'))} |")
    rows.append("")
    rows.append(f"Fitted exponents in segments: quasi-static {s['quasi_static_exponent']:.2f}, time domain "
                f"{s['time_domain_exponent']:.2f} (default), {s.get('time_domain_sweeps_exponent', float('nan')):.2f} "
                f"(sweeps only). Revolutions: set-up {s.get('setup_s', float('nan')):.3g} s + "
                f"{s.get('per_revolution_s', float('nan')):.3g} s per revolution, marching exponent "
                f"{s.get('marching_exponent', float('nan')):.2f}.")
    return rows


def main(argv=None) -> str:
    argv = sys.argv[1:] if argv is None else argv
    data = json.loads(Path(argv[0]).read_text())
    m = data["machine"]
    text = "\n".join([f"Machine: {m['cpus']} cores, {m['platform']}, Python {m['python']}; status {data['status']}.", ""]
                     + engine_rows(data) + [""] + overhead_rows(data) + [""] + scaling_rows(data))
    print(text)
    return text


if __name__ == "__main__":
    main()
