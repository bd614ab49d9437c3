"""Continuation in speed (issue 37): Anderson-accelerated revolutions from a guess, the secant
predictor, the sweep's contiguous blocks per worker, and the continuation sweep against
independent per-point solves (expected values always from independent solves)."""
from __future__ import annotations

import numpy as np
import pytest

from cosim.overrides import prescribed_speed
from cosim.parallel import BlockPool
from cosim.scenario import SCENARIO_DIR, load
from cosim.sweeps import periodic_solution, predicted_state, run_sweep
from tmm_core.anderson import AndersonOptions, anderson, block_weights


def _affine_map(multipliers, seed=0):
    """``x -> A x + b`` with the given eigenvalues of ``A`` (a non-normal basis) and its fixed point
    from a direct solve."""
    rng = np.random.default_rng(seed)
    V = rng.normal(size=(len(multipliers), len(multipliers)))
    A = V @ np.diag(multipliers) @ np.linalg.inv(V)
    b = rng.normal(size=len(multipliers))
    return (lambda x: (A @ x + b, None)), np.linalg.solve(np.eye(len(b)) - A, b)


def test_anderson_reaches_the_fixed_point_in_fewer_revolutions_than_plain_iteration():
    """A contraction whose slowest multiplier is 0.9: plain revolutions need ~200 to reach 1e-9,
    the mixing of the last six a handful; the point is the directly solved one."""
    revolve, exact = _affine_map([0.9, -0.7, 0.5, 0.3, 0.1, 0.05, 0.01, 0.0])
    fp = anderson(revolve, np.ones(8), np.ones(8), AndersonOptions(tolerance=1e-9))
    assert fp.converged and fp.residual < 1e-9
    assert fp.revolutions <= 15
    np.testing.assert_allclose(fp.x, exact, rtol=1e-7, atol=1e-7 * np.max(np.abs(exact)))


def test_anderson_reports_a_stall_instead_of_an_answer_when_revolutions_cannot_converge():
    """A map whose revolutions grow without bound (a multiplier 3): not converged, and the best
    iterate is returned for the caller's Newton fallback; a revolution that raises ends it too."""
    revolve, _ = _affine_map([3.0, 2.5, 2.0])
    fp = anderson(revolve, np.ones(3), np.ones(3), AndersonOptions(tolerance=1e-12, iterations=8, memory=1))
    assert not fp.converged and np.isfinite(fp.residual)

    def failing(x):
        raise np.linalg.LinAlgError("singular")
    fp = anderson(failing, np.ones(3), np.ones(3), AndersonOptions(tolerance=1e-9))
    assert not fp.converged and fp.residual == np.inf and fp.image is None


def test_block_weights_give_each_part_of_the_state_unit_size():
    w = block_weights(np.array([1e-4, -2e-4, 3.0, 1.0, 0.0, 0.0]), 3)
    np.testing.assert_allclose(w, [5e3, 5e3, 1 / 3, 1 / 3, 1.0, 1.0])


def test_the_secant_predictor_is_exact_for_states_linear_in_speed_and_keeps_its_reach():
    x = lambda rpm: np.array([1.0, 2.0]) + rpm * np.array([0.5, -0.25])   # noqa: E731
    np.testing.assert_allclose(predicted_state([(100.0, x(100.0)), (105.0, x(105.0))], 110.0), x(110.0))
    np.testing.assert_allclose(predicted_state([(105.0, x(105.0))], 110.0), x(105.0))
    assert predicted_state([(100.0, x(100.0))], 300.0) is None and predicted_state([], 300.0) is None
    # A worker's next block starts far from its last one: no secant through the two (455 rpm,
    # another block's orbit past the fold, and 405 rpm extrapolated to 415 rpm), the last alone.
    np.testing.assert_allclose(predicted_state([(455.0, x(455.0)), (405.0, x(405.0))], 415.0), x(405.0))


def test_the_block_pool_runs_contiguous_blocks_last_first_and_answers_each_job():
    """Seven jobs in three blocks: runs of consecutive jobs (3, 3, 1), handed to the pool once the
    last job is submitted, the last block first; each job's future gets its own result or error."""
    from concurrent.futures import Future

    class Immediate:
        def __init__(self):
            self.blocks = []

        def submit(self, fn, calls):
            self.blocks.append([args[0] for _, args in calls])
            future = Future()
            future.set_result(fn(calls))
            return future

    def square(k):
        if k == 4:
            raise ValueError("no four")
        return k * k

    pool = Immediate()
    blocks = BlockPool(pool, 7, 3)
    futures = [blocks.submit(square, k) for k in range(7)]
    assert pool.blocks == [[6], [3, 4, 5], [0, 1, 2]]
    assert [f.result() for k, f in enumerate(futures) if k != 4] == [0, 1, 4, 9, 25, 36]
    with pytest.raises(ValueError, match="no four"):
        futures[4].result()


def _light(tmp_path, extra=""):
    path = tmp_path / "rig_light.toml"
    path.write_text(f'extends = "{SCENARIO_DIR / "crank_rocker_373rpm"}.toml"\n\n[solver.tmm]\nsegments = 4\n{extra}',
                    encoding="utf-8")
    return path


def _independent(path, rpm, model):
    """A cold periodic solve at ``rpm`` in this process, with no orbit to continue from."""
    sc = load(str(path)).with_overrides({"solver.tmm.model": model, **prescribed_speed(rpm)})
    return periodic_solution(sc)


def _compare(summary, path, model, speeds, rtol):
    """Peaks and the largest multiplier of the sweep's points at ``speeds`` against independent
    solves (each to the solvers' own tolerance, so they agree to well within ``rtol``)."""
    points = {p["rpm"]: p["engines"]["tmm"] for p in summary["points"]}
    for rpm in speeds:
        p, tmm = _independent(path, rpm, model), points[rpm]
        assert tmm["status"] == "completed", tmm
        for g, (bending, axial) in p.gauges.items():
            stats = tmm["gauges"][g]
            scale = max(abs(bending).max(), 1e-12) * 1e6
            assert abs(stats["bending_max_ue"] - bending.max() * 1e6) < rtol * scale
            assert abs(stats["bending_min_ue"] - bending.min() * 1e6) < rtol * scale
        assert abs(tmm["floquet_max"] - abs(p.multipliers[0])) < 1e-3


def test_a_small_continuation_sweep_matches_independent_solves(tmp_path):
    """Ten speeds on one worker (enough for continuation): every point after the first starts
    from the previous orbits, and the peaks and largest multipliers equal cold solves."""
    path = _light(tmp_path)
    _, summary = run_sweep(str(path), "300:345:5", ("tmm",), workers=1, out=tmp_path / "out", progress=False,
                           record=False, resonance=False, model="full")
    starts = [p["engines"]["tmm"].get("start") for p in summary["points"]]
    assert summary["status"] == "completed"
    assert sum(s is not None and s.startswith("guess") for s in starts) >= 8, starts
    _compare(summary, path, "full", (305.0, 345.0), 1e-5)


def test_a_two_speed_sweep_continues_past_the_fold(tmp_path):
    """The full model continues in any sweep: 405 then 415 rpm on the FE rig. From the linear
    start 415 rpm has no orbit (a 7-point sweep left it unsolved); from 405 rpm's orbit it finds
    an unstable one. The reduced model, solved from its own linear start, also has an unstable
    orbit there (|mu| = 1.15, docs/validation.md, the slim model's gate)."""
    _, summary = run_sweep(str(SCENARIO_DIR / "crank_rocker_373rpm.toml"), "405,415", ("tmm",), workers=1,
                           out=tmp_path / "out", progress=False, record=False, resonance=False)
    points = {p["rpm"]: p["engines"]["tmm"] for p in summary["points"]}
    assert points[415.0]["status"] == "completed", points[415.0].get("error")
    assert points[415.0]["start"].startswith("guess")
    assert points[415.0]["floquet_max"] > 1.0 and points[415.0]["orbit"] != "stable"


@pytest.mark.slow
@pytest.mark.parametrize("model", ["full", "reduced"])
def test_the_continuation_sweep_equals_independent_solves_at_a_handful_of_speeds(tmp_path, model):
    """The 8-segment rig over 100-400 rpm in 10 rpm steps on two workers (contiguous blocks,
    the first point solved in the parent): at five speeds across both blocks the peaks and the
    largest multiplier equal independent cold solves."""
    path = tmp_path / "rig.toml"
    path.write_text(f'extends = "{SCENARIO_DIR / "crank_rocker_373rpm"}.toml"\n', encoding="utf-8")
    _, summary = run_sweep(str(path), "100:400:10", ("tmm",), workers=2, out=tmp_path / "out", progress=False,
                           record=False, resonance=False, model=model)
    _compare(summary, path, model, (110.0, 200.0, 250.0, 340.0, 400.0), 1e-5)
