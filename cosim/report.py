"""Text tables of a results folder (``cosim compare <folder>``), read from its summary.json: a
run's comparison table, a sweep's peaks per speed, an uncertainty run's band, a static
structure's results (:func:`report` picks the one that fits the folder). A summary that is not a
JSON object, or a folder that is still running or was cut short, is said so, never a traceback.

The tables of ``cosim identify`` (:func:`identification_table`) and ``cosim synthesize``
(:func:`synthesis_table`) are here too, from the records those commands return.

Owns: the text tables of ``cosim compare`` from a folder's summary.json, and of ``cosim identify``
and ``cosim synthesize`` from their results. Boundaries: reads only summary.json; computes nothing
new; prints nothing (the commands of cosim.commands print).
"""
from __future__ import annotations

import json
from pathlib import Path

from .engines import MODELS, is_rigid
from .files import FileRefused, SUMMARY_BYTES, read_text_bounded
from .run_outcome import MISSING_OUTPUTS
from .structure_scenario import summary_table

#: Where a user reads why the models and the measurement differ (pointed to when they differ much).
MEASUREMENT_GAP_DOC = "docs/validation.md, section 'How far the bench is from the measurement'"
#: A peak error beyond this fraction gets the pointer to that section.
LARGE_PEAK_ERROR = 0.5


def load_summary(run_dir) -> dict:
    """The parsed summary.json of a folder (or the file itself); ValueError naming the file when
    it is not a JSON object of a bench summary."""
    path = Path(run_dir)
    if path.is_dir():
        path = path / "summary.json"
    if not path.exists():
        raise FileNotFoundError(f"no summary.json in {Path(run_dir)} (is it a run folder under logs/?)")
    try:
        data = json.loads(read_text_bounded(path, SUMMARY_BYTES))
    except FileRefused as exc:
        raise ValueError(f"{path}: {exc}; not a bench summary") from None
    except RecursionError:
        raise ValueError(f"{path}: nested too deeply to be a bench summary") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not a bench summary (a JSON {type(data).__name__}, expected an object with "
                         "'scenario' and 'status')")
    if "scenario" not in data or "status" not in data:
        missing = " and ".join(k for k in ("scenario", "status") if k not in data)
        raise ValueError(f"{path}: not a bench summary (no key {missing})")
    return data


def folder_kind(summary: dict) -> str:
    """``"run"``, ``"sweep"``, ``"uncertainty"`` or ``"structure"`` (from the summary's keys)."""
    if summary.get("kind") == "structure":
        return "structure"
    if "points" in summary and "rpm" in summary:
        return "sweep"
    if "samples" in summary and "parameters" in summary:
        return "uncertainty"
    return "run"


def status_notice(summary: dict, kept: str = "traces.csv holds every completed step") -> str | None:
    """One line when the folder's work did not finish (``None`` when it did); ``kept`` says what
    the folder keeps of an unfinished run."""
    status = summary.get("status")
    if status in ("completed", "completed with failed samples"):
        return None
    if status == MISSING_OUTPUTS:
        gone = ", ".join(str(m.get("what")) for m in summary.get("missing") or []) or "see the notes"
        return (f"COMPLETED WITH MISSING OUTPUTS: the results below are whole, but {gone} is missing or may be "
                "incomplete (the reasons are in the summary's missing and notes)")
    if status == "completed with unsolved points":
        u = summary.get("unsolved_points") or {}
        return (f"COMPLETED WITH UNSOLVED POINTS: {u.get('count', '?')} of {u.get('of', '?')} points have no "
                "solution (why: below the table)")
    if status == "incomplete":
        done = summary.get("progress")
        return ("INCOMPLETE: still running, or killed before it could finish" +
                (f" (progress {100 * done:.0f} %)" if isinstance(done, (int, float)) else "") +
                f"; the table shows the summary as last written ({kept})")
    if status == "interrupted":
        return "INTERRUPTED: stopped by the user or a signal; the results below cover what ran"
    if status == "failed":
        return "FAILED: " + (summary["error"] if summary.get("error") else "see the errors below")
    return f"status {status!r}"


def report(summary: dict) -> str:
    """The table that fits the summary's folder (:func:`folder_kind`)."""
    kind = folder_kind(summary)
    if kind == "run":
        return comparison_table(summary)
    if kind == "structure":
        notice = status_notice(summary)
        if notice:
            return f"scenario {summary.get('scenario')}  static structure analysis\n{notice}"
        return summary_table(summary)
    return (sweep_table if kind == "sweep" else uncertainty_table)(summary)


def _fmt(x, digits=1):
    return "-" if x is None else f"{x:.{digits}f}"


def comparison_table(summary: dict) -> str:
    """Gauge extremes of the last revolution per engine (microstrain), drive torque range, wall
    and simulated time; records and scores where the summary has them."""
    count = summary.get("revolutions")
    count = f"{count:g}" if isinstance(count, (int, float)) and not isinstance(count, bool) else count
    revolutions = (f"until steady (at most {count} revolutions)" if summary.get("until_steady")
                   else f"revolutions {count}")
    lines = [f"scenario {summary.get('scenario')}  status {summary.get('status')}  mode {summary.get('mode')}  "
             f"{revolutions}" + (f"  (stop: {summary['stop']})" if summary.get("stop") else "")]
    notice = status_notice(summary)
    if notice:
        lines.append(notice)
    lk = summary.get("linkage") or {}
    if lk.get("transmission_min_deg") is not None:
        limits = ""
        if lk.get("crank_angle_extended_deg") is not None:
            limits = (f"; limit positions at crank {lk['crank_angle_extended_deg']:.2f} and "
                      f"{lk['crank_angle_folded_deg']:.2f} deg (rocker swing {lk['oscillation_deg']:.2f} deg)")
        lines.append(f"linkage: {lk.get('grashof', '')}, transmission angle {lk['transmission_min_deg']:.2f} to "
                     f"{lk['transmission_max_deg']:.2f} deg{limits}")
    engines = summary.get("engines") or {}
    gauges = sorted({g for e in engines.values() for g in (e.get("gauges") or {})})
    head = f"{'gauge':<14} {'engine':<8} {'bend max':>9} {'bend min':>9} {'axial max':>9} {'axial min':>9}  [microstrain]"
    lines += ["", head, "-" * len(head)]
    for g in gauges:
        for name, e in engines.items():
            s = (e.get("gauges") or {}).get(g)
            if s is None:
                continue
            lines.append(f"{g:<14} {name:<8} {_fmt(s.get('bending_max_ue')):>9} {_fmt(s.get('bending_min_ue')):>9} "
                         f"{_fmt(s.get('axial_max_ue')):>9} {_fmt(s.get('axial_min_ue')):>9}"
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
                     f"{_fmt(e.get('drive_torque_min_Nm'), 2):>10}  {MODELS.get(name, '')}"
                     + (f"  {e['error']}" if e.get("error") else ""))
    lines.append("steady: the last two revolutions agree within the tolerance (change = their largest difference "
                 "relative to the peak-to-peak); results of an engine that is NOT STEADY are a transient")
    for name, e in engines.items():
        if e.get("unsteady"):
            lines.append(f"  {name} NOT STEADY, {e['unsteady']['text']}")
    lines += _flag_lines(engines)
    speed = {n: e["speed"] for n, e in engines.items() if e.get("speed")}
    if speed:
        lines += ["", "crank speed (motor): mean [rpm] and (max - min) / mean of the last revolution"]
        for n, s in speed.items():
            lines.append(f"  {n:<8} {_fmt(s.get('mean_rpm_last'), 2)} rpm  fluctuation "
                         f"{_fmt(100 * s['fluctuation_last'] if s.get('fluctuation_last') is not None else None, 2)} %")
    lines += _motor_lines(engines)
    scores = summary.get("scores")
    if scores:
        head = (f"{'engine':<8} {'gauge':<12} {'record':<18} {'+peak err':>9} {'-peak err':>9} {'rms [ue]':>8} "
                f"{'corr':>6} {'lag [deg]':>9} {'scale':>6} {'in env':>6}")
        lines += ["", "scores against records (peak errors = model / record - 1; for - peaks, + = larger magnitude)",
                  head, "-" * len(head)]
        for s in scores:
            lines.append(f"{s.get('engine', '?'):<8} {s.get('gauge', '?'):<12} {s.get('record', '?'):<18} "
                         f"{_pct(s.get('plus_peak_error')):>9} "
                         f"{_pct(s.get('minus_peak_error')):>9} {_fmt(s.get('rms_error_ue')):>8} "
                         f"{_fmt(s.get('correlation'), 2):>6} {_fmt(s.get('phase_lag_deg')):>9} "
                         f"{_fmt(s.get('scale'), 2):>6} {_fmt(s.get('inside_envelope'), 2):>6}"
                         + ("" if s.get("steady", True) else "  NOT STEADY"))
        gap = _measurement_gap_line(scores)
        if gap:
            lines.append(gap)
    for w in summary.get("record_warnings") or []:
        lines.append(f"note: {w}")
    return "\n".join(lines)


def _flag_lines(engines: dict) -> list:
    """The engines' physics flags (``engines.<engine>.flags``, :mod:`cosim.physics_flags`), one line
    per message with the engines that carry it."""
    by_message = {}
    for name, e in engines.items():
        for f in e.get("flags") or []:
            if isinstance(f, dict) and f.get("message"):
                by_message.setdefault(f["message"], []).append(name)
    if not by_message:
        return []
    return ["", "physics flags:"] + [f"  [{', '.join(names)}] {msg}" for msg, names in by_message.items()]


def _measurement_gap_line(scores: list) -> str | None:
    """One line pointing to the measurement-gap section when any peak error exceeds
    :data:`LARGE_PEAK_ERROR`; a rigid engine among the scored is named as such (it has no elastic
    response to overshoot with: scoring closest does not make it the better model)."""
    errors = [abs(s[k]) for s in scores for k in ("plus_peak_error", "minus_peak_error")
              if isinstance(s.get(k), (int, float)) and s[k] == s[k]]
    if not errors or max(errors) <= LARGE_PEAK_ERROR:
        return None
    rigid = sorted({s.get("engine") for s in scores if is_rigid(s.get("engine"))})
    return (f"peak errors up to {100 * max(errors):.0f} %: the models and the records differ by more than the "
            f"models differ from each other; why, and what the declared unknowns can and cannot explain: "
            f"{MEASUREMENT_GAP_DOC}" + (f". {', '.join(rigid)}: the rigid model (no elastic response), which is why "
                                        "it can score closest" if rigid else ""))


def _pct(x):
    return "-" if x is None or x != x else f"{100 * x:+.1f}%"


def _motor_lines(engines: dict) -> list:
    """Motor current and voltage ranges and the energy balance of the last revolution (motor runs)."""
    lines = []
    for n, e in engines.items():
        m, en = e.get("motor"), e.get("energy_J")
        if not m and not en:
            continue
        if not lines:
            lines += ["", "motor (whole run: current and voltage range; last revolution: energy balance [J])"]
        if m:
            lines.append(f"  {n:<8} current {_fmt(m.get('current_min_A'), 2)} .. {_fmt(m.get('current_max_A'), 2)} A"
                         f"  voltage {_fmt(m.get('voltage_min_V'), 1)} .. {_fmt(m.get('voltage_max_V'), 1)} V")
        if isinstance(en, dict) and "note" in en:
            lines.append(f"  {n:<8} energy balance: {en['note']}")
        elif isinstance(en, dict):
            e_in = en.get("electrical_in_J")
            res = en.get("residual_J")
            rel = f" ({100 * res / e_in:+.2f} % of the input)" if e_in and res is not None else ""
            lines.append(f"  {n:<8} electrical in {_fmt(e_in, 3)} = copper {_fmt(en.get('copper_loss_J'), 3)} + "
                         f"friction {_fmt(en.get('friction_loss_J'), 3)} + linkage work {_fmt(en.get('linkage_work_J'), 3)} + "
                         f"drive kinetic {_fmt(en.get('drive_kinetic_energy_change_J'), 3)} + magnetic "
                         f"{_fmt(en.get('magnetic_energy_change_J'), 3)} + residual {_fmt(res, 3)}{rel}")
    return lines


def sweep_table(summary: dict) -> str:
    """Peaks per speed, engine and gauge of a ``cosim sweep`` folder [microstrain]."""
    rpm = summary.get("rpm") or []
    points = summary.get("points") or []
    lines = [f"sweep of {summary.get('scenario')}  status {summary.get('status')}  method {summary.get('method')}  "
             f"{len(points)} of {len(rpm)} points"]
    notice = status_notice(summary, kept="sweep.csv holds every finished point")
    if notice:
        lines.append(notice)
    head = (f"{'rpm':>7} {'engine':<8} {'gauge':<14} {'status':<10} {'bend max':>9} {'bend min':>9} "
            f"{'floquet':>8}  [microstrain]")
    lines += ["", head, "-" * len(head)]
    for p in points:
        if p.get("did_not_run"):
            lines.append(f"{_fmt(p.get('rpm')):>7} did not run: {p.get('error')}")
            continue
        for engine, e in (p.get("engines") or {}).items():
            gauges = e.get("gauges") or {"-": {}}
            for g, st in gauges.items():
                lines.append(f"{_fmt(p.get('rpm')):>7} {engine:<8} {g:<14} {str(e.get('status')):<10} "
                             f"{_fmt(st.get('bending_max_ue')):>9} {_fmt(st.get('bending_min_ue')):>9} "
                             f"{_fmt(e.get('floquet_max'), 3):>8}" + (f"  {e['error']}" if e.get("error") else "")
                             + ("  not steady" if e.get("steady") is False else "")
                             + (f"  unstable orbit ({e['orbit']})" if e.get("orbit") not in (None, "stable") else ""))
    if summary.get("parametric_resonance_rpm"):
        lines.append(f"parametric resonance (|Floquet multiplier| > 1) at {summary['parametric_resonance_rpm']} rpm")
    lines += unstable_orbit_lines(summary.get("unstable_orbits"))
    if summary.get("points_without_solution"):
        lines.append(f"no solution at {summary['points_without_solution']} rpm")
    lines += unsolved_lines(summary.get("unsolved_points"))
    if summary.get("points_not_steady"):
        lines.append(f"not steady at {summary['points_not_steady']} rpm (last two revolutions differ by more than "
                     "output.steady_tolerance): those peaks are a transient's, not a steady state's")
    for c in summary.get("resonance_candidates") or []:
        lines.append(f"resonance candidate: mode {c['mode']} x harmonic {c['harmonic']} at "
                     f"{c['rpm'][0]:.0f}-{c['rpm'][1]:.0f} rpm")
    return "\n".join(lines)


def unstable_orbit_lines(orbits: list | None) -> list:
    """A sweep's unstable periodic orbits (``summary["unstable_orbits"]``), grouped by kind: the
    speeds with their largest |Floquet multiplier|, and what the kind means (the summary's own
    text, from :data:`tmm_core.periodic.ORBIT_KINDS`)."""
    lines = []
    for kind in sorted({o["kind"] for o in orbits or []}):
        same = [o for o in orbits if o["kind"] == kind]
        at = ", ".join(f"{o['rpm']:g} rpm (|mu| = {o['mu_max']:.3g})" for o in same)
        lines.append(f"unstable orbit, {kind}: {at}" + (f"; {same[0]['meaning']}" if same[0].get("meaning") else ""))
    return lines


def unsolved_count(summary: dict) -> str:
    """``"; N of M points without a solution"`` for a sweep's one-line result ("" when none)."""
    u = summary.get("unsolved_points")
    return f"; {u['count']} of {u['of']} points without a solution" if u else ""


def unsolved_lines(unsolved: dict | None, shown: int = 3, limit: int = 200) -> list:
    """A sweep's points without a solution (``summary["unsolved_points"]``): each distinct reason
    once with its count (at most ``shown``, cut to ``limit`` characters), and what they mean."""
    if not unsolved:
        return []
    lines = [f"{unsolved['count']} of {unsolved['of']} points without a solution:"]
    for r in unsolved["reasons"][:shown]:
        e = r["error"] if len(r["error"]) <= limit else r["error"][:limit - 3] + "..."
        where = f"{r['rpm'][0]:g}" + (f" to {r['rpm'][-1]:g}" if len(r["rpm"]) > 1 else "")
        lines.append(f"  {r['count']} x {e} (at {where} rpm)")
    if len(unsolved["reasons"]) > shown:
        lines.append(f"  {len(unsolved['reasons']) - shown} other error(s): see summary.json")
    lines.append(f"  {unsolved['note']}")
    return lines


def uncertainty_table(summary: dict) -> str:
    """Band of the predicted peaks, the most influential parameter and the record check of a
    ``cosim uncertainty`` folder [microstrain]."""
    lines = [f"uncertainty of {summary.get('scenario')}  status {summary.get('status')}  "
             f"{summary.get('samples')} samples in {_fmt(summary.get('wall_time_s'))} s"]
    notice = status_notice(summary, kept="the band is computed when every sample has finished")
    if notice:
        lines.append(notice)
    if summary.get("error"):
        lines.append(f"error: {summary['error']}")
    for g, b in (summary.get("band") or {}).items():
        lo_max, hi_max = b.get("peak_max_range_ue") or (None, None)
        lo_min, hi_min = b.get("peak_min_range_ue") or (None, None)
        lines.append(f"  {g}: +peak {_fmt(lo_max)}..{_fmt(hi_max)} ue, -peak {_fmt(lo_min)}..{_fmt(hi_min)} ue; "
                     f"most influential: {(summary.get('most_influential') or {}).get(g)}")
    for r in summary.get("records") or []:
        lines.append(f"  record {r.get('title') or r.get('record')} {r.get('gauge')} {r.get('peak')}peak "
                     f"{_fmt(r.get('recorded_ue'))} ue: {'inside' if r.get('inside') else 'outside'} the band")
    if summary.get("failed_samples"):
        lines.append(f"  failed samples: {failed_samples_text(summary['failed_samples'])}")
    return "\n".join(lines)


def failed_samples_text(failed: list, shown: int = 3, limit: int = 200) -> str:
    """The failed samples ("sample i: error") as one short line: how many, and each distinct error
    once (at most ``shown`` of them, cut to ``limit`` characters) with its count. 130 samples
    failing alike printed a 67 kB line."""
    groups = {}
    for item in failed:
        head, _, error = str(item).partition(": ")
        groups.setdefault(error or head, []).append(head)
    parts = [f"{len(heads)} x {e if len(e) <= limit else e[:limit - 3] + '...'}"
             for e, heads in sorted(groups.items(), key=lambda kv: -len(kv[1]))[:shown]]
    more = f"; {len(groups) - shown} other error(s)" if len(groups) > shown else ""
    return f"{len(failed)}: " + "; ".join(parts) + more


def identification_table(result: dict) -> str:
    """The printed summary of an identification (the result of :func:`cosim.identify.identify`):
    its fit, the identified unknowns and the calibration and validation peaks [microstrain]."""
    lines = [f"identification on {', '.join(result['calibration_scenarios'])}: {result['status']}"]
    if result.get("error"):
        return "\n".join(lines + [f"error: {result['error']}"])
    st = result["statistics"]
    lines.append(f"chi^2 {st['chi2']:.3g} over {st['peaks']} peaks, {st['unknowns']} continuous unknowns "
                 f"(sigma: {result['sigma_model']['relative']:.0%} of the peak and "
                 f"{result['sigma_model']['absolute_ue']:g} ue)")
    for n, p in result["parameters"].items():
        if p.get("discrete"):
            lines.append(f"  {n:<18} {p['value']!s:>12}  (choice; cost per value {p['best_cost_per_value']})")
        else:
            flags = ", ".join(f for f, on in (("at a bound of its range", p["at_bound"]),
                                              ("not constrained by the records", not p["constrained"])) if on)
            lines.append(f"  {n:<18} {p['value']:>12.4g} +/- {p['sigma']:.2g} {p['unit']}  95 %: "
                         f"{p['interval95'][0]:.3g}..{p['interval95'][1]:.3g}" + (f"  [{flags}]" if flags else ""))
    for title, block in (("calibration", result.get("calibration", {})), ("validation", result.get("validation", {}))):
        for scn, gauges in block.items():
            for g, sides in gauges.items():
                cells = []
                for side, c in sides.items():
                    err = "n/a" if c["error"] is None else f"{c['error']:+.0%}"
                    sig = "" if not c.get("sigma_ue") else f" +/- {c['sigma_ue']:.0f}"
                    model = "n/a" if c["model_ue"] is None else f"{c['model_ue']:.0f}{sig}"
                    cells.append(f"{side} record {c['record_ue']:.0f} model {model} ({err})")
                lines.append(f"  {title:<11} {scn} {g}: " + "; ".join(cells))
    return "\n".join(lines)


def synthesis_table(record: dict) -> str:
    """The printed summary of ``cosim synthesize`` (:func:`cosim.synthesis.result_record`): lengths
    in the record's unit, angles [deg] from the ground line (crank pivot -> rocker pivot), CCW."""
    r = record
    lines = [f"four-bar synthesis, case {r['case']} (FE thesis Ch. III): {r['grashof']}, residual {r['residual']:.1e}",
             ", ".join(f"{k} {r[k]:.6g} {r['unit']}" for k in ("crank", "coupler", "rocker", "ground"))]
    for end, names in {"extended": ("phi2", "mu2", "theta1"), "folded": ("phi4", "mu4", "theta3")}.items():
        lines.append(f"{end + ' limit:':<16} crank angle {r[f'crank_angle_{end}_deg']:7.3f} deg, rocker angle "
                     f"{r[f'rocker_angle_{end}_deg']:7.3f} deg ("
                     + ", ".join(f"{k} {r[k + '_deg']:.3f}" for k in names) + ")")
    lines += [f"oscillation {r['oscillation_deg']:.3f} deg, time ratio {r['time_ratio']:.3f}; transmission angle "
              f"{r['transmission_min_deg']:.3f} deg (crank angle 0) to {r['transmission_max_deg']:.3f} deg (180 deg)",
              "angles in deg from the ground line (crank pivot -> rocker pivot), counter-clockwise"]
    if r.get("scenario"):
        lines.append(f"scenario written to {r['scenario']}")
    return "\n".join(lines)
