"""Physics flags of a run: what its peaks mean that a table of strains does not say, written per
engine into summary.json (``engines.<engine>.flags``) and shown under the console's table.

Each flag is ``{"kind", "message", "value", "threshold"}``; the message names the link, gauge or
mode, its value and the threshold. Kinds:

* ``buckling``: a gauged link's axial compression (its ``axial_min_ue`` times E A) against its own
  Euler load (:func:`tmm_core.closed_forms.euler_load_N`; the crank clamped-free at its shaft, every
  other link pinned-pinned), at :data:`BUCKLING_FRACTIONS` of it;
* ``transmission``: a four-bar passing near toggle or a change point (its transmission angle range,
  ``summary["linkage"]``, within :data:`TOGGLE_DEG` or :data:`CHANGE_POINT_DEG` of 0 or 180 deg);
* ``resonance``: a natural frequency within :data:`RESONANCE_BAND` of a harmonic k = 1 ..
  :data:`HARMONICS` of the crank speed: each flexible link's own first bending mode (closed form)
  and, for four-bars, the linkage's modes over a revolution (:func:`cosim.resonance.frequency_map`);
* ``step``: the transfer-matrix step near such a resonance of a link's own mode, where its
  integrator's period error, amplified by the resonance at the link's damping, moves the resonant
  response by :data:`STEP_ERROR_FRACTION` or more (:func:`step_flags`);
* ``rigid_model``: the rigid engine's peak bending more than :data:`RIGID_FACTOR` times off every
  flexible engine's at the same gauge.

Owns: the flags' thresholds and texts. Boundaries: pure functions of (scenario, summary), except
:func:`attach_flags` which writes them into the summary; the closed forms live in tmm_core.
"""
from __future__ import annotations

import logging
import math

import numpy as np
from tmm_core import FourBarMechanism
from tmm_core.closed_forms import euler_load_N, first_bending_frequency_Hz, resonance_sensitivity
from tmm_core.fourbar_limits import grashof_class
from tmm_core.integrators import get_integrator, numerical_frequency

from .engines import is_rigid
from .resonance import frequency_map

log = logging.getLogger(__name__)

#: Fractions of a link's Euler load that are flagged: at 50 % a beam-column's bending deflection is
#: amplified by 1 / (1 - P/P_cr) = 2 (the strains are no longer those of a stiff link); at 100 % the
#: link would buckle (a geometrically exact model's strains then grow without the load's growing).
BUCKLING_FRACTIONS = (0.5, 1.0)
#: A transmission angle within this of 0 or 180 deg is near toggle: the coupler pushes the rocker
#: nearly along it, joint forces grow as 1 / sin(mu) (2.9x those at 90 deg) and small clearances or
#: compliance change the motion (design practice keeps mu within 40-140 deg).
TOGGLE_DEG = 20.0
#: Within this the links are nearly in line (a change point, s + l = p + q, reaches 0): the branch
#: the linkage follows is undetermined there.
CHANGE_POINT_DEG = 5.0
#: Harmonics of the crank speed checked: near toggle a linkage's inertia loads keep their higher
#: harmonics (the FE rig at 373 rpm, rigid model: the 10th-15th carry 17-3 % of the largest).
HARMONICS = 15
#: A mode within this fraction of a harmonic: a 2 %-damped mode amplifies it at least
#: 1 / (1 - 0.95^2) = 10x, enough for a weak harmonic to dominate the response.
RESONANCE_BAND = 0.05
#: The step's period error times the resonance's sensitivity (the predicted shift of the resonant
#: response, :func:`step_flags`) flagged from this fraction, and the shift the suggested step keeps.
STEP_ERROR_FRACTION, STEP_ERROR_TARGET = 0.01, 0.005
#: The rigid model's peak bending this many times off every flexible engine's: the elastic
#: response is then larger than the rigid-body load's own strain.
RIGID_FACTOR = 2.0
#: Crank angles of the linkage's frequency map (from the drive's start angle); a coarse bisection
#: is enough for a flag (relative tolerance).
_MAP_ANGLES, _MAP_RTOL = 12, 1e-3
#: Wall-time bound [s] of that map (fewer crank angles when it would take longer).
MAP_SECONDS = 45.0


def flag(kind: str, message: str, value: float, threshold: float) -> dict:
    return {"kind": kind, "message": message, "value": float(value), "threshold": float(threshold)}


def end_conditions(mechanism, link) -> str:
    """The link's end conditions for its closed forms: the crank is clamped to its shaft with a
    pin at its tip, which may move across it (clamped-free, the lower bound); every other link is
    pinned at both ends."""
    return "clamped-free" if link is getattr(mechanism, "crank", None) else "pinned-pinned"


def _links(sc) -> dict:
    try:
        return {link.name: link for link in sc.mechanism.links()}
    except Exception:              # a mechanism without links() (a static structure)
        return {}


def buckling_flags(sc, gauges: dict) -> list:
    """Per gauged link, the worst gauge's compression P = -E A eps_axial_min [N] (one engine's
    ``gauges`` summary [µε]) against the link's Euler load; flagged at the highest of
    :data:`BUCKLING_FRACTIONS` it reaches."""
    links, where = _links(sc), {g.name: g.link for g in sc.gauges}
    worst = {}
    for g, stats in (gauges or {}).items():
        link = links.get(where.get(g))
        eps = stats.get("axial_min_ue")
        if link is None or eps is None or not eps < 0:
            continue
        mat, sec = link.material, link.section
        support = end_conditions(sc.mechanism, link)
        P = -eps * 1e-6 * mat.E_Pa * sec.area_m2
        Pcr = euler_load_N(mat.E_Pa * sec.inertia_m4, link.length_m, support)
        if P / Pcr > worst.get(link.name, (0.0,))[0]:
            worst[link.name] = (P / Pcr, g, eps, P, Pcr, support)
    out = []
    for name, (ratio, g, eps, P, Pcr, support) in worst.items():
        reached = [f for f in BUCKLING_FRACTIONS if ratio >= f]
        if not reached:
            continue
        what = "at or beyond its buckling load" if reached[-1] >= 1 else "approaching its buckling load"
        out.append(flag("buckling", f"buckling: the {name} is {what}: {P:.4g} N compression at {g} "
                                    f"(axial {eps:.1f} µε) = {100 * ratio:.0f} % of its {support} Euler load "
                                    f"{Pcr:.4g} N (flagged from {100 * reached[-1]:.0f} %)", ratio, reached[-1]))
    return out


def transmission_flags(sc, linkage: dict | None) -> list:
    """A four-bar near toggle or a change point, from the summary's ``linkage`` (transmission angle
    range [deg]) or, where that could not be made, from the Grashof class of its geometry."""
    if not isinstance(sc.mechanism, FourBarMechanism):
        return []
    g = sc.mechanism.geometry
    kind = grashof_class(g.crank, g.coupler, g.rocker, g.ground)
    if "change point" in kind:
        return [flag("transmission", f"change point: the four-bar is a {kind} (shortest + longest link = the "
                                     "other two): its links fall in line once a revolution (transmission angle "
                                     f"0 or 180 deg, threshold {CHANGE_POINT_DEG:g} deg) and the branch it "
                                     "follows there is undetermined", 0.0, CHANGE_POINT_DEG)]
    lk = linkage or {}
    lo, hi = lk.get("transmission_min_deg"), lk.get("transmission_max_deg")
    if lo is None or hi is None:
        return []
    near = min(lo, 180.0 - hi)
    where = (f"minimum transmission angle {lo:.1f} deg" if lo <= 180.0 - hi
             else f"maximum transmission angle {hi:.1f} deg")
    if near < CHANGE_POINT_DEG:
        return [flag("transmission", f"near a change point: {where}, within {CHANGE_POINT_DEG:g} deg of the links "
                                     "falling in line; the motion there depends on clearances and compliance",
                     near, CHANGE_POINT_DEG)]
    if near < TOGGLE_DEG:
        return [flag("transmission", f"near toggle: {where}, within {TOGGLE_DEG:g} deg of 0/180 deg: joint forces "
                                     f"grow as 1/sin (x{1 / math.sin(math.radians(near)):.1f} of those at 90 deg) "
                                     "and the inertia loads keep high harmonics", near, TOGGLE_DEG)]
    return []


def link_modes(sc) -> list:
    """Each flexible link's own first bending mode [Hz] (closed form, uniform span without its
    point masses, :func:`end_conditions`): ``[{"what", "band_Hz": (f, f)}]``."""
    out = []
    for name, link in _links(sc).items():
        mu = link.material.density_kg_m3 * link.section.area_m2
        if link.rigid or not mu > 0:
            continue
        support = end_conditions(sc.mechanism, link)
        f = first_bending_frequency_Hz(link.material.E_Pa * link.section.inertia_m4, mu, link.length_m, support)
        out.append({"what": f"the {name}'s own first bending mode ({support}, closed form) at {f:.1f} Hz",
                    "band_Hz": (f, f), "link": link, "f_Hz": f})
    return out


def linkage_modes(sc, rpm: float, progress: bool = False) -> list:
    """A four-bar's natural frequencies [Hz] up to the highest that can be flagged, as bands over
    :data:`_MAP_ANGLES` crank angles (:func:`cosim.resonance.frequency_map`, bounded to
    :data:`MAP_SECONDS`; ``progress``: a bar); [] for other linkages or if the map cannot be made
    (seconds on a four-bar)."""
    if not isinstance(sc.mechanism, FourBarMechanism) or not rpm > 0:
        return []
    f_max = HARMONICS * rpm / 60 * (1 + RESONANCE_BAND)
    try:
        f = frequency_map(sc, n_angles=_MAP_ANGLES, n_modes=4, f_max_Hz=f_max, rtol=_MAP_RTOL, progress=progress,
                          max_seconds=MAP_SECONDS)["f_Hz"]
    except Exception as exc:         # a flag must never lose the run
        log.debug("no linkage frequency map for the physics flags: %s", exc)
        return []
    out = []
    for mode in range(f.shape[1]):
        col = f[:, mode][np.isfinite(f[:, mode])]
        if len(col):
            lo, hi = float(col.min()), float(col.max())
            out.append({"what": f"linkage mode {mode + 1} at {lo:.1f}-{hi:.1f} Hz over the revolution "
                                f"(below {f_max:.0f} Hz at {len(col)} of {_MAP_ANGLES} crank angles)",
                        "band_Hz": (lo, hi)})
    return out


def resonance_flags(rpm: float, modes: list) -> list:
    """Modes ``[{"what", "band_Hz": (lo, hi)}]`` within :data:`RESONANCE_BAND` of a harmonic k f_rev
    (k = 1 .. :data:`HARMONICS`, f_rev = rpm / 60 [Hz]); the nearest harmonic per mode."""
    out = []
    for m in modes:
        near = _nearest_harmonic(m["band_Hz"], rpm)
        if near:
            gap, k, h = near
            where = "takes in" if gap == 0 else f"lies within {100 * gap:.1f} % of"
            out.append(flag("resonance", f"resonance: {m['what']} {where} harmonic {k} of the crank speed "
                                         f"({h:.1f} Hz at {rpm:.0f} rpm; flagged within {100 * RESONANCE_BAND:g} % "
                                         f"for harmonics 1-{HARMONICS})", gap, RESONANCE_BAND))
    return out


def _nearest_harmonic(band_Hz: tuple, rpm: float) -> tuple | None:
    """``(gap, k, harmonic [Hz])`` of the harmonic k f_rev (k = 1 .. :data:`HARMONICS`, f_rev =
    rpm / 60 [Hz]) nearest the frequency band ``(lo, hi)`` [Hz] (gap 0 inside it, else relative to
    the harmonic), if within :data:`RESONANCE_BAND`; else None."""
    lo, hi = band_Hz
    near = []
    for k in range(1, HARMONICS + 1):
        h = k * rpm / 60.0
        gap = 0.0 if lo <= h <= hi else min(abs(lo - h), abs(hi - h)) / h
        if gap <= RESONANCE_BAND:
            near.append((gap, k, h))
    return min(near) if near else None


def step_flags(sc, rpm: float, modes: list) -> list:
    """The transfer-matrix step near a resonance of a link's own mode (``modes`` of
    :func:`link_modes`): the step's integrator lowers the mode's frequency by its period error
    (:func:`tmm_core.integrators.numerical_frequency`), which the resonant response amplifies by
    :func:`tmm_core.closed_forms.resonance_sensitivity` at the link's damping. Flagged where the
    product reaches :data:`STEP_ERROR_FRACTION`, with the step that keeps it within
    :data:`STEP_ERROR_TARGET` (the period error is second order in the step)."""
    integrator, dt = get_integrator(sc.tmm.integrator), sc.engine_step_s("tmm")
    out = []
    for m in modes:
        near = _nearest_harmonic(m["band_Hz"], rpm) if "link" in m else None
        if near is None:
            continue
        gap, k, h = near
        zeta = float(m["link"].damping.ratio_at(m["f_Hz"]))
        omega = 2.0 * math.pi * m["f_Hz"]
        period_error = omega / numerical_frequency(integrator, omega, dt)[0] - 1.0
        sensitivity = resonance_sensitivity(h / m["f_Hz"], zeta)
        shift = sensitivity * period_error
        if not shift >= STEP_ERROR_FRACTION:
            continue
        deg = math.degrees(abs(sc.drive.speed_rad_s) * dt)
        enough = deg * math.sqrt(STEP_ERROR_TARGET / shift)
        out.append(flag("step", f"step: {m['what']} lies {100 * gap:.1f} % from harmonic {k} with "
                                f"{100 * zeta:.2g} % damping, where the resonant response moves "
                                f"{sensitivity:.0f}x any relative error of that "
                                f"frequency; the step ({deg:.3g} deg, {integrator.name}) puts the mode "
                                f"{100 * period_error:.3f} % low: about {100 * shift:.1f} % on the resonant part of "
                                f"the response (a step of {enough:.2g} deg keeps it within "
                                f"{100 * STEP_ERROR_TARGET:g} %; flagged from {100 * STEP_ERROR_FRACTION:g} %)",
                        shift, STEP_ERROR_FRACTION))
    return out


def _peak(stats: dict) -> float:
    return max(abs(stats.get("bending_max_ue") or 0.0), abs(stats.get("bending_min_ue") or 0.0))


def rigid_flags(engines: dict) -> dict:
    """``{rigid engine: [flag]}`` where its peak bending [µε] at a gauge lies more than
    :data:`RIGID_FACTOR` times off every flexible engine's (the gauge where it is farthest)."""
    flexible = {n: e.get("gauges") or {} for n, e in engines.items() if not is_rigid(n)}
    out = {}
    for name, e in engines.items():
        if not is_rigid(name):
            continue
        worst = None
        for g, stats in (e.get("gauges") or {}).items():
            mine = _peak(stats)
            others = {n: _peak(gs[g]) for n, gs in flexible.items() if g in gs}
            if not mine > 0 or not others or not all(v > 0 for v in others.values()):
                continue
            factor = min(max(v / mine, mine / v) for v in others.values())
            if worst is None or factor > worst[0]:
                worst = (factor, g, mine, others)
        if worst is not None and worst[0] > RIGID_FACTOR:
            factor, g, mine, others = worst
            theirs = ", ".join(f"{n} {v:.0f} µε" for n, v in others.items())
            out[name] = [flag("rigid_model", f"rigid model: no elastic response; {name} differs from the flexible "
                                             f"engines by {factor:.1f}x at {g} (peak bending {name} {mine:.0f} µε, "
                                             f"{theirs}; flagged beyond {RIGID_FACTOR:g}x)", factor, RIGID_FACTOR)]
    return out


def physics_flags(sc, summary: dict, modes: list | None = None) -> dict:
    """``{engine: [flag]}`` for every engine of the summary that was available. ``modes``: the
    natural frequencies to check (default :func:`link_modes` and :func:`linkage_modes`)."""
    rpm = sc.drive.speed_rpm
    own = link_modes(sc)
    if modes is None:
        modes = own + linkage_modes(sc, rpm)
    common = transmission_flags(sc, summary.get("linkage"))
    resonant = resonance_flags(rpm, modes)
    rigid = rigid_flags(summary.get("engines") or {})
    out = {}
    for name, e in (summary.get("engines") or {}).items():
        if e.get("status") == "unavailable":
            continue
        res = resonant
        if is_rigid(name):            # it has no modes to ring: its peaks miss the resonance
            res = [dict(f, message=f["message"] + f"; {name} is rigid and cannot show it") for f in resonant]
        out[name] = buckling_flags(sc, e.get("gauges")) + common + res + rigid.get(name, [])
        if name == "tmm":
            out[name] += step_flags(sc, rpm, own)
    return out


def questionable(summary: dict, implausible: bool) -> bool:
    """Whether a run's results call for the linkage's own natural frequencies (seconds of work):
    a strain beyond plausibility, or a run until steady whose flexible engine did not settle."""
    if implausible:
        return True
    return bool(summary.get("until_steady")) and summary.get("status") != "interrupted" and any(
        e.get("status") == "completed" and e.get("steady") is False and not is_rigid(n)
        for n, e in (summary.get("engines") or {}).items())


def attach_flags(sc, summary: dict, linkage_map: bool = True, progress: bool = False) -> dict:
    """:func:`physics_flags` written into ``summary["engines"][engine]["flags"]`` (a list, empty
    when nothing is flagged) and logged; returns them. The resonances are checked against the
    links' own modes (closed forms), and against the linkage's when ``linkage_map`` (a bounded
    map of seconds; ``progress``: its bar). A failure is logged, never raised: the flags must not
    lose a run."""
    modes = link_modes(sc) + (linkage_modes(sc, sc.drive.speed_rpm, progress) if linkage_map else [])
    try:
        flags = physics_flags(sc, summary, modes)
    except Exception as exc:
        log.warning("physics flags not computed: %s: %s", type(exc).__name__, exc)
        return {}
    for name, fl in flags.items():
        summary["engines"][name]["flags"] = fl
        for f in fl:
            log.debug("%s: %s", name, f["message"])      # the console prints them under its table
    return flags
