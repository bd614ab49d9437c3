"""Natural frequencies by the transfer-matrix frequency search (exact distributed mass)."""
import numpy as np
import pytest

from cosim.units import FOOT, INCH, PSI, SLUG
from tmm_core import Joint, Material, Member, Section, Structure
from tmm_core.frequencies import dynamic_field_matrix, fourbar_frequencies, frequency_model, natural_frequencies
from tmm_core.matrices import field_matrix

from scenarios.rigs import alexander_lawrence, fe_crank_rocker

ALU = Material("aluminium", 10.3e6 * PSI, 5.292 * SLUG / FOOT**3)   # FE thesis rig
STRIP = Section.rectangle(INCH, 0.125 * INCH)

# Pinned values of independent models (docs/validation.md, "Reference values read from the
# sources"); ``python -m tests.benchmarks.frequency_references`` regenerates them with exudyn's
# constrained eigenvalue analysis of the same rigs.
#: The FE rig with a strip crank (slope clamped at its pivot): its first three frequencies [Hz] at
#: each crank angle [deg] of FE_RIG_ANGLES_DEG without lumped masses, and at crank angle 0 with
#: 0.13128 lbf at each coupler end (one quintic element per link).
FE_RIG_ANGLES_DEG = (0.0, 40.0)
FE_RIG_BARE_HZ = [[12.2, 88.6, 150.6], [47.3, 80.4, 136.7]]
FE_RIG_BEARINGS_HZ = [[8.0, 83.7, 123.0]]
#: Wang's linkages' first bending mode [Hz] at the crank angles WANG_ANGLES_DEG: steel (depth
#: 0.062 in), and composite by its modulus [psi].
WANG_ANGLES_DEG = (0.0, 90.0)
WANG_STEEL_FIRST_HZ = 36.9
WANG_COMPOSITE_FIRST_HZ = {1.328e6: 62.8, 3.143e6: 96.6}
#: Bounds [Hz] of the Alexander-Lawrence coupler's first bending mode over a revolution (the
#: independent flexible model puts it near 47 Hz; docs/validation.md, "Damping decides the coupler
#: response near 400 rpm").
AL_FIRST_MODE_BOUNDS_HZ = (40.0, 50.0)


def _beam(support: str, L: float, n: int = 3):
    clamped = support == "clamped-free"
    m = Member.uniform("beam", "A", "B", L, n, STRIP, ALU, start_connection="rigid" if clamped else "pin")
    joints = (Joint("A", "clamped"), Joint("B")) if clamped else (Joint("A", "pinned"), Joint("B", "pinned"))
    return frequency_model(Structure(joints, (m,)), {"A": np.zeros(2), "B": np.array([L, 0.0])}, 2 * np.pi * 3000)


def test_dynamic_field_matrix_tends_to_the_static_one():
    np.testing.assert_allclose(dynamic_field_matrix(0.3, 2e6, 5.0, 0.2, 0.0, -12.0), field_matrix(0.3, 2e6, 5.0, -12.0),
                               rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("support, roots", [
    ("pinned-pinned", [np.pi, 2 * np.pi, 3 * np.pi, 4 * np.pi]),
    ("clamped-free", [1.8751040687119611, 4.694091132974174, 7.854757438237613, 10.995540734875467]),
])
@pytest.mark.parametrize("n", [1, 5])
def test_uniform_beam_frequencies_match_closed_forms(support, roots, n):
    L = 12 * INCH
    f = natural_frequencies(_beam(support, L, n), 4, 2 * np.pi * 3000)
    EI, mu = ALU.E_Pa * STRIP.inertia_m4, ALU.density_kg_m3 * STRIP.area_m2
    exact = np.array(roots) ** 2 / L**2 * np.sqrt(EI / mu) / (2 * np.pi)
    np.testing.assert_allclose(f, exact, rtol=1e-6)


def test_fe_rig_output_link_first_frequency():
    """FE thesis §3.3: output link as a pinned-pinned 12 in strip, 79.07 Hz (calc), 78.13 Hz measured."""
    f = natural_frequencies(_beam("pinned-pinned", 12 * INCH), 1, 2 * np.pi * 1000)
    assert f[0] == pytest.approx(79.07, rel=5e-3)


def test_assembled_fe_rig_matches_independent_fe_model():
    """docs/validation.md, "The FE rig's natural frequencies from an independent finite-element
    model": crank slope clamped, quintic elements, no lumped
    masses: 12.2, 88.6, 150.6 Hz at 0 deg and 47.3, 80.4, 136.7 Hz at 40 deg; with 0.13128 lbf at
    each coupler end 8.0, 83.7, 123.0 Hz at 0 deg. One quintic element per link is slightly stiff,
    so agreement within 1 %."""
    f = fourbar_frequencies(fe_crank_rocker(4, bearing_lbf=0.0, crank_stiffness_factor=1.0),
                            np.radians(FE_RIG_ANGLES_DEG), 3, 1000.0)
    np.testing.assert_allclose(f, FE_RIG_BARE_HZ, rtol=1e-2)
    f = fourbar_frequencies(fe_crank_rocker(4, crank_stiffness_factor=1.0), np.radians([0.0]), 3, 1000.0)
    np.testing.assert_allclose(f, FE_RIG_BEARINGS_HZ, rtol=1e-2)


def test_frequencies_over_a_revolution_and_independence_of_the_mesh():
    th = np.radians(np.arange(0.0, 360.0, 45.0))
    f4 = fourbar_frequencies(alexander_lawrence(4), th, 3, 500.0)
    f16 = fourbar_frequencies(alexander_lawrence(16), th[:2], 3, 500.0)
    assert f4.shape == (8, 3) and np.all(np.isfinite(f4))
    np.testing.assert_allclose(f4[:2], f16, rtol=1e-8)
    # docs/validation.md, "Damping decides the coupler response near 400 rpm": the coupler's first
    # bending mode is near 47 Hz, the 7th harmonic of 400 rpm.
    low, high = AL_FIRST_MODE_BOUNDS_HZ
    assert np.all((f4[:, 0] > low) & (f4[:, 0] < high))


def test_wang_linkages_match_the_notes_independent_model():
    """docs/validation.md, "Wang's linkages' first modes from an independent model" (not thesis
    data; with the aluminium housings): first bending modes about 36.9 Hz (steel, depth 0.062 in),
    62.8 Hz (composite, E = 1.328e6 psi) and 96.6 Hz (E = 3.143e6 psi), nearly independent of
    the crank angle."""
    from scenarios.rigs import wang_composite, wang_steel
    from tmm_core import StandardLinearSolid
    f = fourbar_frequencies(wang_steel(4), np.radians(WANG_ANGLES_DEG), 1, 500.0)
    np.testing.assert_allclose(f, WANG_STEEL_FIRST_HZ, rtol=1e-2)
    for E, expected in WANG_COMPOSITE_FIRST_HZ.items():
        sls = StandardLinearSolid(E * PSI, 0.5 * E * PSI, 0.5)
        f = fourbar_frequencies(wang_composite(4, sls), np.radians(WANG_ANGLES_DEG), 1, 500.0)
        np.testing.assert_allclose(f, expected, rtol=1e-2)
