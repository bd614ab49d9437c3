"""Unit tests of the 7x7 transfer matrices against closed forms and Shin's printed forms."""
import numpy as np
import pytest

from tmm_core.matrices import (M, N, ONE, TH, U, V, W, field_matrix, frame_rotation, point_matrix,
                               rigid_element_matrix, spring_matrix, stumpff)


def test_stumpff_matches_closed_forms_and_is_continuous_at_the_series_switch():
    for s in (-30.0, -4.0, -1e-3, 1e-3, 4.0, 30.0):
        c0, c1, c2, c3, c4 = stumpff(s)
        r = np.sqrt(abs(s))
        ch, sh = (np.cosh(r), np.sinh(r)) if s > 0 else (np.cos(r), np.sin(r))
        assert c0 == pytest.approx(ch, rel=1e-13)
        assert c1 == pytest.approx(sh / r, rel=1e-13)
        assert c2 == pytest.approx((ch - 1) / s, rel=1e-9)
    # The switch between series and closed form sits at |s| = 4: both sides agree.
    for s0 in (4.0, -4.0):
        below, above = stumpff(s0 * (1 - 1e-13)), stumpff(s0 * (1 + 1e-13))
        for a, b in zip(below, above):
            assert a == pytest.approx(b, rel=1e-11)


def test_zero_axial_force_field_matrix_is_shin_eq_3_14():
    L, EA, EI = 0.3, 2.0e6, 5.0
    T = field_matrix(L, EA, EI)
    expected = np.eye(7)
    expected[U, N] = L / EA
    # Shin's Eq. 3.14 in his convention (theta_S = -theta, M_S = -M) gives these entries in ours.
    expected[W, TH] = L
    expected[W, M] = L**2 / (2 * EI)
    expected[W, V] = -L**3 / (6 * EI)
    expected[TH, M] = L / EI
    expected[TH, V] = -L**2 / (2 * EI)
    expected[M, V] = -L
    np.testing.assert_allclose(T, expected, rtol=1e-14, atol=1e-18)


@pytest.mark.parametrize("P", [250.0, -250.0])
def test_beam_column_field_matrix_matches_shin_eqs_3_15_and_3_16(P):
    """Shin's tension (sinh/cosh) and compression (sin/cos) forms,
    converted to our sign convention (theta and M negated)."""
    L, EA, EI = 0.4, 1e7, 3.0
    K = np.sqrt(abs(P) / EI)
    T = field_matrix(L, EA, EI, P)
    if P > 0:
        ch, sh, Pm = np.cosh(K * L), np.sinh(K * L), P
        w_th, w_M, w_V = sh / K, (ch - 1) / Pm, L / Pm - sh / (K * Pm)
        th_th, th_M, th_V = ch, K * sh / Pm, -(ch - 1) / Pm
        M_th, M_M, M_V = Pm * sh / K, ch, -sh / K
    else:
        c, s, Pm = np.cos(K * L), np.sin(K * L), -P
        w_th, w_M, w_V = s / K, (1 - c) / Pm, s / (K * Pm) - L / Pm
        th_th, th_M, th_V = c, K * s / Pm, -(1 - c) / Pm
        M_th, M_M, M_V = -Pm * s / K, c, -s / K
    got = [T[W, TH], T[W, M], T[W, V], T[TH, TH], T[TH, M], T[TH, V], T[M, TH], T[M, M], T[M, V]]
    want = [w_th, w_M, w_V, th_th, th_M, th_V, M_th, M_M, M_V]
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_three_field_matrix_forms_are_continuous_as_P_goes_to_zero():
    """Tension and compression forms tend to the P = 0 form: every non-zero entry changes by a
    relative O(P L^2/EI), and the only entry that is zero at P = 0 (M-theta) equals P L."""
    L, EA, EI, q, p = 0.5, 1e7, 4.0, -3.0, 2.0
    T0 = field_matrix(L, EA, EI, 0.0, q, p)
    nz = T0 != 0
    for eps in (1e-2, 1e-5, 1e-8):
        P = eps * EI / L**2          # s = P L^2 / EI = eps
        for sign in (+1, -1):
            T = field_matrix(L, EA, EI, sign * P, q, p)
            rel = np.abs(T[nz] - T0[nz]) / np.abs(T0[nz])
            assert rel.max() <= eps, (sign, eps, rel.max())
            assert T[M, TH] == pytest.approx(sign * P * L, rel=eps)
            zero = ~nz
            zero[M, TH] = False
            assert np.all(T[zero] == 0.0)


def test_distributed_load_column_integrates_the_state_equations():
    """Column 7 against direct numerical integration of the state ODE with loads."""
    from scipy.integrate import solve_ivp
    L, EA, EI, P, q, p = 0.7, 3e5, 2.0, -15.0, 4.0, -6.0

    def rhs(x, y):
        u, w, th, Mo, Vo, No = y
        return [No / EA, th, Mo / EI, -Vo + P * th, -q, -p]

    y0 = np.array([0.001, -0.002, 0.01, 0.3, -1.2, 5.0])
    sol = solve_ivp(rhs, (0, L), y0, rtol=1e-12, atol=1e-14)
    T = field_matrix(L, EA, EI, P, q, p)
    # With the axial force in the ODE held at P (beam-column linearisation).
    np.testing.assert_allclose(T @ np.r_[y0, 1.0], np.r_[sol.y[:, -1], 1.0], rtol=1e-8, atol=1e-12)


def test_point_matrix_subtracts_applied_loads_and_adds_spring_stiffness():
    T = point_matrix((1.0, 2.0, 3.0))
    S = T @ np.r_[0, 0, 0, 10.0, 20.0, 30.0, 1.0]
    assert S[N] == 29.0 and S[V] == 18.0 and S[M] == 7.0
    Ts = spring_matrix(100.0, np.pi / 2)   # vertical sliding spring: force -k w
    S = Ts @ np.r_[0.3, 0.02, 0, 0, 0, 0, 1.0]
    assert S[V] == pytest.approx(100.0 * 0.02) and S[N] == pytest.approx(0.0, abs=1e-12)


def test_frame_rotation_rotates_vectors_and_inverts():
    phi = 0.7
    T = frame_rotation(phi)
    S = np.r_[1.0, 0.0, 0.1, 0.2, 0.0, 3.0, 1.0]  # u along old x, N along old x
    R = T @ S
    np.testing.assert_allclose(R[[U, W]], [np.cos(phi), np.sin(phi)])
    np.testing.assert_allclose(R[[N, V]], [3 * np.cos(phi), 3 * np.sin(phi)])
    assert R[TH] == 0.1 and R[M] == 0.2
    np.testing.assert_allclose(frame_rotation(-phi) @ T, np.eye(7), atol=1e-15)


def test_rigid_element_secant_form_gives_exact_rigid_rotation():
    L = 2.0
    for r in (-0.8, -1e-8, 0.0, 0.3, 1.2):
        S = rigid_element_matrix(L, r) @ np.r_[0, 0, r, 0, 0, 0, 1.0]
        np.testing.assert_allclose(S[[U, W]], [L * (np.cos(r) - 1), L * np.sin(r)], atol=1e-15)
