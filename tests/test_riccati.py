"""Stability of chaining many segments: Riccati transfer vs Shin's plain products.

Expected values are closed-form beam-column solutions of a cantilever with a tip transverse
load F and an axial tip load P (tension: w_L = F/(P k) (kL - tanh kL); compression:
w_L = F/(P k) (tan kL - kL), k = sqrt(|P|/EI)).
"""
import numpy as np
import pytest

from tmm_core import solve_static
from tmm_core.matrices import field_matrix, point_matrix
from tmm_core.riccati import chain_product, condense_chain

from .helpers import assert_equilibrium, cantilever, tip_load_case

L, EI, F = 1.0, 2.0e3, 10.0


def closed_form_tip(P):
    k = np.sqrt(abs(P) / EI)
    if P > 0:
        return F / (P * k) * (k * L - np.tanh(k * L)), F / P * (1 - 1 / np.cosh(k * L))
    return F / (-P * k) * (np.tan(k * L) - k * L), F / -P * (1 / np.cos(k * L) - 1)


@pytest.mark.parametrize("P_over_Pcr", [0.0, 0.5, -0.5, -0.99, 5.0])
def test_same_cantilever_split_into_2_and_400_segments_agrees(P_over_Pcr):
    Pcr = np.pi**2 * EI / (4 * L**2)           # clamped-free Euler load
    P = P_over_Pcr * Pcr
    results = []
    for n in (2, 400):
        structure, member = cantilever(n, L, EI)
        sol = solve_static(structure, tip_load_case(member, (P, F, 0.0), L), beam_column=True)
        r = sol.members["beam"]
        assert_equilibrium(sol, load_scale=F + abs(P), length_scale=L, deformed=True, moment_rtol=1e-6)
        results.append(np.r_[r.w[-1], r.theta[-1], sol.reaction_moment("A"), sol.reactions["A"][:2]])
    a, b = results
    np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8 * np.abs(a).max())
    if P != 0.0:
        w_exact, th_exact = closed_form_tip(P)
        assert b[0] == pytest.approx(w_exact, rel=1e-9)
        assert b[1] == pytest.approx(th_exact, rel=1e-9)


def _plain_tip_deflection(n, P):
    """Shin-style: multiply all matrices, then solve the three tip conditions f = 0."""
    U = chain_product([field_matrix(L / n, 1e9, EI, P) for _ in range(n)] + [point_matrix((P, F, 0.0))])
    x = np.linalg.solve(U[3:6, 3:6], -U[3:6, 6])
    return (U @ np.r_[0, 0, 0, x, 1.0])[1]


def _riccati_tip_deflection(n, P):
    mats, flags = [], []
    for _ in range(n):
        mats += [point_matrix((0.0, 0.0, 0.0)), field_matrix(L / n, 1e9, EI, P)]
        flags += [False, True]
    mats.append(point_matrix((P, F, 0.0)))
    flags.append(False)
    factor, loads = condense_chain(mats, flags)
    return np.linalg.solve(factor.stiffness[3:, 3:], -loads.load[3:])[1]


def test_plain_products_lose_precision_where_riccati_does_not():
    """Measured: with k L = 40 (high tension) Shin's plain product is wrong in the first digit,
    while the Riccati chain with 400 segments stays at round-off."""
    P = 40.0**2 * EI / L**2
    exact = closed_form_tip(P)[0]
    plain = abs(_plain_tip_deflection(400, P) - exact) / exact
    riccati = abs(_riccati_tip_deflection(400, P) - exact) / exact
    assert riccati < 1e-12
    assert plain > 1e-2


def test_condensed_stiffness_is_symmetric_and_positive_for_a_stable_chain():
    structure, member = cantilever(50, L, EI)
    mats, flags = [], []
    for _ in range(50):
        mats += [point_matrix((0.0, 0.0, 0.0)), field_matrix(L / 50, 4e8, EI, -100.0)]
        flags += [False, True]
    factor, _ = condense_chain(mats, flags)
    K = factor.stiffness
    np.testing.assert_allclose(K, K.T, rtol=1e-9, atol=1e-9 * np.abs(K).max())
    assert int(factor.negative_pivots) == 0
