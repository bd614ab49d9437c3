"""Mechanisms used by the kineto-elastodynamics tests, built from the source descriptions."""
from __future__ import annotations

from cosim.units import FOOT, INCH, POUND_FORCE, POUND_MASS, PSI, SLUG
from tmm_core import Damping, FourBarMechanism, Link, Material, PointMass, Section

G0 = 9.80665


def alexander_lawrence(n: int = 8, damping: float = 0.0, damping_Hz: float = 47.0, E_factor: float = 1.0,
                       bearing_lb: float = 0.06) -> FourBarMechanism:
    """Shin §8.3 (notes seed000 §7.2): crank 4, coupler 11, follower 10.5, ground 10 in; 1 in wide
    aluminium strip, crank 0.167 in, coupler and follower 0.063 in thick; 0.06 lb bearing mass at
    each coupler end. Assumed (not in the source): E = 10.3e6 psi, 0.1 lb/in^3."""
    alu = Material("aluminium", 10.3e6 * PSI * E_factor, 0.1 * POUND_MASS / INCH**3, 90e3 * PSI, 45e3 * PSI)
    thin, thick = Section.rectangle(INCH, 0.063 * INCH), Section.rectangle(INCH, 0.167 * INCH)
    d = Damping.modal(damping, damping_Hz) if damping else Damping()
    bm = bearing_lb * POUND_MASS
    return FourBarMechanism(
        Link("crank", 4 * INCH, thick, alu, n, damping=d),
        Link("coupler", 11 * INCH, thin, alu, n, (PointMass(0.0, bm, label="B bearing"),
                                                   PointMass(11 * INCH, bm, label="C bearing")), damping=d),
        Link("rocker", 10.5 * INCH, thin, alu, n, damping=d), 10 * INCH)


def fe_crank_rocker(n: int = 8, bearing_lbf: float = 0.13128, damping: float = 0.0, damping_Hz: float = 79.0,
                    crank_stiffness_factor: float = 100.0) -> FourBarMechanism:
    """FE crank-rocker thesis rig (notes seed002 §3.1): crank 7, coupler 10, rocker 12, ground 11 in;
    1 in x 1/8 in aluminium, E = 10.3e6 psi, 5.292 slug/ft^3; bearing weight 0.13128 lbf at each
    coupler end. The real crank was far stiffer than a 1/8 in strip (split links and shafts; the
    thesis computes 304 Hz for it, reference_checks.md): by assumption 100x the strip's modulus."""
    alu = Material("aluminium", 10.3e6 * PSI, 5.292 * SLUG / FOOT**3)
    crank_mat = Material("crank (stiffened by assumption)", 10.3e6 * PSI * crank_stiffness_factor,
                         5.292 * SLUG / FOOT**3)
    sec = Section.rectangle(INCH, 0.125 * INCH)
    d = Damping.modal(damping, damping_Hz) if damping else Damping()
    bm = bearing_lbf * POUND_FORCE / G0
    return FourBarMechanism(
        Link("crank", 7 * INCH, sec, crank_mat, n, damping=d),
        Link("coupler", 10 * INCH, sec, alu, n, (PointMass(0.0, bm, label="A bearing"),
                                                  PointMass(10 * INCH, bm, label="B bearing")), damping=d),
        Link("rocker", 12 * INCH, sec, alu, n, damping=d), 11 * INCH)
