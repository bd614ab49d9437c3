"""The dominant Floquet multipliers read off successive revolutions
(:mod:`tmm_core.revolution_dmd`), and the periodic solver's use of them for an orbit reached from a
guess. Expected values: the eigenvalues of a known linear map (closed form), and the full
monodromy of a cold solve (Newton shooting, the exact linearization)."""
import numpy as np
import pytest

from cosim.scenario import load
from tmm_core.periodic import READ_TRUSTED_BELOW, periodic_steady_state
from tmm_core.revolution_dmd import dominant_multipliers


def _affine_revolutions(eigenvalues, n=12, revolutions=30, seed=3):
    """Revolutions of ``y -> M y + c`` with M's eigenvalues given (a complex pair allowed) from a
    random start: the changes evolve by M whatever the fixed point."""
    rng = np.random.default_rng(seed)
    Q = rng.standard_normal((n, n))
    D = np.zeros((n, n))
    vals = list(eigenvalues) + [0.005] * (n - len(eigenvalues))
    i = 0
    while i < n:
        v = vals[i]
        if np.iscomplex(v):
            D[i:i + 2, i:i + 2] = [[v.real, v.imag], [-v.imag, v.real]]
            i += 2
        else:
            D[i, i] = v
            i += 1
    M = Q @ D @ np.linalg.inv(Q)
    y, c = [rng.standard_normal(n)], rng.standard_normal(n)
    for _ in range(revolutions):
        y.append(M @ y[-1] + c)
    return np.array(y)


def test_the_multipliers_of_a_linear_map_are_read_exactly():
    pair = 0.5 * np.exp(1j * np.radians(120))
    mu, read = dominant_multipliers(_affine_revolutions([pair, np.conj(pair), 0.3, -0.2]), rank=12)
    assert read > 12
    np.testing.assert_allclose(np.abs(mu[:4]), [0.5, 0.5, 0.3, 0.2], rtol=1e-8)
    assert abs(np.degrees(np.angle(mu[0]))) == pytest.approx(120, rel=1e-8)


def test_changes_at_the_rounding_floor_are_not_read():
    """A map that settles within a few revolutions: only the changes above the floor count, and
    fewer than two give no reading."""
    y = _affine_revolutions([0.01], revolutions=10)
    _, read = dominant_multipliers(y, floor=1e-9)
    assert 2 <= read <= 6
    assert len(dominant_multipliers(y[:2])[0]) == 0


@pytest.fixture(scope="module")
def fe_rig():
    return load("crank_rocker_373rpm")


def _solve(sc, rpm, guess=None):
    s = sc.with_overrides({"drive.speed": f"{rpm} rpm"})
    return periodic_steady_state(s.time_domain().model, s.drive.speed_rad_s, step_s=s.engine_step_s("tmm"),
                                 initial_state=guess)


@pytest.mark.parametrize("rpm", [pytest.param(220, marks=pytest.mark.slow), 300, 373,
                                 pytest.param(350, marks=pytest.mark.slow), pytest.param(390, marks=pytest.mark.slow)])
def test_an_orbit_from_a_guess_reads_its_largest_multiplier_as_the_monodromy_gives_it(fe_rig, rpm):
    """Continued from 5 rpm below, the largest multiplier is read off the revolutions, within 1e-3
    of the cold solve's full monodromy at five check speeds (issue 37; measured: within 2e-5 from
    210 to 420 rpm)."""
    continued = _solve(fe_rig, rpm, guess=_solve(fe_rig, rpm - 5).state)
    cold = _solve(fe_rig, rpm)
    assert continued.info.get("multipliers", "").startswith("read off")
    assert abs(abs(continued.multipliers[0]) - abs(cold.multipliers[0])) < 1e-3
    assert abs(continued.multipliers[0]) < READ_TRUSTED_BELOW


def test_an_orbit_whose_perturbation_dies_too_fast_gets_the_monodromy(fe_rig):
    """At 150 rpm the largest multiplier is 0.02: a perturbation is at the rounding after three
    revolutions, too few to read, so the full monodromy is computed."""
    continued = _solve(fe_rig, 150, guess=_solve(fe_rig, 145).state)
    assert "multipliers" not in continued.info
    assert len(continued.multipliers) > 100           # every multiplier of the monodromy
