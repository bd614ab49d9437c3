"""The source documents' rigs as mechanisms (SI), with their assumptions stated.

Until the TOML scenario files exist these builders are the single description of each rig;
scripts and tests import them from here.
"""
from __future__ import annotations

from cosim.units import FOOT, INCH, POUND_FORCE, POUND_MASS, PSI, SLUG
from tmm_core import Damping, FourBarMechanism, Link, Material, PointMass, Section, StandardLinearSolid
from tmm_core.mechanism import EndBlock

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


def _wang_blocks(aluminium):
    """Wang's aluminium bearing housings (notes seed001 §2.2, modelled as in his code):
    coupler 1.5 in 0.75x0.75 at the crank pin and 1.5 in 1.25x0.75 at the coupler-rocker pin;
    rocker 1.5 in 1.25x0.75 at the ground pivot and 1.75 in 1.75x0.27 at the coupler-rocker pin."""
    block = lambda L, w, d: EndBlock(L * INCH, Section.rectangle(w * INCH, d * INCH), aluminium)  # noqa: E731
    return {"coupler": (block(1.5, 0.75, 0.75), block(1.5, 1.25, 0.75)),
            "rocker": (block(1.5, 1.25, 0.75), block(1.75, 1.75, 0.27))}


def _wang(L1, L2, L3, L4, span_material, width_in, depth_in, n, damping, viscoelastic=None):
    aluminium = Material("aluminium housing", 10.3e6 * PSI, 0.1 * POUND_MASS / INCH**3)
    # The crank is rigid in the rig and in Wang's model: a 0.5 in square steel bar (assumption).
    crank_steel = Material("crank (rigid by assumption)", 30e6 * PSI * 100.0, 0.3 * POUND_MASS / INCH**3)
    blocks = _wang_blocks(aluminium)
    span = Section.rectangle(width_in * INCH, depth_in * INCH)
    return FourBarMechanism(
        Link("crank", L2 * INCH, Section.rectangle(0.5 * INCH, 0.5 * INCH), crank_steel, 2),
        Link("coupler", L3 * INCH, span, span_material, n, damping=damping, viscoelastic=viscoelastic,
             start_block=blocks["coupler"][0], end_block=blocks["coupler"][1]),
        Link("rocker", L4 * INCH, span, span_material, n, damping=damping, viscoelastic=viscoelastic,
             start_block=blocks["rocker"][0], end_block=blocks["rocker"][1]),
        L1 * INCH)


def wang_steel(n: int = 4, depth_in: float = 0.062) -> FourBarMechanism:
    """Wang's steel four-bar (notes seed001 §1, code values): ground 16.12, crank 2.25, coupler
    and rocker 12 in; low-carbon steel E = 30e6 psi, 0.3 lb/in^3 (code), 0.75 in wide, 0.062 in
    deep (code; the text says 0.055); mass-proportional damping C = 0.622 M as in his code."""
    steel = Material("low-carbon steel", 30e6 * PSI, 0.3 * POUND_MASS / INCH**3)
    return _wang(16.12, 2.25, 12.0, 12.0, steel, 0.75, depth_in, n, Damping(mass_per_s=0.622))


#: Assumed standard-linear-solid constants of Wang's +/-45 deg graphite-epoxy (the thesis lost
#: the fitted values): instantaneous = the tangent modulus of the fastest (0.5 s) ramp test,
#: relaxed = the 1.328e6 psi his VISCO program uses, relaxation time = that fastest ramp time.
WANG_COMPOSITE_SLS = StandardLinearSolid(3.143e6 * PSI, 1.328e6 * PSI, 0.5)


def wang_composite(n: int = 4, sls: StandardLinearSolid = WANG_COMPOSITE_SLS) -> FourBarMechanism:
    """Wang's +/-45 deg composite four-bar (notes seed001 §1, VISCO values): ground 12, crank 2.5,
    coupler and rocker 9 in; 1.36 in wide (OCR-doubtful), 0.135 in deep, 0.06 lb/in^3, SLS links."""
    composite = Material("+/-45 graphite-epoxy (instantaneous)", sls.instantaneous_modulus_Pa,
                         0.06 * POUND_MASS / INCH**3)
    return _wang(12.0, 2.5, 9.0, 9.0, composite, 1.36, 0.135, n, Damping(), viscoelastic=sls)
