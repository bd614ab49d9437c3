"""Periodic steady state, Floquet multipliers (issue 9)."""
import math

import numpy as np
import pytest

from cosim.overrides import prescribed_speed
from cosim.scenario import load
from tmm_core import CrankMotion, TimeDomain
from tmm_core.discretization import DEFAULT_TERMS, DYNAMIC_TERMS as SECOND_ORDER
from tmm_core.errors import ConvergenceError
from tmm_core.periodic import ORBIT_KINDS, mathieu_multipliers, orbit_stability, periodic_steady_state


def _on_angle(angle, values, N):
    a = np.mod(angle, 2 * math.pi)
    order = np.argsort(a)
    return values[order]


def test_periodic_solution_equals_time_marching_to_steady_state():
    """FE crank-rocker rig at 241 rpm (2 % damping): the one-solve periodic response and the
    time-marched steady state (same integrator and step) agree to 0.5 % of peak-to-peak
    (measured 5e-10: the periodic state is the marched map's fixed point)."""
    s = load("crank_rocker_241rpm")
    w = s.drive.speed_rad_s
    td = TimeDomain(s.mechanism, integrator="generalized_alpha", gauges=s.gauges)
    p = periodic_steady_state(td, w, step_deg=1.0)
    assert p.residual < 1e-6
    assert np.max(np.abs(p.multipliers)) < 1.0
    r = td.run(CrankMotion.constant_speed(w, step_deg=1.0, revolutions=60), start="quasi_static", steady_tol=1e-7,
               record_displacements=False)
    assert r.steady
    N = p.info["steps_per_revolution"]
    for g in p.gauges:
        marched = _on_angle(r.crank_angle[-N:], r.gauges[g][0][-N:], N)
        periodic = _on_angle(p.angle, p.gauges[g][0], N)
        assert np.max(np.abs(marched - periodic)) < 0.005 * np.ptp(marched)
    np.testing.assert_allclose(_on_angle(p.angle, p.drive_torque, N), _on_angle(r.crank_angle[-N:], r.drive_torque[-N:], N),
                               atol=0.005 * np.ptp(r.drive_torque[-N:]))


@pytest.mark.parametrize("delta, epsilon, stable", [
    # First (principal) tongue of the Mathieu chart: boundaries delta = 1/4 -+ epsilon/2 for small epsilon.
    (0.25, 0.1, False),          # inside the tongue
    (0.25 + 0.08, 0.1, True),    # above its upper boundary 0.30
    (0.25 - 0.08, 0.1, True),    # below its lower boundary 0.20
    # Second tongue near delta = 1: boundaries 1 - epsilon^2/12 and 1 + 5 epsilon^2/12.
    (1.0 + 0.05, 0.4, False),    # between 0.987 and 1.067
    (1.0 + 0.12, 0.4, True),
])
def test_floquet_multipliers_reproduce_the_mathieu_stability_chart(delta, epsilon, stable):
    mu = mathieu_multipliers(delta, epsilon)
    assert (np.max(np.abs(mu)) <= 1.0 + 1e-6) == stable
    assert abs(np.prod(mu) - 1.0) < 1e-8            # Liouville: undamped, det = 1


# -- compiled linearized revolutions (tmm_core.compiled.periodic) against the numpy reference --

def _rig(rpm, integrator=None):
    """FE crank-rocker rig (8 segments per link, second-order step) at ``rpm`` with its angle step:
    the time domain, one revolution's configurations, the state keys, N and dt."""
    from tmm_core.periodic import STATE_KEYS
    s = load("crank_rocker_373rpm")
    t = s.tmm
    td = TimeDomain(s.mechanism, integrator=integrator or t.integrator, coupling=t.coupling, beam_column=t.beam_column,
                    gravity=s.gravity, gauges=s.gauges, axial_force=t.axial_force, dynamic_terms=SECOND_ORDER)
    w = rpm * math.pi / 30
    crank = CrankMotion.constant_speed(w, step_s=t.step_rad / w, revolutions=1.0, start_angle=s.drive.start_angle_rad)
    N = crank.steps_per_revolution()
    cfg = td.configurations(crank.angle[:N], crank.speed[:N], crank.acceleration[:N], crank.dt, maps=True)
    # The stages' internals take the frozen model, not the facade.
    return td.model, cfg, STATE_KEYS[td.integrator.name], N, crank.dt


def _block_errors(fast, ref, n):
    """Largest difference in every (row, column) block of n x n, relative to the block's largest entry."""
    K = fast.shape[0] // n
    return np.array([[np.max(np.abs(fast[i * n:(i + 1) * n, j * n:(j + 1) * n] - ref[i * n:(i + 1) * n, j * n:(j + 1) * n]))
                      / np.max(np.abs(ref[i * n:(i + 1) * n, j * n:(j + 1) * n])) for j in range(K)] for i in range(K)])


@pytest.mark.parametrize("integrator", ["generalized_alpha", "newmark", "houbolt"])
def test_compiled_linearized_revolutions_match_numpy(integrator):
    """At 241 rpm the compiled linear pass (Phi, c) and monodromy of the second-order step agree
    with the numpy reference (batched steps; per-step dense solves of the step's Jacobian) to
    1e-10 in every block of the matrices (measured <= 1.2e-11), and the compiled trajectory
    velocities with the integrator's own recursion."""
    from tmm_core.compiled import binding, periodic as kp
    from tmm_core.periodic import _batched_step, _monodromy, _revolution, _state
    from tmm_core.time_step import kernel_data
    model, cfg, keys, N, dt = _rig(241.0, integrator)
    n, ns = model.n_dof, len(keys) * model.n_dof
    forced, unit = _state(model, keys, np.zeros((1, ns))), _state(model, keys, np.eye(ns))
    for k in range(1, N + 1):
        forced, _, _ = _batched_step(model, cfg, k % N, forced, dt)
        unit, _, _ = _batched_step(model, cfg, k % N, unit, dt, forced=False)
    Phi_ref = np.concatenate([unit[k] for k in keys], axis=1).T
    c_ref = np.concatenate([forced[k][0] for k in keys])
    Phi, c = kp.linear_shooting(binding.linearized(), model, kernel_data(model, cfg), keys, N, dt)
    assert np.max(_block_errors(Phi, Phi_ref, n)) < 1e-10
    # Newmark's revolution map is unstable on this rig (spectral radius 2.5: no numerical damping of
    # the stiff modes), which amplifies round-off in the forced response (measured 1.3e-10).
    tol_c = 1e-9 if integrator == "newmark" else 1e-10
    for j in range(len(keys)):
        assert np.max(np.abs(c - c_ref)[j * n:(j + 1) * n]) < tol_c * np.max(np.abs(c_ref[j * n:(j + 1) * n]))

    # Linearized about the revolution from the state one revolution after rest (with Newmark,
    # I - Phi is singular: no periodic solution to start from).
    x0 = c
    _, trajectory, _ = _revolution(model, cfg, keys, x0, N, dt)
    st, c_v = _state(model, keys, x0), model.integrator.coefficients(dt)[1]
    for j, (_, z, v, _) in enumerate(trajectory):
        _, h_v = model.integrator.history(st, dt)
        st = model.integrator.advance(st, z, dt)
        np.testing.assert_allclose(v, c_v * z + h_v, rtol=0, atol=1e-10 * np.max(np.abs(v)))
    M = kp.monodromy(binding.linearized(), model, kernel_data(model, cfg), keys, trajectory, dt)
    M_ref = _monodromy(model, cfg, keys, trajectory, dt)
    assert np.max(_block_errors(M, M_ref, n)) < 1e-10


def test_compiled_monodromy_matches_numpy_near_buckling():
    """At 373 rpm (the coupler near its buckling load; the step's Jacobian condition ~3e5 after
    scaling) the compiled monodromy agrees with the numpy one to 1e-9 of its largest entry. The
    numpy reference is itself not reproducible much below that here: measured 5e-11 on one
    checkout and 1.5e-10 on a fresh clone (BLAS's summation order with its thread count); the
    comparisons of this file fail with a term of the linearization dropped (checked with the
    Coriolis term). Unscaled, the numpy solve alone lost 1e-7."""
    from tmm_core.compiled import binding, periodic as kp
    from tmm_core.periodic import _monodromy, _revolution
    from tmm_core.time_step import kernel_data
    model, cfg, keys, N, dt = _rig(373.0)
    ns = len(keys) * model.n_dof
    Phi, c = kp.linear_shooting(binding.linearized(), model, kernel_data(model, cfg), keys, N, dt)
    _, trajectory, _ = _revolution(model, cfg, keys, np.linalg.solve(np.eye(ns) - Phi, c), N, dt)
    M = kp.monodromy(binding.linearized(), model, kernel_data(model, cfg), keys, trajectory, dt)
    M_ref = _monodromy(model, cfg, keys, trajectory, dt)
    assert np.max(np.abs(M - M_ref)) < 1e-9 * np.max(np.abs(M_ref))


def test_compiled_periodic_solution_matches_numpy():
    """The whole periodic solve at 373 rpm (Newton shooting, two monodromies) of the second-order
    segments, whose derivatives are analytic: with the compiled backend and with the numpy one (as
    without numba) the responses agree to 1e-10 of their range and the Floquet spectral radius to
    1e-10. (The co-rotational segments' twin: tests/test_corotational.py.)"""
    s = load("crank_rocker_373rpm")

    def solve(backend):
        td = s.time_domain(backend=backend, dynamic_terms=SECOND_ORDER)
        return periodic_steady_state(td, s.drive.speed_rad_s, step_s=s.engine_step_s("tmm"),
                                     start_angle=s.drive.start_angle_rad)
    fast, ref = solve("compiled"), solve("numpy")
    assert fast.info["newton_iterations"] == ref.info["newton_iterations"]
    for g in ref.gauges:
        for fa, re in zip(fast.gauges[g], ref.gauges[g]):
            assert np.max(np.abs(fa - re)) < 1e-10 * np.ptp(re)
    assert np.max(np.abs(fast.drive_torque - ref.drive_torque)) < 1e-10 * np.ptp(ref.drive_torque)
    assert abs(abs(fast.multipliers[0]) - abs(ref.multipliers[0])) < 1e-10


@pytest.mark.parametrize("delta, epsilon, kind", [
    (0.25, 0.2, "period doubling"),     # first Mathieu tongue: subharmonic, multipliers real < -1
    (1.0, 0.6, "saddle"),               # second tongue: harmonic, multipliers real > +1
    (0.5, 0.1, None),                   # between the tongues: stable
])
def test_an_unstable_orbit_is_classified_by_its_leading_multiplier(delta, epsilon, kind):
    # Independent of the classification: the Mathieu chart's odd tongues (delta = (2k+1)^2/4) are
    # the period-doubling instabilities, its even ones (delta = k^2) the harmonic ones.
    s = orbit_stability(mathieu_multipliers(delta, epsilon))
    assert s["kind"] == kind and s["stable"] == (kind is None)
    assert s["mu_max"] == pytest.approx(float(np.max(np.abs(mathieu_multipliers(delta, epsilon)))))


def test_a_complex_pair_outside_the_unit_circle_is_a_torus():
    pair = 1.2 * np.exp(0.7j)
    s = orbit_stability([0.5, pair, np.conj(pair)])
    assert s["kind"] == "torus" and s["mu_max"] == pytest.approx(1.2) and set(ORBIT_KINDS) >= {s["kind"]}


@pytest.mark.parametrize("rpm, terms", [(415.0, DEFAULT_TERMS), (450.0, DEFAULT_TERMS), (415.0, SECOND_ORDER),
                                         (445.0, SECOND_ORDER)],
                         ids=["415-corotational", "450-corotational", "415-second_order", "445-second_order"])
def test_a_diverging_newton_revolution_is_reported_as_the_steps_failure(rpm, terms):
    """FE rig past its fold, solved from the linear start: Newton's revolution diverges. Its
    report is the step's (it did not converge, with the axial forces it reached), not the
    structure's refusal of non-finite node loads nor a segment "overflowing cosh; split the link
    into more segments" (a refactorization at the diverging forces), which read as bad input,
    nor a division by zero in a co-rotational segment whose chord a diverging iterate folded
    back (seen at 445 rpm, where the co-rotational model now finds an unstable orbit: multiplier
    6.97)."""
    sc = load("crank_rocker_373rpm").with_overrides(prescribed_speed(rpm))
    with pytest.raises(ConvergenceError) as failed:
        periodic_steady_state(sc.time_domain(dynamic_terms=terms), sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"),
                              start_angle=sc.drive.start_angle_rad)
    message = str(failed.value)
    assert "must be finite" not in message and "split the link" not in message, message
    # The step's own reports: its iteration did not converge, or its dynamic system lost its
    # positive definiteness (the links buckle even with their inertia).
    assert "did not converge" in message or "not positive definite" in message, message
