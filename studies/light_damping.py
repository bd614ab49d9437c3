"""Issue 34, item 1: why the transfer-matrix model (TMM) parts from exudyn at light damping and on
the resonance flank of the FE crank-rocker (rigid crank, prescribed speed), found by experiment.

Every case is a variant of the shipped scenario ``crank_rocker_373rpm`` made with
``Scenario.with_overrides`` (speed ``drive.speed``, damping ``links.coupler.damping.ratio`` and
``links.rocker.damping.ratio``, meshes and steps ``solver.*``); nothing is edited by hand.

Reference: exudyn (geometrically exact ANCF cables, generalized-alpha 0.9), started from rest and
run until its last two revolutions agree (``exudyn`` sub-command; results cached in
``studies/light_damping_exudyn.json`` with the per-revolution peaks, so the table can be rebuilt
without re-running it). Its mesh and step are refined (16 elements / 0.2 deg, the shipped
setting, against 32 / 0.1 deg) to show it converged.

TMM: the periodic steady state is found by Newton shooting (tmm_core.periodic), continued in the
damping ratio from 2 % (where the solver converges from its own start) down to the case's ratio,
each solve starting from the previous orbit. The Floquet multipliers of the orbit say whether time
marching can settle on it (all inside the unit circle) and how fast. Where the continuation
fails the case is marched in time (``march`` sub-command) and the revolution-to-revolution
change reported. Each candidate cause is a variant of the TMM (``VARIANTS``): step halved, mesh
doubled, integrator dissipation changed, second-order terms switched, rotating-frame terms off,
and the segments' exact strain or exact rotation (co-rotational) prototypes.

    python -m studies.light_damping exudyn [--elements 16 --step-deg 0.2] [--cases 373:0.5,...]
    python -m studies.light_damping tmm [--variants base,step,...] [--cases ...]
    python -m studies.light_damping march --case 373:0.5 [--variant base] [--revolutions 40]
    python -m studies.light_damping step-split [--case 241:0.5]
    python -m studies.light_damping frequencies
    python -m studies.light_damping multipliers [--cases 373:1] [--variant step8] [--elements 16]
    python -m studies.light_damping deflection [--cases 241:2,373:2]
    python -m studies.light_damping amplitude [--case 355:1] [--cranks 5,6,6.5,6.75,6.9,7]
    python -m studies.light_damping table      # the markdown table of docs/light_damping.md

Run heavy parts with ``nice``; the exudyn references take ~4 s per revolution at 16 elements.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
EXUDYN_CACHE = HERE / "light_damping_exudyn.json"
TMM_CACHE = HERE / "light_damping_tmm.json"
GAUGES = ("coupler_mid", "rocker_mid")

#: (rpm, damping ratio [%]) of the issue's cases, and the shipped setting for comparison.
CASES = ((373, 0.5), (373, 1.0), (373, 2.0), (241, 0.5), (241, 1.0), (365, 2.0), (381, 2.0))


def case_key(rpm, zeta) -> str:
    return f"{rpm:g}rpm_{zeta:g}%"


def parse_cases(text):
    if not text:
        return CASES
    return tuple((float(a), float(b)) for a, b in (c.split(":") for c in text.split(",")))


def scenario(rpm, zeta, overrides=None):
    """The FE rig at ``rpm`` with damping ratio ``zeta`` [%] on coupler and rocker."""
    from cosim.scenario import load
    o = {"drive.speed": f"{rpm:g} rpm", "links.coupler.damping.ratio": f"{zeta:g} %",
         "links.rocker.damping.ratio": f"{zeta:g} %"}
    o.update(overrides or {})
    return load("crank_rocker_373rpm").with_overrides(o)


def peaks(gauges, mask=slice(None)):
    """``{gauge: [bend max, bend min, axial max, axial min]}`` [microstrain]."""
    return {g: [float(x) * 1e6 for x in (b[mask].max(), b[mask].min(), a[mask].max(), a[mask].min())]
            for g, (b, a) in gauges.items()}


def per_revolution(angle, gauges):
    """Peaks of every complete revolution (list over revolutions)."""
    a = np.asarray(angle) - angle[0]
    rev = np.floor(a / (2 * math.pi) + 1e-9).astype(int)
    out = []
    for k in range(int(rev.max()) + 1):
        m = rev == k
        if m.sum() > 10:
            out.append(peaks(gauges, m))
    return out


def change_of(revs):
    """Largest change of any peak between the last two revolutions, relative to that gauge's
    bending peak-to-peak (the size the steady verdict measures changes against)."""
    if len(revs) < 2:
        return float("nan")
    a, b = revs[-1], revs[-2]
    return max(max(abs(x - y) for x, y in zip(a[g], b[g])) / (a[g][0] - a[g][1]) for g in a)


def load_json(path):
    return json.loads(path.read_text()) if path.exists() else {}


def save_json(path, data):
    path.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")


# -- exudyn reference -----------------------------------------------------------------------------
def run_exudyn(rpm, zeta, elements=16, step_deg=0.2, revolutions=40, start_angle=0.0):
    """exudyn from rest at crank ``start_angle`` [deg] for ``revolutions``."""
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    sc = scenario(rpm, zeta, {"solver.exudyn.elements": elements, "solver.exudyn.step": f"{step_deg:g} deg",
                              "drive.start_angle": f"{start_angle:g} deg"})
    t0 = time.time()
    r = run_prescribed(make_engine("exudyn"), sc, revolutions=revolutions)
    revs = per_revolution(r.crank_angle, r.gauges)
    return {"rpm": rpm, "zeta_pct": zeta, "elements": elements, "step_deg": step_deg, "revolutions": len(revs),
            "last": revs[-1], "change": change_of(revs), "per_revolution": revs, "wall_s": time.time() - t0}


def cmd_exudyn(args):
    cache = load_json(EXUDYN_CACHE)
    for rpm, zeta in parse_cases(args.cases):
        key = f"{case_key(rpm, zeta)}_{args.elements}el_{args.step_deg:g}deg" + \
            (f"_start{args.start_angle:g}deg" if args.start_angle else "")
        if key in cache and not args.force:
            continue
        res = run_exudyn(rpm, zeta, args.elements, args.step_deg, args.revolutions, args.start_angle)
        cache = load_json(EXUDYN_CACHE)
        cache[key] = res
        save_json(EXUDYN_CACHE, cache)
        print(key, {g: [round(x, 1) for x in v] for g, v in res["last"].items()}, f"change {res['change']:.2e}",
              f"{res['wall_s']:.0f} s", flush=True)
    return 0


# -- transfer-matrix model: periodic orbits continued in speed and damping -------------------------
#: The second-order (von Karman) segments, the TMM's model before the co-rotational ones.
SECOND_ORDER = ("shortening", "axial_force")
#: Candidate causes: each a change of the TMM against the shipped setting of the time ('base': 8
#: segments per link, 0.5 deg step, generalized-alpha rho_inf 0.9, second-order step with the
#: shortening from bending and the step's own axial force, rotating-frame terms on).
VARIANTS = {
    "base": ("the shipped TMM setting before issue 34 (second-order segments)", {}),
    "exact_strain": ("prototype: the segments' exact strain instead of the second-order one (numpy step)",
                     {"dynamic_terms": ("shortening", "axial_force", "exact_strain")}),
    "corotational": ("segments exact in their rotation (co-rotational; the default since issue 34), step halved "
                     "(0.25 deg)", {"dynamic_terms": ("shortening", "axial_force", "corotational"), "step_deg": 0.25}),
    "step": ("step halved (0.25 deg)", {"step_deg": 0.25}),
    "step8": ("step divided by 4 (0.125 deg)", {"step_deg": 0.125}),
    "mesh": ("mesh doubled (16 segments per link)", {"segments": 16}),
    "rho07": ("more numerical dissipation (rho_inf 0.7)", {"rho_inf": 0.7}),
    "no_shortening": ("second order: shortening from bending off", {"dynamic_terms": ("axial_force",)}),
    "no_rotating": ("rotating-frame terms off", {"coupling": (False, False, False)}),
    "no_coriolis": ("Coriolis term off", {"coupling": (False, True, True)}),
    "no_centrifugal": ("centrifugal term off", {"coupling": (True, False, True)}),
    "no_angular_acceleration": ("angular-acceleration term off", {"coupling": (True, True, False)}),
    "no_rotating_step": ("rotating-frame terms off, step halved (0.25 deg): does the step error live in them?",
                         {"coupling": (False, False, False), "step_deg": 0.25}),
}


def time_domain(rpm, zeta, spec, overrides=None):
    """``(TimeDomain, speed [rad/s], step [deg])`` of the FE rig variant ``spec`` (VARIANTS), with
    the scenario ``overrides`` (keys and values as :func:`scenario` takes them)."""
    from tmm_core import Coupling, TimeDomain
    from tmm_core.integrators import GeneralizedAlpha
    over = dict(overrides or {})
    if "segments" in spec:
        over["solver.tmm.segments"] = spec["segments"]
    sc = scenario(rpm, zeta, over)
    s = sc.tmm
    # The variants are of the second-order TMM, the shipped model (the co-rotational segments are
    # a variant of their own); explicit, so that the tables regenerate as measured whatever the
    # default becomes.
    extra = {"dynamic_terms": SECOND_ORDER, **{k: spec[k] for k in ("dynamic_terms", "backend") if k in spec}}
    extra.update(spec.get("td", {}))
    td = TimeDomain(sc.mechanism, integrator=GeneralizedAlpha(spec.get("rho_inf", 0.9)),
                    coupling=Coupling(*spec["coupling"]) if "coupling" in spec else s.coupling,
                    beam_column=s.beam_column, gravity=sc.gravity, gauges=sc.gauges,
                    axial_force=spec.get("axial_force", s.axial_force), **extra)
    return td, sc.drive.speed_rad_s, spec.get("step_deg", math.degrees(s.step_rad))


def periodic_orbit(td, speed, step_deg, x0=None, iterations=12):
    """The periodic orbit (:func:`tmm_core.periodic.periodic_steady_state`) from the state ``x0``
    (None: the solver's own start). Returns ``(state, {gauge: peaks}, multipliers, Newton
    iterations)``; the axial peaks are the gauges' own reading (between segment middles).
    (Before that reading existed, this study read the axial strain at a node as the mean of the
    two segments meeting there; the cached orbits keep those two extra peaks.)"""
    from tmm_core.periodic import ShootingOptions, periodic_steady_state
    p = periodic_steady_state(td, speed, step_deg=step_deg, shooting=ShootingOptions(1e-7, iterations),
                              initial_state=x0)
    return p.state, peaks(p.gauges), p.multipliers, p.info.get("newton_iterations", 0)


def continuation_path(rpm, zeta, start=(373.0, 2.0)):
    """Points (rpm, zeta) from ``start``: speed first at 2 % (steps of at most 4 rpm), then the
    damping down (each step at most 25 % of the ratio)."""
    path, (r, z) = [start], start
    while abs(r - rpm) > 1e-9:
        r = r + max(-4.0, min(4.0, rpm - r))
        path.append((r, z))
    while z > zeta + 1e-9:
        z = max(zeta, z * 0.8)
        path.append((rpm, z))
    return path


def tmm_case(rpm, zeta, spec, log=print):
    """The TMM's periodic orbit at (rpm, zeta) for variant ``spec``, continued from 373 rpm / 2 %;
    a failed step is retried from the last orbit with the step halved (down to 1/8). Returns a
    dict with the peaks, the largest multiplier modulus, and where the continuation stopped."""
    from tmm_core.errors import TMMError
    path = continuation_path(rpm, zeta)
    x0, last, res = None, None, None
    i, t0 = 0, time.time()
    target = path[0]
    while True:
        try:
            td, speed, step = time_domain(target[0], target[1], spec)
            x0n, pk, mu, its = periodic_orbit(td, speed, step, x0)
        except (TMMError, np.linalg.LinAlgError) as exc:
            if last is None or abs(target[1] - last[1]) < 0.02 * last[1] and abs(target[0] - last[0]) < 0.5:
                return {"ok": False, "stopped_at": last, "failed_at": list(target), "error": str(exc)[:300],
                        "last": res, "wall_s": time.time() - t0}
            target = ((target[0] + last[0]) / 2, (target[1] + last[1]) / 2)
            continue
        x0, last = x0n, target
        res = {"rpm": target[0], "zeta_pct": target[1], "peaks": pk, "mu_max": float(np.abs(mu[0])),
               "mu": [[float(m.real), float(m.imag)] for m in mu[:4]], "newton": its}
        log(f"    {target[0]:6.1f} rpm {target[1]:5.3f} %  rocker {pk['rocker_mid'][0]:7.1f} {pk['rocker_mid'][1]:7.1f}  "
            f"|mu| {abs(mu[0]):.4f}  newton {its}")
        if abs(target[0] - rpm) < 1e-9 and abs(target[1] - zeta) < 1e-9:
            return {"ok": True, **res, "wall_s": time.time() - t0}
        i = next(j for j, p in enumerate(path) if p == target) if target in path else i
        # the next point of the path beyond the current one
        after = path[path.index(target) + 1] if target in path else next(
            p for p in path if (p[1] < target[1] - 1e-12 and abs(p[0] - rpm) < 1e-9) or
            (abs(p[1] - path[0][1]) < 1e-12 and abs(p[0] - rpm) < abs(target[0] - rpm) - 1e-9))
        target = after


def cmd_tmm(args):
    cache = load_json(TMM_CACHE)
    for name in args.variants.split(","):
        label, spec = VARIANTS[name]
        for rpm, zeta in parse_cases(args.cases):
            key = f"{name}|{case_key(rpm, zeta)}"
            if key in cache and not args.force:
                continue
            print(f"{name} ({label}) at {rpm:g} rpm, {zeta:g} %", flush=True)
            res = tmm_case(rpm, zeta, spec, log=lambda m: print(m, flush=True))
            cache = load_json(TMM_CACHE)
            cache[key] = res
            save_json(TMM_CACHE, cache)
    return 0


# -- time marching: what a run that does not settle shows -----------------------------------------
def march(rpm, zeta, spec, revolutions=40):
    """The TMM marched from its quasi-static start: peaks per revolution, the last change and
    the trend (cosim.metrics.revolution_trend) over the last revolutions."""
    from cosim.metrics import revolution_trend
    from tmm_core.revolution import revolution_change
    from tmm_core import CrankMotion
    td, speed, step = time_domain(rpm, zeta, spec)
    t0 = time.time()
    r = td.run(CrankMotion.constant_speed(speed, step_deg=step, revolutions=revolutions), start="quasi_static",
               record_displacements=False)
    revs = per_revolution(r.crank_angle, r.gauges)
    signals = [r.drive_torque] + [b for b, _ in r.gauges.values()]
    change = revolution_change(r.crank_angle, signals)
    # What a run that is not steady shows (as cosim.metrics.steadiness reports it).
    trend = revolution_trend(r.crank_angle, signals) if not change < 5e-3 else None
    lo = min(v["rocker_mid"][1] for v in revs[len(revs) // 2:])
    hi = max(v["rocker_mid"][1] for v in revs[len(revs) // 2:])
    return {"revolutions": len(revs), "change": change, "last": revs[-1],
            "rocker_min_range_second_half": [lo, hi], "trend": trend and {k: trend[k] for k in ("kind", "text")},
            "per_revolution": revs, "wall_s": time.time() - t0}


def cmd_march(args):
    cache = load_json(TMM_CACHE)
    rpm, zeta = parse_cases(args.case)[0]
    res = march(rpm, zeta, VARIANTS[args.variant][1], args.revolutions)
    cache = load_json(TMM_CACHE)
    cache[f"march|{args.variant}|{case_key(rpm, zeta)}"] = res
    save_json(TMM_CACHE, cache)
    print(f"{args.variant} at {rpm:g} rpm {zeta:g} %: change {100 * res['change']:.2f} %, rocker min over the second "
          f"half {res['rocker_min_range_second_half'][0]:.0f}..{res['rocker_min_range_second_half'][1]:.0f} ue; "
          f"{res['trend'] and res['trend']['text']}")
    return 0


# -- the tables of docs/light_damping.md ----------------------------------------------------------
PEAK_NAMES = ("bend max", "bend min", "axial max", "axial min")


def reference(rpm, zeta):
    """The converged exudyn peaks of a case: 32 elements / 0.1 deg where run, else 16 / 0.2 deg."""
    cache = load_json(EXUDYN_CACHE)
    for tag in ("32el_0.1deg", "16el_0.2deg"):   # (a start at another angle is not a reference)
        r = cache.get(f"{case_key(rpm, zeta)}_{tag}")
        if r is not None:
            return r["last"], tag
    return None, None


def errors(pk, ref, n=2):
    """Relative errors [%] of the first ``n`` peaks of every gauge."""
    return {g: [100 * (pk[g][i] / ref[g][i] - 1) for i in range(n)] for g in GAUGES}


def worst(err):
    return max((abs(x), x) for v in err.values() for x in v)[1]


def cmd_table(args):
    ex, tm = load_json(EXUDYN_CACHE), load_json(TMM_CACHE)
    out = ["### The candidates: what each TMM variant changes", "", "| variant | change against the shipped TMM |",
           "|---|---|"] + [f"| {k} | {label} |" for k, (label, _) in VARIANTS.items()]
    out += ["", "### exudyn references (from rest, until the last two revolutions agree)", "",
           "| case | mesh / step | revs | change | coupler bend max / min | rocker bend max / min | "
           "coupler axial max / min | rocker axial max / min |", "|---|---|---|---|---|---|---|---|"]
    for key in sorted(ex, key=lambda k: (-ex[k]["zeta_pct"], ex[k]["rpm"], ex[k]["elements"])):
        r = ex[key]
        c, k = r["last"]["coupler_mid"], r["last"]["rocker_mid"]
        start = f", from rest at {key.split('_start')[1].replace('deg', ' deg')}" if "_start" in key else ""
        out.append(f"| {r['rpm']:g} rpm, {r['zeta_pct']:g} %{start} | {r['elements']} el / {r['step_deg']:g} deg | "
                   f"{r['revolutions']} | {r['change']:.1e} | {c[0]:.0f} / {c[1]:.0f} | {k[0]:.0f} / {k[1]:.0f} | "
                   f"{c[2]:.1f} / {c[3]:.1f} | {k[2]:.1f} / {k[3]:.1f} |")
    out += ["", "### TMM periodic orbits against exudyn (peak errors, %; against exudyn's finest run of the case: "
            "32 el / 0.1 deg where it exists, else 16 el / 0.2 deg)", "",
            "| variant | case | orbit | largest multiplier | coupler bend max / min | rocker bend max / min | "
            "coupler axial max / min | rocker axial max / min |", "|---|---|---|---|---|---|---|---|"]
    for name, (label, _) in VARIANTS.items():
        for rpm, zeta in CASES:
            r = tm.get(f"{name}|{case_key(rpm, zeta)}")
            if r is None:
                continue
            ref, _ = reference(rpm, zeta)
            if not r["ok"]:
                stop = r.get("stopped_at")
                where = f"none below {stop[1]:.3g} % (continued from 2 %)" if stop else "not found"
                last = r.get("last")
                mu = f"{last['mu_max']:.3f} at {last['zeta_pct']:.3g} %" if last else "-"
                out.append(f"| {name} | {rpm:g} rpm, {zeta:g} % | {where} | {mu} | | | | |")
                continue
            e = errors(r["peaks"], ref, 4) if ref else None
            cells = ["-"] * 4 if e is None else [
                f"{e['coupler_mid'][0]:+.1f} / {e['coupler_mid'][1]:+.1f}", f"{e['rocker_mid'][0]:+.1f} / {e['rocker_mid'][1]:+.1f}",
                f"{e['coupler_mid'][2]:+.1f} / {e['coupler_mid'][3]:+.1f}", f"{e['rocker_mid'][2]:+.1f} / {e['rocker_mid'][3]:+.1f}"]
            out.append(f"| {name} | {rpm:g} rpm, {zeta:g} % | steady | {r['mu_max']:.3f} | " + " | ".join(cells) + " |")
    marches = {k: v for k, v in tm.items() if k.startswith("march|")}
    if marches:
        out += ["", "### TMM marched in time (from the quasi-static start)", "", "| variant | case | revolutions | "
                "last change | rocker bend min, second half | verdict, or the last revolution's bending errors "
                "(coupler, rocker) % |", "|---|---|---|---|---|---|"]
        for k, v in marches.items():
            _, name, case = k.split("|")
            lo, hi = v["rocker_min_range_second_half"]
            rpm, zeta = (float(x) for x in case.replace("rpm", "").replace("%", "").split("_"))
            ref, _ = reference(rpm, zeta)
            if v["trend"] is None and ref is not None:
                e = errors(v["last"], ref, 2)
                verdict = (f"steady: {e['coupler_mid'][0]:+.1f} / {e['coupler_mid'][1]:+.1f}, "
                           f"{e['rocker_mid'][0]:+.1f} / {e['rocker_mid'][1]:+.1f}")
            else:
                verdict = v["trend"]["text"] if v["trend"] else "steady"
            out.append(f"| {name} | {case} | {v['revolutions']} | {100 * v['change']:.2g} % | {lo:.0f} .. {hi:.0f} ue | "
                       f"{verdict} |")
    print("\n".join(out))
    return 0


# -- where the step error lives: the linear model's step sensitivity ------------------------------
def cmd_step_split(args):
    """Step sensitivity of the linear step (quasi-static axial force, no second-order
    pseudo-loads) against the second-order one at a case where both apply (241 rpm: the rocker
    stays well below its Euler load): periodic orbits at 0.5, 0.25 and 0.125 deg."""
    from tmm_core.periodic import periodic_steady_state
    rpm, zeta = parse_cases(args.case)[0]
    ref, _ = reference(rpm, zeta)
    cache = load_json(TMM_CACHE)
    rows = ["| axial force model | step | coupler bend max / min | rocker bend max / min | errors (coupler, rocker) % |",
            "|---|---|---|---|---|"]
    for model in ("quasi_static", "dynamic"):
        for step in (0.5, 0.25, 0.125):
            key = f"stepsplit|{model}|{step:g}deg|{case_key(rpm, zeta)}"
            if key not in cache:
                td, speed, _ = time_domain(rpm, zeta, {"axial_force": model, "step_deg": step})
                cache[key] = peaks(periodic_steady_state(td, speed, step_deg=step).gauges)
                save_json(TMM_CACHE, cache)
            pk = cache[key]
            e = errors(pk, ref, 2)
            rows.append(f"| {model} | {step:g} deg | {pk['coupler_mid'][0]:.1f} / {pk['coupler_mid'][1]:.1f} | "
                        f"{pk['rocker_mid'][0]:.1f} / {pk['rocker_mid'][1]:.1f} | "
                        f"{e['coupler_mid'][0]:+.1f} / {e['coupler_mid'][1]:+.1f}, "
                        f"{e['rocker_mid'][0]:+.1f} / {e['rocker_mid'][1]:+.1f} |")
    print("\n".join(rows))
    return 0


# -- the linear models: natural frequencies at rest ------------------------------------------------
def cmd_frequencies(args):
    """First two natural frequencies [Hz] of the rig at rest, crank held, at a few crank angles:
    exudyn's constrained eigenvalues (16 and 32 elements) and the TMM's frequency search (8 and
    16 segments)."""
    from cosim.engines.exudyn import natural_frequencies
    from tmm_core.frequencies import fourbar_frequencies
    print("| crank angle [rad] | exudyn 16 el | exudyn 32 el | TMM 8 seg | TMM 16 seg |\n|---|---|---|---|---|")
    for angle in (0.0, 1.0, 2.5, 4.5):
        cells = [natural_frequencies(scenario(373, 2.0, {"solver.exudyn.elements": el}), angle, 2) for el in (16, 32)]
        cells += [fourbar_frequencies(scenario(373, 2.0, {"solver.tmm.segments": seg}).mechanism, np.array([angle]), 2,
                                      1000.0)[0] for seg in (8, 16)]
        print(f"| {angle:g} | " + " | ".join(" / ".join(f"{f:.2f}" for f in c) for c in cells) + " |")
    return 0


# -- the dynamics about the orbit: Floquet multipliers read off a transient ------------------------
def revolution_samples(angle, gauges):
    """``[revolution, sample]``: every gauge's bending and axial strain [-] at the same crank angles
    in each complete revolution, each channel scaled by its last revolution's peak-to-peak."""
    a = np.asarray(angle) - angle[0]
    per_rev = int(round(2 * math.pi / np.median(np.diff(a))))
    k = len(a) // per_rev
    channels = [np.asarray(x)[:k * per_rev].reshape(k, per_rev) for pair in gauges.values() for x in pair]
    return np.hstack([c / np.ptp(c[-1]) for c in channels])


def transient_multipliers(samples, rank=6, first=3, floor=1e-9):
    """The Floquet multipliers that dominate the approach to the periodic orbit, read off a
    transient (:func:`tmm_core.revolution_dmd.dominant_multipliers` on the revolutions from
    ``first`` on). Returns the multipliers, largest first, and the revolutions used."""
    from tmm_core.revolution_dmd import dominant_multipliers
    mu, read = dominant_multipliers(samples[first:], rank, floor)
    return mu, (first, first + read + 1)


def cmd_multipliers(args):
    """The largest Floquet multipliers of both engines about their steady orbit, read the same way
    off each engine's transient from rest (exudyn) or from the quasi-static start (TMM), and the
    TMM's own from its monodromy (a check of the reading)."""
    from tmm_core import CrankMotion
    cache = load_json(TMM_CACHE)
    for rpm, zeta in parse_cases(args.cases):
        key = f"multipliers|{case_key(rpm, zeta)}"
        res = cache.get(key, {})
        exudyn = f"exudyn_{args.elements}el_{args.exudyn_step_deg:g}deg"
        if exudyn not in res or args.force:
            from cosim.engines import make_engine
            from cosim.master import run_prescribed
            sc = scenario(rpm, zeta, {"solver.exudyn.elements": args.elements,
                                      "solver.exudyn.step": f"{args.exudyn_step_deg:g} deg"})
            r = run_prescribed(make_engine("exudyn"), sc, revolutions=args.revolutions)
            samples = revolution_samples(r.crank_angle, r.gauges)
            mu, used = transient_multipliers(samples, args.rank, args.first)
            res[exudyn] = {"mu": [[float(m.real), float(m.imag)] for m in mu], "revolutions": list(used)}
        spec = VARIANTS[args.variant][1]
        tag = f"tmm_{args.variant}"
        if tag not in res or args.force:
            td, speed, step = time_domain(rpm, zeta, spec)
            r = td.run(CrankMotion.constant_speed(speed, step_deg=step, revolutions=args.revolutions),
                       start="quasi_static", record_displacements=False)
            mu, used = transient_multipliers(revolution_samples(r.crank_angle, r.gauges), args.rank, args.first)
            orbit = cache.get(f"{args.variant}|{case_key(rpm, zeta)}", {})
            res[tag] = {"mu": [[float(m.real), float(m.imag)] for m in mu], "revolutions": list(used),
                        "monodromy": orbit.get("mu")}
        cache = load_json(TMM_CACHE)
        cache[key] = res
        save_json(TMM_CACHE, cache)
        for name, v in res.items():
            show = lambda ms: " ".join(f"{abs(complex(*m)):.3f}@{math.degrees(np.angle(complex(*m))):+.1f}"
                                       for m in ms[:4])
            mono = f"   monodromy {show(v['monodromy'])}" if v.get("monodromy") else ""
            print(f"{case_key(rpm, zeta)} {name:12s} transient {show(v['mu'])} (revolutions {v['revolutions']}){mono}")
    return 0


def cmd_deflection(args):
    """Each link's largest deflection from its chord [mm] and largest section rotation against
    its rigid-body frame [deg] over the last of ``--revolutions`` revolutions of the second-order
    TMM ('base') from its quasi-static start, at each speed of ``--cases``: how far the elastic motion goes
    beyond small rotations."""
    from tmm_core import CrankMotion
    for rpm, zeta in parse_cases(args.cases):
        td, speed, step = time_domain(rpm, zeta, VARIANTS["base"][1])
        crank = CrankMotion.constant_speed(speed, step_deg=step, revolutions=args.revolutions)
        r = td.run(crank, start="quasi_static")
        last = crank.steps_per_revolution()
        for link in td.model.links:
            q = r.displacements[link.name][-last:]                        # (steps, nodes, (u, w, theta))
            x = link.stations / link.stations[-1]
            chord = q[:, :1, 1] + (q[:, -1:, 1] - q[:, :1, 1]) * x
            print(f"{case_key(rpm, zeta)} {link.name:8s} length {link.length_m * 1e3:4.0f} mm: deflection from "
                  f"the chord up to {np.abs(q[:, :, 1] - chord).max() * 1e3:5.2f} mm, sections turned up to "
                  f"{math.degrees(np.abs(q[:, :, 2]).max()):5.2f} deg")
    return 0


# -- the same dynamics at smaller amplitude: the crank shortened ---------------------------------
#: Crank lengths [in] of the amplitude experiment: the shipped 7 in and shorter cranks, which move
#: the linkage away from its 18 deg toggle and shrink every inertia load and deflection.
CRANKS_IN = (5.0, 6.0, 6.5, 6.75, 6.9, 7.0)


def amplitude_case(rpm, zeta, crank_in, revolutions=30):
    """Both engines from their starts at ``rpm`` / ``zeta`` [%] with the crank ``crank_in`` [in]
    long: the multipliers read off each transient (:func:`transient_multipliers`), exudyn's largest
    segment rotation against the chord per link (:func:`cosim.metrics.link_rotations`) and both
    engines' bending peaks over the last revolution [microstrain]. exudyn at 16 elements / 0.2
    deg, the TMM at 0.125 deg (its step converged: VARIANTS['step8']); each run's last
    revolution-to-revolution change (:func:`change_of`) says whether it settled."""
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    from cosim.metrics import last_revolution, link_rotations
    from tmm_core import CrankMotion
    over = {"links.crank.length": f"{crank_in:g} in"}
    sc = scenario(rpm, zeta, {**over, "solver.exudyn.elements": 16, "solver.exudyn.step": "0.2 deg"})
    ex = run_prescribed(make_engine("exudyn"), sc, revolutions=revolutions)
    td, speed, step = time_domain(rpm, zeta, VARIANTS["step8"][1], over)
    tm = td.run(CrankMotion.constant_speed(speed, step_deg=step, revolutions=revolutions), start="quasi_static",
                record_displacements=False)

    def bending_peaks(run):
        last = last_revolution(run.crank_angle)
        return {g: [float(b[last].max()) * 1e6, float(b[last].min()) * 1e6] for g, (b, _) in run.gauges.items()}

    out = {"rotation_deg": link_rotations(ex)}
    for name, run in (("exudyn", ex), ("tmm", tm)):
        mu, _ = transient_multipliers(revolution_samples(run.crank_angle, run.gauges))
        out[name] = {"mu": [[float(m.real), float(m.imag)] for m in mu], "peaks_ue": bending_peaks(run),
                     "change": change_of(per_revolution(run.crank_angle, run.gauges))}
    return out


def cmd_amplitude(args):
    """The multiplier comparison of ``multipliers`` at one speed and damping with the crank
    shortened: how the engines' difference grows with the elastic rotations (cached)."""
    rpm, zeta = parse_cases(args.case)[0]
    for crank in (float(c) for c in args.cranks.split(",")):
        key = f"amplitude|{case_key(rpm, zeta)}|crank{crank:g}in"
        cache = load_json(TMM_CACHE)
        if key not in cache or args.force:
            res = amplitude_case(rpm, zeta, crank, args.revolutions)
            cache = load_json(TMM_CACHE)
            cache[key] = res
            save_json(TMM_CACHE, cache)
        res = cache[key]
        mu = {e: complex(*res[e]["mu"][0]) for e in ("exudyn", "tmm")}
        worst = max(abs(t / x - 1.0) for g in res["exudyn"]["peaks_ue"]
                    for t, x in zip(res["tmm"]["peaks_ue"][g], res["exudyn"]["peaks_ue"][g]))
        print(f"| {crank:g} | {res['rotation_deg']['rocker']:.2f} / {res['rotation_deg']['coupler']:.2f} | "
              + " | ".join(f"{abs(m):.3f} at {math.degrees(abs(np.angle(m))):.1f} deg" for m in mu.values())
              + f" | {math.degrees(abs(np.angle(mu['tmm'])) - abs(np.angle(mu['exudyn']))):+.1f} | "
              f"{100 * worst:.1f} % | {res['exudyn']['change']:.0e} / {res['tmm']['change']:.0e} |")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("exudyn", help="exudyn reference runs (cached)")
    e.add_argument("--cases", default="")
    e.add_argument("--elements", type=int, default=16)
    e.add_argument("--step-deg", type=float, default=0.2)
    e.add_argument("--revolutions", type=float, default=40)
    e.add_argument("--force", action="store_true")
    e.add_argument("--start-angle", type=float, default=0.0, help="crank angle of the start from rest [deg]")
    e.set_defaults(func=cmd_exudyn)
    t = sub.add_parser("tmm", help="TMM periodic orbits of the variants (cached)")
    t.add_argument("--cases", default="")
    t.add_argument("--variants", default=",".join(VARIANTS))
    t.add_argument("--force", action="store_true")
    t.set_defaults(func=cmd_tmm)
    m = sub.add_parser("march", help="march the TMM in time and say what the response does")
    m.add_argument("--case", default="373:0.5")
    m.add_argument("--variant", default="base")
    m.add_argument("--revolutions", type=float, default=40)
    m.set_defaults(func=cmd_march)
    sp = sub.add_parser("step-split", help="step sensitivity of the linear step against the second-order one")
    sp.add_argument("--case", default="241:0.5")
    sp.set_defaults(func=cmd_step_split)
    fr = sub.add_parser("frequencies", help="natural frequencies at rest of both engines")
    fr.set_defaults(func=cmd_frequencies)
    mu = sub.add_parser("multipliers", help="the largest Floquet multipliers of both engines, read off transients")
    mu.add_argument("--cases", default="373:1")
    mu.add_argument("--variant", default="step8", help="the TMM variant (VARIANTS)")
    mu.add_argument("--elements", type=int, default=16)
    mu.add_argument("--exudyn-step-deg", type=float, default=0.2)
    mu.add_argument("--revolutions", type=float, default=30)
    mu.add_argument("--rank", type=int, default=6)
    mu.add_argument("--first", type=int, default=3, help="the first revolution the reading uses")
    mu.add_argument("--force", action="store_true")
    mu.set_defaults(func=cmd_multipliers)
    de = sub.add_parser("deflection", help="the links' largest deflection and section rotation")
    de.add_argument("--cases", default="241:2,373:2")
    de.add_argument("--revolutions", type=float, default=8)
    de.set_defaults(func=cmd_deflection)
    am = sub.add_parser("amplitude", help="the multiplier comparison with the crank shortened (smaller rotations)")
    am.add_argument("--case", default="355:1")
    am.add_argument("--cranks", default=",".join(f"{c:g}" for c in CRANKS_IN), help="crank lengths [in]")
    am.add_argument("--revolutions", type=float, default=30)
    am.add_argument("--force", action="store_true")
    am.set_defaults(func=cmd_amplitude)
    tb = sub.add_parser("table", help="print the markdown tables from the cached results")
    tb.set_defaults(func=cmd_table)
    args = ap.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
