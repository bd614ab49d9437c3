"""Markdown tables of a benchmark result file written by ``tests.benchmarks.bench`` (the README's
tables are printed by this, not typed by hand). Parts missing from the file are left out.

    python -m tests.benchmarks.bench_table logs/benchmarks/bench-<timestamp>.json
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

ENGINES = ("tmm", "exudyn", "mujoco")


def _setting(s: dict) -> str:
    return ", ".join(f"{v} {k}" if k in ("segments", "elements") else f"{v}" for k, v in s.items())


def _num(x, fmt=".3g", empty=""):
    return empty if x is None or isinstance(x, str) else format(x, fmt)


def _pct(x):
    return "" if x is None else f"{100 * x:+.1f} %"


def _rows_of(data: dict):
    """(rig, engine, engine block) for every engine block of the file."""
    for rig, block in (data.get("rigs") or {}).items():
        if not isinstance(block, dict):
            continue
        if "error" in block and not any(e in block for e in ENGINES):
            yield rig, "", {"error": block["error"]}
            continue
        for engine in ENGINES:
            if isinstance(block.get(engine), dict):
                yield rig, engine, block[engine]


def accuracy_rows(data: dict) -> list[str]:
    tol = data.get("tol", 0.01)
    rows = [f"| rig | engine | cheapest setting within {100 * tol:g} % | vs own converged | vs exudyn converged: "
            "chosen | vs exudyn converged: converged | converged p-p [microstrain] |", "|---|---|---|---|---|---|---|"]
    for rig, engine, b in _rows_of(data):
        ref = b.get("reference") or {}
        ptp = ", ".join(f"{g} {v:.0f}" for g, v in (ref.get("metrics") or {}).items())
        vs = ((data["rigs"][rig].get("vs_exudyn") or {}).get(engine) or {}) if engine else {}
        c = b.get("chosen")
        if not c:
            rows.append(f"| {rig} | {engine} | {b.get('error') or 'no setting within tolerance'} | | | "
                        f"{_pct(vs.get('converged_max'))} | {ptp} |")
            continue
        note = "" if vs.get("exudyn_converged_steady", True) else " (exudyn not steady)"
        rows.append(f"| {rig} | {engine} | {_setting(c['setting'])} | {_pct(c.get('error_vs_reference'))} | "
                    f"{_signed_max(vs.get('chosen'))}{note} | {_signed_max(vs.get('converged'))} | {ptp} |")
    return rows


def _signed_max(d):
    """The gauge difference of largest size, signed, as a percentage."""
    if not d:
        return ""
    g = max(d, key=lambda k: abs(d[k]))
    return f"{100 * d[g]:+.1f} % ({g})"


def cost_rows(data: dict) -> list[str]:
    rows = ["| rig | engine | setting | first call [s] | set-up [s] | marching, s per simulated s | x TMM | "
            "set-up + marching per simulated s | x TMM | revolutions to steady | to steady [s] | x TMM | "
            "TMM periodic solve [s] | peak memory [MB] |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for rig, engine, b in _rows_of(data):
        c = b.get("chosen")
        if not c or ("march_per_sim_s" not in c and "wall_per_sim_s" not in c):
            why = b.get("error") or (c or {}).get("error") or "no setting within tolerance"
            rows.append(f"| {rig} | {engine} | {why} |" + " |" * 11)
            continue
        r = (data["rigs"][rig].get("ratios_vs_tmm") or {}).get(engine, {})
        r = r if isinstance(r, dict) else {"wall": r}        # files before 2026-11-26: one ratio
        one = engine == "tmm"
        periodic = c.get("periodic_solve_s")
        rows.append(f"| {rig} | {engine} | {_setting(c['setting'])} | {_num(c.get('first_call_s'), '.2f')} | "
                    f"{_num(c.get('setup_s'))} | {_num(c.get('march_per_sim_s'))} | "
                    f"{'1' if one else _num(r.get('march'))} | {_num(c.get('wall_per_sim_s'))} | "
                    f"{'1' if one else _num(r.get('wall'))} | {_num(c.get('revolutions_to_steady'), 'g')} | "
                    f"{_num(c.get('time_to_steady_s'))} | {'1' if one else _num(r.get('to_steady'))} | "
                    f"{periodic if isinstance(periodic, str) else _num(periodic)} | "
                    f"{_num(c.get('peak_memory_MB'), '.0f')} |")
    return rows


def quasi_static_rows(data: dict) -> list[str]:
    q = data.get("quasi_static")
    if not q:
        return []
    if "error" in q:
        return [f"Quasi-static revolution: {q['error']}"]
    fe = q["fe_crank_rocker_241rpm"]
    n = fe["segments_per_link"]
    rows = [f"| FE rig 241 rpm, 360 positions, {n} segments per link | numpy [ms] | compiled [ms] | ratio |",
            "|---|---|---|---|"]
    for what, label in (("quasi_static", f"quasi-static revolution, beam-column (at most "
                                         f"{fe.get('quasi_static_solves')} solves a position)"),
                        ("configurations", "factorization of a revolution with maps")):
        a, b = fe[f"{what}_numpy"], fe[f"{what}_compiled"]
        rows.append(f"| {label} | {1e3 * a['min_s']:.3g} | {1e3 * b['min_s']:.3g} | "
                    f"{fe[what + '_ratio']['min']:.2g}x |")
    al = q.get("alexander_lawrence_400rpm") or {}
    rows += ["", f"First compiled calls in a fresh process (numba cache load): {fe['first_compiled_calls_s']:.3g} s. "
             f"Alexander-Lawrence, compiled beam-column revolution: "
             f"{1e3 * al.get('quasi_static_beam_column_s', float('nan')):.3g} ms (median)."]
    return rows


def floor_rows(data: dict) -> list[str]:
    f = data.get("floor")
    if not f:
        return []
    if isinstance(f, dict):
        return [f"Per-step floor: {f.get('error')}"]
    rows = ["| compiled march per step, FE rig 241 rpm | per step [us] | against the 3-5 us floor | set-up of a "
            "revolution [s] |", "|---|---|---|---|"]
    for p in f:
        rows.append(f"| {p['segments_per_link']} segments per link, {p['step_deg']:g} deg | "
                    f"{1e6 * p['per_step_s']:.3g} | "
                    f"{p['ratio_to_floor'][0]:.2g}-{p['ratio_to_floor'][1]:.2g}x | {p['setup_s']:.3g} |")
    return rows


def sweep_rows(data: dict) -> list[str]:
    s = data.get("sweep")
    if not s:
        return []
    if s.get("finished"):
        return [f"Speed sweep ({s.get('points')} points, {s.get('rpm')} rpm, {s.get('segments_per_link')} segments per "
                f"link, {s.get('workers')} workers): {s['wall_time_s']:.3g} s (goal 2 s), median "
                f"{_num(s.get('median_point_s'))} s per point; no solution at {s.get('points_without_solution')} rpm."]
    return [f"Speed sweep ({s.get('rpm')} rpm): {s.get('note') or s.get('error')}."]


def overhead_rows(data: dict) -> list[str]:
    o = data.get("bench_overhead")
    if not o:
        return []
    if "error" in o:
        return [f"bench overhead: {o['error']}"]
    rows = ["| engine steps per macro step (per call) | engine [s] | master [s] (fraction) | whole run, traces only "
            "(fraction) | whole run, rerun streaming (fraction) | streaming alone [s] (fraction of engine) | "
            "streaming in the run's loop [s] (fraction of engine) | streaming, median of pairs: whole run / loop "
            "(quartiles) |",
            "|---|---|---|---|---|---|---|---|"]
    for m, r in o.items():
        per_call = f" ({r['engine_steps_per_call']})" if "engine_steps_per_call" in r else ""
        rows.append(f"| {m}{per_call} | {r['engine_s']:.3g} | {r['master_s']:.3g} "
                    f"({100 * r['master_fraction']:.0f} %) | "
                    f"{r['run_traces_only_s']:.3g} ({100 * r['overhead_traces_only_fraction']:.0f} %) | "
                    f"{r['run_stream_s']:.3g} ({100 * r['overhead_stream_fraction']:.0f} %) | "
                    + (f"{r['streaming_s']:.3g} ({100 * r['streaming_fraction']:.0f} %) |" if "streaming_s" in r
                       else " |")
                    + (f" {r['streaming_loop_s']:.3g} ({100 * r['streaming_loop_fraction']:.0f} %) |"
                       if "streaming_loop_s" in r else " |")
                    + (" " + " / ".join(f"{100 * r[f'streaming_paired_{k}_median_fraction']:.0f} % "
                                        f"({100 * r[f'streaming_paired_{k}_quartiles_fraction'][0]:.0f} to "
                                        f"{100 * r[f'streaming_paired_{k}_quartiles_fraction'][1]:.0f} %)"
                                        for k in ("whole", "loop")) + " |"
                       if "streaming_paired_whole_median_fraction" in r else " |"))
    return rows


def scaling_rows(data: dict) -> list[str]:
    s = data.get("tmm_scaling")
    if not s:
        return []
    if "error" in s:
        return [f"TMM scaling: {s['error']}"]
    rows = ["| segments per link | quasi-static revolution [s] | time-domain revolution, default [s] | "
            "time-domain revolution, maps only [s] | time-domain revolution, numpy sweeps only [s] |",
            "|---|---|---|---|---|"]
    for r in s["by_segments"]:
        part = "" if r.get("time_domain_sweeps_revolutions_marched", 1.0) == 1.0 else \
            f" ({r['time_domain_sweeps_revolutions_marched']:g} revolution, scaled)"
        rows.append(f"| {r['segments']} | {_num(r.get('quasi_static_revolution_s'))} | "
                    f"{_num(r.get('time_domain_revolution_s'))} | {_num(r.get('time_domain_maps_revolution_s'))} | "
                    f"{_num(r.get('time_domain_sweeps_revolution_s'))}{part} |")
    rows.append("")
    def x(key, fmt=".2f"):
        return _num(s.get(key), fmt, "n/a")        # NaN (too few points to fit) is stored as null
    rows.append(f"Fitted exponents in segments: quasi-static {x('quasi_static_exponent')}, time domain "
                f"{x('time_domain_exponent')} (default), {x('time_domain_maps_exponent')} (maps only), "
                f"{x('time_domain_sweeps_exponent')} (numpy sweeps only). "
                f"Revolutions: set-up {x('setup_s', '.3g')} s + {x('per_revolution_s', '.3g')} s per revolution, "
                f"marching exponent {x('marching_exponent')}.")
    return rows


def main(argv=None) -> str:
    argv = sys.argv[1:] if argv is None else argv
    data = json.loads(Path(argv[0]).read_text())
    m = data["machine"]
    load = m.get("load_average_at_start")
    head = f"Machine: {m['cpus']} cores, {m['platform']}, Python {m['python']}; status {data['status']}"
    if load:
        head += f"; load average {load[0]:.1f} at the start"
    total = (data.get("elapsed_s") or {}).get("total")
    if total:
        head += f"; {total / 60:.1f} min in all"
    sections = [[head + "."]]
    if data.get("rigs"):
        sections += [accuracy_rows(data), cost_rows(data)]
    sections += [quasi_static_rows(data), floor_rows(data), sweep_rows(data), overhead_rows(data), scaling_rows(data)]
    text = "\n\n".join("\n".join(s) for s in sections if s)
    print(text)
    return text


if __name__ == "__main__":
    main()
