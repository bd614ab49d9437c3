"""Text tables of a finished run (``cosim compare <run-dir>``), read from its summary.json."""
from __future__ import annotations

import json
from pathlib import Path


def load_summary(run_dir) -> dict:
    path = Path(run_dir)
    if path.is_dir():
        path = path / "summary.json"
    if not path.exists():
        raise FileNotFoundError(f"no summary.json in {Path(run_dir)} (is it a run folder under logs/?)")
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None


def _fmt(x, digits=1):
    return "-" if x is None else f"{x:.{digits}f}"


def comparison_table(summary: dict) -> str:
    """Gauge extremes of the last revolution per engine (microstrain), drive torque range, wall
    and simulated time; records and scores where the summary has them."""
    lines = [f"scenario {summary.get('scenario')}  status {summary.get('status')}  mode {summary.get('mode')}  "
             f"revolutions {summary.get('revolutions')}" + (f"  (stop: {summary['stop']})" if summary.get("stop") else "")]
    engines = summary.get("engines", {})
    gauges = sorted({g for e in engines.values() for g in (e.get("gauges") or {})})
    head = f"{'gauge':<14} {'engine':<8} {'bend max':>9} {'bend min':>9} {'axial max':>9} {'axial min':>9}  [microstrain]"
    lines += ["", head, "-" * len(head)]
    for g in gauges:
        for name, e in engines.items():
            s = (e.get("gauges") or {}).get(g)
            if s is None:
                continue
            lines.append(f"{g:<14} {name:<8} {_fmt(s['bending_max_ue']):>9} {_fmt(s['bending_min_ue']):>9} "
                         f"{_fmt(s['axial_max_ue']):>9} {_fmt(s['axial_min_ue']):>9}"
                         + ("" if e.get("steady", True) else "  NOT STEADY"))
        for rec in (summary.get("records") or {}).get(g, []):
            lines.append(f"{g:<14} {'record':<8} {_fmt(rec.get('bending_max_ue')):>9} {_fmt(rec.get('bending_min_ue')):>9} "
                         f"{_fmt(rec.get('axial_max_ue')):>9} {_fmt(rec.get('axial_min_ue')):>9}  {rec.get('label', '')}")
    head = (f"{'engine':<8} {'status':<11} {'wall [s]':>9} {'sim [s]':>8} {'revs':>5} {'steady':>7} {'change':>7} "
            f"{'torque max':>10} {'torque min':>10}  [N m]")
    lines += ["", head, "-" * len(head)]
    for name, e in engines.items():
        steady = "-" if "steady" not in e else ("yes" if e["steady"] else "NO")
        change = e.get("revolution_change")
        lines.append(f"{name:<8} {e.get('status', '?'):<11} {_fmt(e.get('wall_time_s'), 2):>9} "
                     f"{_fmt(e.get('sim_time_s'), 3):>8} {_fmt(e.get('revolutions_run'), 1):>5} {steady:>7} "
                     f"{'-' if change is None else f'{100 * change:.2f}%':>7} {_fmt(e.get('drive_torque_max_Nm'), 2):>10} "
                     f"{_fmt(e.get('drive_torque_min_Nm'), 2):>10}" + (f"  {e['error']}" if e.get("error") else ""))
    lines.append("steady: the last two revolutions agree within the tolerance (change = their largest difference "
                 "relative to the peak-to-peak); results of an engine that is NOT STEADY are a transient")
    speed = {n: e["speed"] for n, e in engines.items() if e.get("speed")}
    if speed:
        lines += ["", "crank speed (motor): mean [rpm] and (max - min) / mean of the last revolution"]
        for n, s in speed.items():
            lines.append(f"  {n:<8} {s['mean_rpm_last']:.2f} rpm  fluctuation {100 * s['fluctuation_last']:.2f} %")
    scores = summary.get("scores")
    if scores:
        head = (f"{'engine':<8} {'gauge':<12} {'record':<18} {'+peak err':>9} {'-peak err':>9} {'rms [ue]':>8} "
                f"{'corr':>6} {'lag [deg]':>9} {'scale':>6} {'in env':>6}")
        lines += ["", "scores against records (peak errors = model / record - 1; for - peaks, + = larger magnitude)",
                  head, "-" * len(head)]
        for s in scores:
            lines.append(f"{s['engine']:<8} {s['gauge']:<12} {s['record']:<18} {_pct(s.get('plus_peak_error')):>9} "
                         f"{_pct(s.get('minus_peak_error')):>9} {_fmt(s.get('rms_error_ue')):>8} "
                         f"{_fmt(s.get('correlation'), 2):>6} {_fmt(s.get('phase_lag_deg')):>9} "
                         f"{_fmt(s.get('scale'), 2):>6} {_fmt(s.get('inside_envelope'), 2):>6}"
                         + ("" if s.get("steady", True) else "  NOT STEADY"))
    for w in summary.get("record_warnings") or []:
        lines.append(f"note: {w}")
    return "\n".join(lines)


def _pct(x):
    return "-" if x is None or x != x else f"{100 * x:+.1f}%"
