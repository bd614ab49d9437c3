"""The compiled march (tmm_core.compiled.march) against the numpy reference path of TimeDomain (issue 15).

Both paths do the same arithmetic in a different order, so over a revolution they must agree to
round-off: 1e-12 relative, with the second-order step's iteration converged to 1e-14 so that its
stopping point does not differ between the two (at 1e-13 a start state that moved by round-off,
the compiled quasi-static start, shifted one toggle step's stopping point: 3e-12 for ten steps).
"""

import numpy as np
import pytest

from cosim.scenario import load
from tmm_core import CrankMotion, TimeDomain
from tmm_core.compiled import statics as compiled_statics
from tmm_core.compiled.cache import AVAILABLE as NUMBA

pytestmark = pytest.mark.skipif(not NUMBA, reason="numba is not installed")


def _both(sc, revolutions=1.0, **kw):
    s = sc.tmm
    opts = dict(integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                axial_force=s.axial_force, axial_tolerance=1e-14)
    opts.update(kw)
    crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"), revolutions=revolutions)
    return [TimeDomain(sc.mechanism, backend=c, **opts).run(crank, start="quasi_static") for c in ("numpy", "compiled")]


def _assert_same(a, b, rtol=1e-12):
    def rel(x, y):
        return float(np.max(np.abs(x - y)) / np.max(np.abs(x)))
    assert rel(a.drive_torque, b.drive_torque) < rtol
    for g in a.gauges:
        assert rel(a.gauges[g][0], b.gauges[g][0]) < rtol, g
        assert rel(a.gauges[g][1], b.gauges[g][1]) < rtol, g
    for link in a.displacements:
        assert rel(a.displacements[link], b.displacements[link]) < rtol, link


def test_compiled_second_order_march_equals_numpy_over_a_revolution():
    """FE rig at 373 rpm: second-order step, rotating-frame terms, Kelvin-Voigt damping, rigid crank."""
    _assert_same(*_both(load("crank_rocker_373rpm")))


def test_compiled_march_on_stored_factorizations_equals_numpy_over_a_revolution(monkeypatch):
    """The map-free compiled march (tmm_core.compiled.time_step: a solve on each configuration's
    stored factorization per iteration, instead of the dense maps) against the numpy reference,
    FE rig at 373 rpm (second-order step); measured 2.5e-13."""
    import tmm_core.batches as batches
    monkeypatch.setattr(batches, "FACTORS_ABOVE_DOF", 0)
    sc = load("crank_rocker_373rpm")
    numpy_run, compiled_run = _both(sc)
    _assert_same(numpy_run, compiled_run)
    s = sc.tmm
    td = TimeDomain(sc.mechanism, integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                    axial_force=s.axial_force, backend="compiled")
    th = np.radians(np.arange(0.0, 360.0, 30.0))
    cfg = td.configurations(th, np.full(len(th), sc.drive.speed_rad_s), np.zeros(len(th)), 1e-4)
    assert cfg.maps is None and cfg.factors is not None and "factor" not in cfg.cache


@pytest.mark.parametrize("integrator", ["newmark", "generalized_alpha"])
def test_compiled_march_on_stored_factorizations_for_the_linear_step(monkeypatch, integrator):
    """Alexander-Lawrence (elastic crank clamped at its pivot, bearing masses), linear step."""
    import tmm_core.batches as batches
    monkeypatch.setattr(batches, "FACTORS_ABOVE_DOF", 0)
    sc = load("alexander_lawrence_400rpm")
    _assert_same(*_both(sc, 0.5, integrator=integrator, axial_force="quasi_static"), rtol=5e-12)


@pytest.mark.parametrize("integrator", ["newmark", "houbolt", "generalized_alpha"])
def test_compiled_march_equals_numpy_for_every_integrator_and_the_quasi_static_axial_force(integrator):
    """Alexander-Lawrence (elastic crank, bearing masses) with the linear step. Measured 1.3e-12
    after half a revolution: the kernel's loop and numpy's BLAS sum the map products in a
    different order, and the round-off accumulates step by step (5e-12 asserted)."""
    sc = load("alexander_lawrence_400rpm")
    _assert_same(*_both(sc, 0.5, integrator=integrator, axial_force="quasi_static"), rtol=5e-12)


def test_the_engine_uses_the_compiled_path_and_gets_the_same_answer():
    from cosim.engines import make_engine
    from cosim.master import run_prescribed
    sc = load("slider_crank_600rpm")
    runs = []
    for compiled in (False, True):
        engine = make_engine("tmm")
        original = TimeDomain.__init__

        def init(self, *a, _c=compiled, **k):
            original(self, *a, **{**k, "backend": "compiled" if _c else "numpy"})
        TimeDomain.__init__ = init
        try:
            runs.append(run_prescribed(engine, sc, revolutions=1.0))
        finally:
            TimeDomain.__init__ = original
    np.testing.assert_allclose(runs[1].drive_torque, runs[0].drive_torque, rtol=1e-7, atol=1e-9)


def test_motor_driven_steps_use_the_stored_factorizations_and_agree_with_numpy():
    """Motor-driven (the crank speed varies): the steps off the cached revolution are factorized per
    macro step and marched on the stored factorizations (maps='factors'), not in numpy as before
    (1 revolution of the FE rig at 373 rpm: 7.9 -> 0.64 s); same answer as the numpy path."""
    from cosim.engines import make_engine
    from cosim.master import CoSimulation
    from tmm_core import step_data
    sc = load("crank_rocker_373rpm")
    runs, calls = [], []
    original_init, original_factors = TimeDomain.__init__, step_data.compiled_factors

    def counted(*a, **k):
        calls.append(1)
        return original_factors(*a, **k)
    for compiled in (False, True):
        def init(self, *a, _c=compiled, **k):
            original_init(self, *a, **{**k, "backend": "compiled" if _c else "numpy"})
        TimeDomain.__init__, step_data.compiled_factors = init, counted
        try:
            res = CoSimulation(sc, {"tmm": make_engine("tmm")}, mode="motor").run(revolutions=0.15)
        finally:
            TimeDomain.__init__, step_data.compiled_factors = original_init, original_factors
        runs.append(res["tmm"].run)
        assert res["tmm"].status == "completed"
    assert len(calls) > 5                 # every macro step of the compiled run
    np.testing.assert_allclose(runs[1].drive_torque, runs[0].drive_torque, rtol=1e-9, atol=1e-9 * np.max(
        np.abs(runs[0].drive_torque)))
    for g, (bending, _) in runs[0].gauges.items():
        np.testing.assert_allclose(runs[1].gauges[g][0], bending, rtol=0, atol=1e-9 * np.max(np.abs(bending)))


# -- the compiled factorization (tmm_core.compiled.structure) ---------------------------------------
def _fe_quasi_static_case(segments=8, positions=72):
    from tmm_core.ked import Coupling, coupling_stiffness, rigid_body_loads
    sc = load("crank_rocker_241rpm").with_overrides({"solver.tmm.segments": segments})
    mech = sc.mechanism
    motion = mech.motion(np.radians(np.linspace(0.0, 360.0, positions, endpoint=False)), sc.drive.speed_rad_s, 0.0)
    stiffness = coupling_stiffness(mech, motion, Coupling(False, True, True), mass_damping=0.0)
    return sc, mech, mech.load_case(motion, rigid_body_loads(mech, motion, sc.gravity), None, stiffness)


def _rel(x, y):
    return float(np.max(np.abs(x - y)) / np.max(np.abs(x)))


def test_compiled_factorization_equals_numpy_for_a_beam_column_solve():
    """One linear solve of the FE rig at 72 crank positions, with compressive and tensile segment
    forces in the field matrices and the rotating-frame node stiffness: every station state, the
    support reactions and the inertia count agree with tmm_core.structure to 1e-12."""
    from tmm_core.compiled import statics as compiled_statics
    from tmm_core.structure import solve_linear
    _, mech, case = _fe_quasi_static_case()
    structure = mech.structure()
    rng = np.random.default_rng(1)
    P = {m.name: rng.uniform(-200.0, 300.0, (72, m.n_segments)) for m in structure.members}
    ref = solve_linear(structure, case, P, count_inertia=True)
    new = compiled_statics.solve_linear(structure, case, P, count_inertia=True)
    for name, r in ref.members.items():
        for k in range(6):
            assert _rel(r.state[..., k], new.members[name].state[..., k]) < 1e-12, (name, k)
    for joint, R in ref.reactions.items():
        assert _rel(R, new.reactions[joint]) < 1e-12, joint
    np.testing.assert_array_equal(ref.negative_eigenvalues, new.negative_eigenvalues)


def test_compiled_quasi_static_revolution_equals_numpy():
    """The beam-column quasi-static iteration (same successive solutions, relaxation and stop)
    in the compiled factorization against the numpy path: same iteration count, 1e-12."""
    from tmm_core import quasi_static
    sc, mech, _ = _fe_quasi_static_case()
    th = np.radians(np.arange(0.0, 360.0, 5.0))
    runs = [quasi_static(mech, th, sc.drive.speed_rad_s, beam_column=True, coupling=sc.tmm.coupling,
                         gravity=sc.gravity, gauges=sc.gauges, backend=c) for c in ("numpy", "compiled")]
    assert runs[0].solution.iterations == runs[1].solution.iterations
    assert _rel(runs[0].drive_torque, runs[1].drive_torque) < 1e-12
    for g in runs[0].gauges:
        for k in range(2):
            assert _rel(runs[0].gauges[g][k], runs[1].gauges[g][k]) < 1e-12, g


def test_beam_column_iteration_that_cannot_meet_its_tolerance_fails_alike_in_both_paths():
    """At an unreachable tolerance the iteration stops at ``max_iter`` solves with
    ConvergenceError in the numpy path and in the compiled one (which iterates each position in
    the kernel and reports the positions that did not converge)."""
    from tmm_core import ConvergenceError
    from tmm_core.compiled import statics as compiled_statics
    from tmm_core.statics import solve_static
    _, mech, case = _fe_quasi_static_case(positions=12)
    structure = mech.structure()
    for solver in (solve_static, compiled_statics.solve_static):
        with pytest.raises(ConvergenceError, match="did not converge in 3 iterations"):
            solver(structure, case, beam_column=True, tol=1e-30, max_iter=3, count_inertia=True)
    # A reachable tolerance: both converge, after the same number of solves.
    runs = [solver(structure, case, beam_column=True, tol=1e-8, max_iter=8, count_inertia=True)
            for solver in (solve_static, compiled_statics.solve_static)]
    assert runs[0].iterations == runs[1].iterations <= 8


@pytest.mark.parametrize("speed, max_iter, error", [(1.0, 200, None), (1.0, 3, "did not converge in 3"),
                                                    (40.0, 200, "buckling load")])
def test_one_call_beam_column_iteration_equals_the_two_call_one(monkeypatch, speed, max_iter, error):
    """The compiled iteration of a batch in one call (linear solve, its checks, the change scales
    and the iteration: compiled_statics._run with cond_limit, taken with more than one thread) against
    the linear solve and the iteration in two calls with the scales from numpy: the same
    results bit for bit, and the same error where the iteration or the linear solve fails
    (``speed`` x the rig's: 40x is above the first natural frequency, negative stiffness; 3
    solves are too few for the tolerance)."""
    from tmm_core import TMMError
    from tmm_core.compiled import statics as compiled_statics
    from tmm_core.ked import Coupling, coupling_stiffness, rigid_body_loads
    sc, mech, _ = _fe_quasi_static_case()
    motion = mech.motion(np.radians(np.linspace(0.0, 360.0, 72, endpoint=False)), speed * sc.drive.speed_rad_s, 0.0)
    case = mech.load_case(motion, rigid_body_loads(mech, motion, sc.gravity), None,
                          coupling_stiffness(mech, motion, Coupling(False, True, True), mass_damping=0.0))
    runs, calls = [], []
    run = compiled_statics._run
    monkeypatch.setattr(compiled_statics, "_run", lambda *a, **k: calls.append(k.get("cond_limit")) or run(*a, **k))
    for chunks in (2, 1):
        monkeypatch.setattr(compiled_statics, "_thread_chunks", lambda B, solves, n=chunks: min(B, n))
        try:
            runs.append(compiled_statics.solve_static(mech.structure(), case, beam_column=True, tol=1e-10,
                                                        max_iter=max_iter, count_inertia=True))
        except TMMError as exc:
            runs.append(exc)
    assert calls[0] is not None and calls[-1] is None       # one call, then the two
    if error is not None:
        assert type(runs[0]) is type(runs[1]) and str(runs[0]) == str(runs[1]) and error in str(runs[0])
        return
    assert runs[0].iterations == runs[1].iterations and runs[0].last_change == runs[1].last_change
    for name, r in runs[1].members.items():
        np.testing.assert_array_equal(runs[0].members[name].state, r.state)
        np.testing.assert_array_equal(runs[0].members[name].axial_force, r.axial_force)
    for joint, R in runs[1].reactions.items():
        np.testing.assert_array_equal(runs[0].reactions[joint], R)


@pytest.mark.parametrize("segments", [1, 4])
def test_inertia_count_of_a_pinned_pinned_column_changes_exactly_at_the_euler_load(segments):
    """Wittrick-Williams count from the factorization's pivots (no eigenvalue problem): a
    pinned-pinned column carries no negative pivot just below pi^2 EI / L^2 and exactly one just
    above it (and two above the second Euler load, 4 pi^2 EI / L^2), in the compiled
    factorization and in the numpy path; beyond the Euler load the solve is refused."""
    from tmm_core.compiled import statics as compiled_statics
    from tmm_core.errors import BucklingError
    from tmm_core.sections import Material, Section
    from tmm_core.structure import Joint, LoadCase, Member, Structure, solve_linear
    L, E, section = 0.5, 70e9, Section.rectangle(0.02, 0.002)
    column = Structure((Joint("A", "pinned"), Joint("B", "pinned")),
                       (Member.uniform("col", "A", "B", L, segments, section, Material("al", E)),))
    case = LoadCase({"A": np.zeros((1, 2)), "B": np.array([[0.0, L]])})
    euler = np.pi**2 * E * section.inertia_m4 / L**2
    for factor, expected in ((0.999999, 0), (1.000001, 1), (3.99999, 1), (4.00001, 2)):
        P = {"col": np.full((1, segments), -factor * euler)}
        for solve in (solve_linear, compiled_statics.solve_linear):
            sol = solve(column, case, P, check_buckling=False, count_inertia=True)
            assert int(sol.negative_eigenvalues[0]) == expected, (solve.__module__, factor)
    with pytest.raises(BucklingError, match="at or beyond its buckling load"):
        compiled_statics.solve_linear(column, case, {"col": np.full((1, segments), -1.001 * euler)})
    compiled_statics.solve_linear(column, case, {"col": np.full((1, segments), -0.999 * euler)})


@pytest.mark.parametrize("scenario", ["crank_rocker_373rpm", "alexander_lawrence_400rpm", "watt_sixbar_600rpm"])
def test_compiled_configuration_maps_equal_numpy(scenario):
    """TimeDomain.configurations: the load-to-response maps (displacements, drive torque, gauges,
    segment axial forces) from the compiled factorization against the numpy factorization and
    Riccati sweeps of every unit load. Displacements to 1e-12 of the map's largest entry (measured
    1.4e-14); outputs and axial forces to 1e-11 (measured 1.1-3.0e-12): their round-off floor, the
    numpy path against itself with only its 3x3 inverses switched (LAPACK for a small batch,
    adjugate for a large one) differs by 3.3e-12."""
    sc = load(scenario)
    s = sc.tmm
    tds = [TimeDomain(sc.mechanism, integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                      axial_force=s.axial_force, backend=c) for c in ("numpy", "compiled")]
    assert tds[1].compiled_factorization and not tds[0].compiled_factorization
    th = np.radians(np.arange(0.0, 360.0, 10.0))
    w = sc.drive.speed_rad_s
    cfgs = [td.configurations(th, np.full(len(th), w), np.zeros(len(th)), 1e-4, maps=True) for td in tds]
    assert "factor" not in cfgs[1].cache
    for key, ref in vars(cfgs[0].maps).items():     # z0 is zero: no loads without the unit loads
        tol = 1e-12 if key in ("Z", "z0") else 1e-11
        assert np.max(np.abs(ref - getattr(cfgs[1].maps, key))) <= tol * np.max(np.abs(ref)), key
    np.testing.assert_array_equal(cfgs[0].indefinite, cfgs[1].indefinite)
    assert cfgs[1].factor().batch == cfgs[0].factor().batch


@pytest.mark.parametrize("scenario", ["crank_rocker_373rpm", "alexander_lawrence_400rpm", "watt_sixbar_600rpm"])
def test_vectorized_map_solve_equals_the_per_load_set_solve(scenario, monkeypatch):
    """The maps' load solve (tmm_core.compiled.step_data: every unit load of a configuration at once,
    vectorized across them, compact outputs) against the per-load-set solve
    (compiled_structure.solve_loads, taken when every station state is asked for) on the same prepared
    batch: node displacements, segment axial forces, joint displacements and forces, and the
    right-side state of every node (the gauges' output, here at all nodes: the stations before and
    after each member's first deformable segment). The same arithmetic in the same order: 1e-12 is
    a margin (measured: equal)."""
    from tmm_core.compiled import statics as compiled_statics
    sc = load(scenario).with_overrides({"solver.tmm.segments": 4})
    s = sc.tmm
    td = TimeDomain(sc.mechanism, integrator=s.integrator, coupling=s.coupling, gravity=sc.gravity, gauges=sc.gauges,
                    axial_force=s.axial_force, backend="compiled")
    assert td.axial_force == "dynamic" and td.gauges
    calls = []
    solve = compiled_statics.solve_prepared

    def captured(prep, P, **kw):
        if kw.get("node_loads") is not None:
            calls.append((prep, np.array(P), kw))
        return solve(prep, P, **kw)

    monkeypatch.setattr(compiled_statics, "solve_prepared", captured)
    th = np.radians(np.arange(0.0, 360.0, 20.0))
    td.configurations(th, np.full(len(th), sc.drive.speed_rad_s), np.zeros(len(th)), 1e-4, maps=True)
    assert len(calls) == 1
    prep, P, kw = calls[0]
    lay = prep.layout
    Nn = prep.Kn.shape[1]
    (z, N, g), q, reaction, _ = solve(prep, P, **dict(kw, compact_nodes=list(range(Nn))))
    states, q1, reaction1, _ = solve(prep, P, **dict(kw, compact_nodes=None))       # (B, R, Nn, 2, 6)
    assert z.shape[2] == kw["node_loads"].shape[1] == td.n_dof + 1
    left = np.arange(int(lay.seg_off[-1])) + np.repeat(np.arange(len(lay.seg_off) - 1), np.diff(lay.seg_off))
    N1 = np.where(lay.rigid, 0.0, 0.5 * (states[:, :, left, 1, 5] + states[:, :, left + 1, 0, 5]))
    pairs = {"z": (z, np.moveaxis(states[:, :, :, 0, :3].reshape(len(P), z.shape[2], -1), 1, 2)),
             "N": (N, np.moveaxis(N1, 1, 2)), "gauge states": (g, np.moveaxis(states[:, :, :, 1, :], 1, -1)),
             "q": (q, q1), "reaction": (reaction, reaction1)}
    for key, (new, ref) in pairs.items():
        assert new.shape == ref.shape, key
        assert np.max(np.abs(new - ref)) <= 1e-12 * np.max(np.abs(ref)), key


def test_iteration_stopping_rule_on_a_geometric_sequence():
    """Changes falling by r = 1e-3 a solve: the rule stops where the implied error
    (change * r / (1 - r)) is below tol, which needs three changes; a change below tol stops
    at once; a growing or single change does not."""
    from tmm_core.statics import iteration_converged
    assert not iteration_converged([1e-1], 1e-10)
    assert not iteration_converged([1e-1, 1e-4], 1e-10)
    assert iteration_converged([1e-1, 1e-4, 1e-7], 1e-9)          # implied error 1e-10
    assert not iteration_converged([1e-1, 1e-4, 1e-7], 1e-11)
    assert not iteration_converged([1e-1, 1e-2, 1e-3, 1e-3], 1e-3)   # stalled: r = 1
    assert iteration_converged([1.0, 1e-11], 1e-10)


@pytest.mark.parametrize("scenario", ["crank_rocker_241rpm", "crank_rocker_373rpm", "watt_sixbar_600rpm"])
def test_quasi_static_stop_is_within_its_tolerance_of_the_converged_answer(scenario):
    """Convergence check of the stopping rule: the answer at tol 1e-8 (the rule may stop on the
    implied error, one solve before the change itself falls below tol) lies within 1e-8 of the
    answer at 1e-13, in the tolerance's own measure: displacements (rotations x the longest
    link) against the largest displacement of the batch, forces (moments / the longest link)
    against the largest force. At 373 rpm the configurations stop after different numbers of
    solves (the iteration runs to each one's own stop)."""
    from cosim.scenario import load
    from tmm_core import quasi_static
    sc = load(scenario)
    th = np.radians(np.arange(0.0, 360.0, 15.0))

    def solve(tol):
        return quasi_static(sc.mechanism, th, sc.drive.speed_rad_s, beam_column=True, coupling=sc.tmm.coupling,
                            gravity=sc.gravity, tol=tol).solution

    loose, tight = solve(1e-8), solve(1e-13)
    Lc = max(r.member.length for r in tight.members.values())
    w = np.array([1.0, 1.0, Lc, 1.0 / Lc, 1.0, 1.0])
    for part in (slice(0, 3), slice(3, 6)):
        scale = max(np.max(np.abs(ref.state[..., part] * w[part])) for ref in tight.members.values())
        err = max(np.max(np.abs((loose.members[k].state - ref.state)[..., part] * w[part]))
                  for k, ref in tight.members.items())
        assert err <= 1e-8 * scale, part


def _quasi_static_in_two_threads():
    from tmm_core import quasi_static
    sc, mech, _ = _fe_quasi_static_case()
    th = np.radians(np.arange(0.0, 360.0, 5.0))        # 72 positions: two parts of the batch
    return quasi_static(mech, th, sc.drive.speed_rad_s, beam_column=True, coupling=sc.tmm.coupling,
                        gravity=sc.gravity, backend="compiled").drive_torque


def _child(queue):
    queue.put(float(np.max(_quasi_static_in_two_threads())))


def test_a_forked_child_runs_the_threaded_batch_solve(monkeypatch):
    """The batch solve's thread pool does not survive a fork (its threads stay in the parent): a
    forked worker that solves a batch in two parts makes its own pool instead of waiting forever
    on the copied one; same answer as the parent's."""
    import multiprocessing
    monkeypatch.setattr(compiled_statics, "THREADS", 2)
    expected = float(np.max(_quasi_static_in_two_threads()))      # the parent's pool now exists
    queue = multiprocessing.get_context("fork").Queue()
    child = multiprocessing.get_context("fork").Process(target=_child, args=(queue,))
    child.start()
    child.join(timeout=120)
    if child.is_alive():
        child.kill()
        pytest.fail("the forked child's batch solve did not finish in 120 s")
    assert child.exitcode == 0 and queue.get(timeout=5) == expected
