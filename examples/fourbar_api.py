"""The transfer-matrix core from Python, on one four-bar: statics, quasi-static analysis, time
marching, the periodic steady state, natural frequencies and the reduced model.

Run it with ``python examples/fourbar_api.py``; ``tests/test_examples.py`` runs it too. Every
name comes from ``tmm_core`` itself (its curated ``__all__``). SI units throughout.

The rig is the FE thesis's crank-rocker (aluminium strip 1 x 1/8 in; crank 7 in, coupler 10 in,
rocker 12 in, ground 11 in) at 241 rpm, with a rigid crank and 2 % modal damping at 79 Hz (the
values of ``scenarios/base/fe_crank_rocker.toml``, without its bearing masses); gauges at
midspan of the coupler and rocker.
"""
import math

import numpy as np

from tmm_core import (CrankMotion, Damping, FourBarMechanism, Gauge, Joint, Link, LoadCase, Material, Member,
                      ReducedOptions, Section, Structure, TimeDomain, fourbar_frequencies, periodic_steady_state,
                      periodic_steady_state_reduced, quasi_static, solve_static, time_domain)

INCH = 0.0254
ALUMINIUM = Material("aluminium", 71.02e9, 2727.4)          # 10.3e6 psi, 5.292 slug/ft^3
STRIP = Section.rectangle(1.0 * INCH, 0.125 * INCH)
SPEED = 241 * 2 * math.pi / 60                               # [rad/s]


def cantilever_tip_deflection(load_N: float = 1.0, length_m: float = 7 * INCH) -> float:
    """Statics: a clamped strip with a tip load [N]; returns the tip deflection [m]."""
    beam = Member.uniform("beam", "A", "B", length_m, 8, STRIP, ALUMINIUM, start_connection="rigid")
    structure = Structure((Joint("A", "clamped"), Joint("B")), (beam,))
    node_loads = np.zeros((beam.n_segments + 1, 3))
    node_loads[-1] = (0.0, -load_N, 0.0)                    # (Fx, Fy, Mz) at the tip [N, N, N m]
    case = LoadCase({"A": np.zeros(2), "B": np.array([length_m, 0.0])}, {"beam": node_loads})
    return -float(solve_static(structure, case).members["beam"].w[-1])


def crank_rocker() -> FourBarMechanism:
    damped = Damping.modal(0.02, 79.0)
    link = lambda name, length: Link(name, length * INCH, STRIP, ALUMINIUM, n_segments=8, damping=damped)  # noqa: E731
    crank = Link("crank", 7.0 * INCH, STRIP, ALUMINIUM, n_segments=8, rigid=True)
    return FourBarMechanism(crank, link("coupler", 10.0), link("rocker", 12.0), 11.0 * INCH)


GAUGES = [Gauge("coupler_mid", "coupler", 5.0 * INCH), Gauge("rocker_mid", "rocker", 6.0 * INCH)]


def peak_bending_ue(gauges: dict, name: str) -> float:
    bending = np.asarray(gauges[name][0])
    return float(np.max(np.abs(bending)) * 1e6)


def main() -> dict:
    out = {"tip_deflection_mm": 1e3 * cantilever_tip_deflection()}
    mech = crank_rocker()
    angles = np.radians(np.arange(0.0, 360.0, 2.0))
    qs = quasi_static(mech, angles, SPEED, beam_column=True, gauges=GAUGES)
    out["quasi_static_rocker_ue"] = peak_bending_ue(qs.gauges, "rocker_mid")
    crank = CrankMotion.constant_speed(SPEED, step_deg=1.0, revolutions=3.0)
    marched = time_domain(mech, crank, integrator="generalized_alpha", gauges=GAUGES)
    out["marched_rocker_ue"] = peak_bending_ue(marched.gauges, "rocker_mid")
    td = TimeDomain(mech, integrator="generalized_alpha", gauges=GAUGES)
    steady = periodic_steady_state(td, SPEED, step_deg=1.0)
    out["periodic_rocker_ue"] = peak_bending_ue(steady.gauges, "rocker_mid")
    out["largest_floquet_multiplier"] = float(np.abs(steady.multipliers[0]))
    out["first_frequency_Hz"] = float(fourbar_frequencies(mech, np.radians([0.0]), 1, 500.0)[0, 0])
    reduced = periodic_steady_state_reduced(td, SPEED, options=ReducedOptions(modes=4))
    out["reduced_rocker_ue"] = peak_bending_ue(reduced.gauges, "rocker_mid")
    return out


if __name__ == "__main__":
    for key, value in main().items():
        print(f"{key:>28} {value:10.4g}")
