"""Static analysis against closed forms and published tables."""
import numpy as np
import pytest

from cosim.units import INCH, PSI
from tmm_core import (FourBarMechanism, Joint, Link, LoadCase, Material, Member, Section, Structure,
                      solve_static, soderberg)

from .helpers import assert_equilibrium, cantilever, tip_load_case

L, EI, EA = 1.0, 2.0e3, 4.0e8
# The stepped beam of Shin §8.5 (_stepped_beam) by an independent solution of its elastica
# (shooting on the exact planar rod equations) and of its small-deflection theory:
# ``python -m tests.benchmarks.elastica_references`` regenerates both.
#: Exact elastica tip displacement (x, y) [mm].
STEPPED_BEAM_ELASTICA_TIP_MM = (-5.257, -38.999)
#: Small-deflection tip deflection [mm].
STEPPED_BEAM_LINEAR_TIP_MM = -40.68


@pytest.mark.parametrize("n", [1, 7])
def test_cantilever_tip_load_and_end_moment_closed_forms(n):
    structure, member = cantilever(n, L, EI, EA)
    F, Mo = 12.0, 3.5
    sol = solve_static(structure, tip_load_case(member, (0.0, F, 0.0), L))
    r = sol.members["beam"]
    assert r.w[-1] == pytest.approx(F * L**3 / (3 * EI), rel=1e-9)
    assert r.theta[-1] == pytest.approx(F * L**2 / (2 * EI), rel=1e-9)
    assert sol.reaction_moment("A") == pytest.approx(-F * L, rel=1e-9)   # ground balances the CCW moment F L
    assert_equilibrium(sol, F, L)

    sol = solve_static(structure, tip_load_case(member, (0.0, 0.0, Mo), L))
    r = sol.members["beam"]
    assert r.w[-1] == pytest.approx(Mo * L**2 / (2 * EI), rel=1e-9)
    assert r.theta[-1] == pytest.approx(Mo * L / EI, rel=1e-9)
    np.testing.assert_allclose(r.M[:-1], Mo, rtol=1e-9)                # uniform moment inside the beam
    assert r.M[-1, 0] == pytest.approx(Mo, rel=1e-9) and abs(r.M[-1, 1]) < 1e-9 * Mo  # zero beyond the tip
    assert_equilibrium(sol, Mo / L, L)

    sol = solve_static(structure, tip_load_case(member, (5.0e3, 0.0, 0.0), L))
    assert sol.members["beam"].u[-1] == pytest.approx(5.0e3 * L / EA, rel=1e-9)


@pytest.mark.parametrize("P", [800.0, -800.0, 3000.0])
def test_beam_column_cantilever_closed_forms(P):
    """Tip transverse load F with axial tension/compression P (Timoshenko & Gere closed forms)."""
    structure, member = cantilever(6, L, EI, EA)
    F = 7.0
    sol = solve_static(structure, tip_load_case(member, (P, F, 0.0), L), beam_column=True)
    k = np.sqrt(abs(P) / EI)
    if P > 0:
        w, th = F / (P * k) * (k * L - np.tanh(k * L)), F / P * (1 - 1 / np.cosh(k * L))
    else:
        w, th = F / (-P * k) * (np.tan(k * L) - k * L), F / -P * (1 / np.cos(k * L) - 1)
    r = sol.members["beam"]
    assert r.w[-1] == pytest.approx(w, rel=1e-9)
    assert r.theta[-1] == pytest.approx(th, rel=1e-9)
    # The clamp balances the moment of the tip loads about A at the deflected tip: F L - P w_L.
    assert sol.reaction_moment("A") == pytest.approx(-(F * L - P * w), rel=1e-9)
    assert_equilibrium(sol, F + abs(P), L, deformed=True, moment_rtol=1e-6)


def test_hanging_bar_under_self_weight_fixes_shin_axial_load_terms():
    """A vertical bar hanging from a clamp: N(x) = w (L - x), tip drop w L^2 / (2 EA)."""
    E, A, rho, g = 7.0e10, 1e-4, 2700.0, 9.81
    n = 5
    member = Member.uniform("bar", "A", "B", L, n, Section(A, 1e-9, 0.01), Material("al", E, rho),
                            start_connection="rigid")
    structure = Structure((Joint("A", "clamped"), Joint("B")), (member,))
    weight = rho * A * g
    case = LoadCase({"A": np.zeros(2), "B": np.array([0.0, -L])},
                    distributed_loads={"bar": np.tile([0.0, -weight], (n, 1))})
    sol = solve_static(structure, case)
    r = sol.members["bar"]
    x = member.stations
    np.testing.assert_allclose(r.N[:, 1], weight * (L - x), rtol=1e-12, atol=1e-12 * weight)
    assert r.displacement[-1, 1] == pytest.approx(-weight * L**2 / (2 * E * A), rel=1e-12)
    assert sol.reactions["A"][1] == pytest.approx(weight * L, rel=1e-12)
    assert_equilibrium(sol, weight * L, L)


def _stepped_beam(per_25mm: int):
    """Shin §8.5 / App. D: 500 mm steel beam pinned at x = 0, 5x5 mm up to
    x = 250 mm then 2.5x2.5 mm, vertical sliding springs 2 N/mm at x = 150 and 400 mm, 15 N down at
    the tip, self-weight 76.5e-6 N/mm^3, E = 207 GPa (Shin does not state it; inferred from his tables)."""
    steel = Material("AISI 4340", 207e9, yield_strength_Pa=689e6)
    big, small = Section.rectangle(5e-3, 5e-3), Section.rectangle(2.5e-3, 2.5e-3)
    n = 20 * per_25mm
    secs = tuple(big if i < 10 * per_25mm else small for i in range(n))
    member = Member("beam", "P1", "P5", (0.025 / per_25mm,) * n, secs, (steel,) * n)
    structure = Structure((Joint("P1", "pinned"), Joint("P5")), (member,))
    K = np.zeros((n + 1, 3, 3))
    K[6 * per_25mm, 1, 1] = K[16 * per_25mm, 1, 1] = 2000.0
    loads = np.zeros((n + 1, 3))
    loads[-1, 1] = -15.0
    q = np.zeros((n, 2))
    q[:, 1] = [-76.5e3 * s.area_m2 for s in secs]
    case = LoadCase({"P1": np.zeros(2), "P5": np.array([0.5, 0.0])}, {"beam": loads}, {"beam": q}, {"beam": K})
    return structure, case


def test_stepped_beam_large_deflection_matches_shin_table_8_16():
    """Tip (node 5) (-5.273, -39.09) mm in Shin Table 8.16 within 0.5 %. The co-rotational mode
    converges to the exact elastica (-5.257, -38.999) mm (notes §7.7, independent solution),
    which lies 0.3 % from Shin's approximate method; 4 sub-segments per 25 mm are used."""
    structure, case = _stepped_beam(4)
    sol = solve_static(structure, case, large_deflection=True)
    r = sol.members["beam"]
    tip = r.displacement[-1] * 1e3
    np.testing.assert_allclose(tip, [-5.273, -39.09], rtol=5e-3)
    np.testing.assert_allclose(tip, STEPPED_BEAM_ELASTICA_TIP_MM, rtol=1e-3)       # exact elastica
    assert np.degrees(r.theta[-1]) == pytest.approx(-18.75, rel=5e-3)
    node4 = 16 * 4
    np.testing.assert_allclose(r.displacement[node4] * 1e3, [-0.9664, -10.22], rtol=1e-2)
    assert r.M[node4, 0] * 1e3 == pytest.approx(-1438, rel=5e-3)         # N mm (same sign: sagging < 0 here)
    sf = sol.safety_factor("beam")
    assert sf.min() == pytest.approx(1.25, rel=1e-2) and int(np.argmin(sf)) == node4
    assert_equilibrium(sol, 15.0, 0.5, deformed=True, moment_rtol=1e-5)

    lin = solve_static(structure, case)
    tip_lin = lin.members["beam"].displacement[-1] * 1e3
    # Small-deflection theory is visibly different (notes: about 4 %): -40.68 mm, no shortening.
    assert tip_lin[1] == pytest.approx(STEPPED_BEAM_LINEAR_TIP_MM, rel=1e-3)
    assert abs(tip_lin[1] / -39.09 - 1) > 0.03
    assert tip_lin[0] == 0.0
    assert_equilibrium(lin, 15.0, 0.5)


def test_end_moment_cantilever_shin_table_4_1():
    """L = 100 cm, M L / EI = 1: exact tip (84.147, 45.970) cm; Shin claims < 2 % with 10 segments."""
    structure, member = cantilever(10, 1.0, EI, EA)
    sol = solve_static(structure, tip_load_case(member, (0.0, 0.0, EI / 1.0), 1.0), large_deflection=True)
    r = sol.members["beam"]
    tip = (np.array([1.0, 0.0]) + r.displacement[-1]) * 100
    np.testing.assert_allclose(tip, [84.147, 45.970], rtol=2e-2)
    np.testing.assert_allclose(tip, [84.147, 45.970], rtol=1e-3)     # what this method achieves
    assert r.theta[-1] == pytest.approx(1.0, rel=1e-9)
    assert_equilibrium(sol, EI / 1.0, 1.0, deformed=True, moment_rtol=1e-6)   # load scale M/L


def _al_fourbar(n=6):
    al = Material("al", 10.3e6 * PSI, 2768.0, 90e3 * PSI, 45e3 * PSI)
    thin, thick = Section.rectangle(INCH, 0.063 * INCH), Section.rectangle(INCH, 0.167 * INCH)
    return FourBarMechanism(Link("crank", 4 * INCH, thick, al, n), Link("coupler", 11 * INCH, thin, al, n),
                            Link("rocker", 10.5 * INCH, thin, al, n), 10 * INCH)


def test_fourbar_drive_torque_equals_virtual_work_of_the_loads():
    """The instantaneous four-bar is statically determinate, so in small-deflection theory the
    crank-pivot reaction moment equals the rigid-body virtual-work torque of the applied loads:
    T * omega_crank + sum(F . v) = 0, with v from the closed-form kinematics at unit crank speed."""
    fb = _al_fourbar()
    th = np.radians(np.arange(0.0, 360.0, 15.0))
    n = 6
    loads = {"coupler": np.zeros(th.shape + (n + 1, 3)), "rocker": np.zeros(th.shape + (n + 1, 3))}
    loads["coupler"][..., 2, :] = [3.0, -8.0, 0.05]
    loads["rocker"][..., 5, :] = [-2.0, 1.0, -0.02]
    gravity = fb.gravity_loads()
    sol = solve_static(fb.structure(), fb.load_case(fb.motion(th), loads, gravity))
    unit = fb.motion(th, 1.0, 0.0)
    power = 0.0
    for name, F in loads.items():
        link = getattr(fb, name)
        x = np.linspace(0, link.length_m, n + 1)
        v = unit.link(name).point(x)[1]
        power = power + np.sum(F[..., :2] * v, axis=(-1, -2)) + np.sum(F[..., 2] * unit.link(name).omega[..., None], -1)
    for link in fb.links():
        x = np.linspace(0, link.length_m, n + 1)
        v = unit.link(link.name).point(0.5 * (x[1:] + x[:-1]))[1]
        power = power + np.sum(gravity[link.name] * (link.length_m / n) * v, axis=(-1, -2))
    np.testing.assert_allclose(sol.reaction_moment("A"), -power, rtol=1e-9, atol=1e-12)
    assert_equilibrium(sol, 10.0, 0.3)


def test_fourbar_beam_column_and_large_deflection_keep_equilibrium():
    fb = _al_fourbar()
    th = np.radians([20.0, 140.0, 260.0])
    n = 6
    loads = np.zeros(th.shape + (n + 1, 3))
    loads[..., 3, 1] = -15.0
    case = fb.load_case(fb.motion(th), {"coupler": loads}, fb.gravity_loads())
    for kw in ({"beam_column": True}, {"large_deflection": True}):
        sol = solve_static(fb.structure(), case, **kw)
        assert_equilibrium(sol, 15.0, 0.3, deformed=True, moment_rtol=1e-5)
        for name, r in sol.members.items():
            assert np.all(np.isfinite(r.state))


def test_soderberg_matches_shin_table_8_12_row_12():
    """Node 12: S_mean = -2752, S_alt = 6900 psi, S_y = 90 ksi, S_n = 45 ksi -> SF 5.44."""
    history = np.array([-2752 - 6900, -2752 + 6900, -2752.0]) * PSI
    sf, mean, alt = soderberg(history, 90e3 * PSI, 45e3 * PSI)
    assert sf == pytest.approx(5.44, rel=2e-3)
    assert mean / PSI == pytest.approx(-2752) and alt / PSI == pytest.approx(6900)
