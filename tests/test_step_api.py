"""The transfer-matrix step's public data and the engine's look-ahead (issue 15): typed
configuration batches, named outputs, the Anderson least squares, and a prescribed run marched
ahead in blocks giving the same answer as step by step."""
import math

import numpy as np
import pytest

from cosim.engines import make_engine
from cosim.engines.base import DriveInput, constant_speed_profile
from cosim.master import PRESCRIBED_MACRO_DEG, CoSimulation, macro_step_for
from cosim.scenario import load
from tmm_core.configuration_batch import ConfigurationBatch, OutputLayout, StepMaps
from tmm_core.anderson import anderson_coefficients

FE = "crank_rocker_241rpm"


def test_anderson_coefficients_solve_the_least_squares_problem():
    rng = np.random.default_rng(3)
    for h in (1, 2, 3, 4):
        dR, r = rng.normal(size=(40, h)), rng.normal(size=40)
        np.testing.assert_allclose(anderson_coefficients(dR, r), np.linalg.lstsq(dR, r, rcond=None)[0], rtol=1e-10)
    # A repeated column (rank-deficient history): the residual is still the least-squares one.
    dR = rng.normal(size=(40, 3))
    dR[:, 2] = dR[:, 0]
    r = rng.normal(size=40)
    gamma = anderson_coefficients(dR, r)
    best = np.linalg.lstsq(dR, r, rcond=None)[0]
    assert gamma[2] == 0.0
    assert np.linalg.norm(dR @ gamma - r) == pytest.approx(np.linalg.norm(dR @ best - r), rel=1e-10)


def test_a_configuration_batch_is_typed_and_its_outputs_are_named():
    sc = load(FE)
    td = sc.time_domain()
    w = sc.drive.speed_rad_s
    th = np.radians([0.0, 90.0, 180.0])
    cfg = td.configurations(th, np.full(3, w), np.zeros(3), 1e-4)
    assert isinstance(cfg, ConfigurationBatch) and len(cfg) == 3 and isinstance(cfg.maps, StepMaps)
    assert cfg.maps.Z.shape == (3, td.n_dof, td.n_dof) and cfg.maps.O.shape[1] == td.outputs.size
    assert cfg.maps.A.shape == (3, len(td.segments.length), td.n_dof)      # the second-order step's axial maps
    np.testing.assert_array_equal(cfg.crank.angle, th)
    layout = td.outputs
    assert layout == OutputLayout(tuple(g.name for g in sc.gauges))
    rows = np.arange(2 * layout.size, dtype=float).reshape(2, layout.size)
    parts = layout.split(rows)
    np.testing.assert_array_equal(layout.torque(rows), rows[:, 0])
    for i, g in enumerate(sc.gauges):
        np.testing.assert_array_equal(parts[g.name][0], rows[:, 1 + 2 * i])
        np.testing.assert_array_equal(parts[g.name][1], rows[:, 2 + 2 * i])
    # The numpy factorization is built on first use and kept.
    assert cfg.factor() is cfg.factor()


def _engine_run(sc, macro_steps, ahead):
    """The TMM engine advanced over ``macro_steps`` (engine steps per call) at constant speed."""
    engine = make_engine("tmm")
    w = sc.drive.speed_rad_s
    engine.reset(sc, 0.0, 0.0, w)
    h = engine.internal_step_s
    profile = constant_speed_profile(w, 0.0, 0.0)
    outs, k = [], 0
    for n in macro_steps:
        k += n
        outs.append(engine.advance(k * h, DriveInput(prescribed=profile, ahead=ahead)))
    return engine, outs


def _stack(outs, gauge):
    return np.concatenate([o.gauges[gauge][0] for o in outs]), np.concatenate([o.drive_torque for o in outs])


def test_marching_ahead_gives_the_step_by_step_answer_and_rewinds_for_a_coupling_iteration():
    sc = load(FE)
    g = sc.gauges[0].name
    plan = [1, 3, 300, 7, 1, 400, 2]           # crosses the look-ahead blocks and a revolution (720 steps)
    _, step_by_step = _engine_run(sc, plan, ahead=False)
    engine, ahead = _engine_run(sc, plan, ahead=True)
    for a, b in zip(_stack(ahead, g), _stack(step_by_step, g)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(np.concatenate([o.nodes["coupler"] for o in ahead]),
                                  np.concatenate([o.nodes["coupler"] for o in step_by_step]))
    for field in ("t", "crank_angle", "crank_speed"):      # served from the block's own arrays
        np.testing.assert_array_equal(np.concatenate([getattr(o, field) for o in ahead]),
                                      np.concatenate([getattr(o, field) for o in step_by_step]))
    assert [len(o.t) for o in ahead] == plan
    # A save in the middle of a look-ahead block rewinds the march to the steps served so far:
    # the steps after it are those of an engine that never marched ahead.
    token = engine.save()
    h, k = engine.internal_step_s, sum(plan)
    profile = constant_speed_profile(sc.drive.speed_rad_s, 0.0, 0.0)
    first = engine.advance((k + 5) * h, DriveInput(prescribed=profile, ahead=True))
    engine.restore(token)
    again = engine.advance((k + 5) * h, DriveInput(prescribed=profile))
    np.testing.assert_array_equal(first.gauges[g][0], again.gauges[g][0])
    _, reference = _engine_run(sc, plan + [5], ahead=False)
    np.testing.assert_array_equal(again.gauges[g][0], reference[-1].gauges[g][0])


def test_a_prescribed_run_advances_about_ten_degrees_per_macro_step_and_a_motor_run_its_coupling_step():
    sc = load(FE)
    H = macro_step_for(sc, ["tmm", "exudyn", "mujoco"])
    H_prescribed = macro_step_for(sc, ["tmm", "exudyn", "mujoco"], mode="prescribed")
    per_rev = 2 * math.pi / abs(sc.drive.speed_rad_s)
    ratio = H_prescribed / H
    assert abs(ratio - round(ratio)) < 1e-9 and ratio > 1
    assert H_prescribed <= per_rev * PRESCRIBED_MACRO_DEG / 360 * (1 + 1e-9)
    assert abs(per_rev / H_prescribed - round(per_rev / H_prescribed)) < 1e-6      # a whole fraction of a revolution
    assert CoSimulation(sc, ("tmm",), mode="motor").macro_step_s == pytest.approx(H)
    # The grouping changes no sample: the prescribed run equals the engine stepped one step at a time.
    res = CoSimulation(sc, ("tmm",), mode="prescribed").run(revolutions=0.5)
    n = len(res["tmm"].run.t)
    _, single = _engine_run(sc, [1] * n, ahead=False)
    g = sc.gauges[0].name
    np.testing.assert_array_equal(res["tmm"].run.gauges[g][0], _stack(single, g)[0])


def test_the_maps_are_stored_augmented_and_their_parts_are_views():
    sc = load(FE)
    td = sc.time_domain()
    cfg = td.configurations(np.radians([10.0, 200.0]), np.full(2, sc.drive.speed_rad_s), np.zeros(2), 1e-4)
    m = cfg.maps
    n = td.n_dof
    assert m.Zx.shape == (2, n, n + 1) and m.Zx.flags.c_contiguous and m.Ax.shape[2] == n + 1
    for part, whole, col in ((m.Z, m.Zx, slice(0, n)), (m.z0, m.Zx, n), (m.O, m.Ox, slice(0, n)), (m.a0, m.Ax, n)):
        assert np.shares_memory(part, whole)
        np.testing.assert_array_equal(part, whole[..., col])


@pytest.mark.parametrize("rig", [FE, "watt_sixbar_600rpm"])
def test_the_linear_axial_force_estimate_equals_the_numpy_linear_quasi_static_solution(rig):
    # Reference: the numpy statics (tmm_core.statics), not the compiled solve under test.
    from tmm_core.ked import Coupling, linear_axial_forces, quasi_static, segment_forces
    sc = load(rig)
    td = sc.time_domain()
    th = np.radians(np.arange(0.0, 360.0, 15.0))
    w, a = np.full(th.shape, sc.drive.speed_rad_s), np.zeros(th.shape)
    ref = quasi_static(td.mech, th, w, a, beam_column=False, coupling=Coupling(), gravity=td.gravity, backend="numpy")
    got = linear_axial_forces(td.mech, td.mech.motion(th, w, a), td.gravity)
    assert set(got) == set(ref.solution.members)
    for name, r in ref.solution.members.items():
        P = segment_forces(r)
        np.testing.assert_allclose(got[name], P, rtol=0, atol=1e-10 * np.max(np.abs(P)))   # rounding of two solvers


def test_an_output_array_of_the_wrong_shape_is_refused():
    from tmm_core.compiled import statics as compiled_statics
    from tmm_core.ked import rigid_body_loads
    td = load(FE).time_domain()
    motion = td.mech.motion(np.radians([0.0, 90.0]), np.full(2, 25.0), np.zeros(2))
    prep = compiled_statics.prepare(td.structure, td.mech.load_case(motion, rigid_body_loads(td.mech, motion)))
    with pytest.raises(ValueError, match="C-contiguous float64"):
        compiled_statics.solve_prepared(prep, np.zeros(prep.factor.shape), compact_nodes=[],
                                          compact_out=(np.empty((2, 3)), None))


def test_the_maps_are_built_without_huge_page_advice_and_the_advice_is_restored():
    from tmm_core.step_data import without_huge_page_advice
    core = getattr(np, "_core", None) or np.core
    get = getattr(core.multiarray, "_get_madvise_hugepage", None)
    if get is None:
        pytest.skip("this numpy has no huge-page switch")
    before = get()
    with without_huge_page_advice():
        assert get() is False
    assert get() == before
    with pytest.raises(RuntimeError):
        with without_huge_page_advice():
            raise RuntimeError("inside")
    assert get() == before


def test_a_prescribed_run_marches_no_step_past_its_end(monkeypatch):
    # The engine marches ahead in blocks; told the run's end (DriveInput.until), its last block
    # stops there. Same samples as stepping one step at a time (the test above), fewer steps.
    from tmm_core import march as march_module
    sc = load(FE)
    marched = []
    cls = next(c for c in vars(march_module).values() if isinstance(c, type) and hasattr(c, "step_many"))
    original = cls.step_many

    def counting(self, cfg, indices, *args, **kwargs):
        marched.append(len(indices))
        return original(self, cfg, indices, *args, **kwargs)
    monkeypatch.setattr(cls, "step_many", counting)
    res = CoSimulation(sc, ("tmm",), mode="prescribed").run(revolutions=1.3)
    assert sum(marched) == len(res["tmm"].run.t)
    with pytest.raises(ValueError, match="until"):
        DriveInput(prescribed=constant_speed_profile(1.0, 0.0, 0.0), until=1.0)


def test_the_engines_node_positions_are_the_rigid_ones_plus_the_rotated_displacements():
    """The TMM engine's deformed nodes (cosim.engines.tmm._nodes) against the
    closed form per link: the link's rigid-body node positions plus its local displacements
    (u along the link, w across) rotated by the link's angle, at the last step marched; a rigid
    link (the FE rig's crank) keeps its rigid-body positions."""
    sc = load(FE)
    engine, outs = _engine_run(sc, [10, 10], ahead=False)
    last = outs[-1]
    angle = float(last.crank_angle[-1])
    motion = engine.td.mech.motion(np.array([angle]), np.array([sc.drive.speed_rad_s]), np.zeros(1))
    local = engine.td.unstack(engine.march.z)
    rigid_links = 0
    for link in sc.mechanism.links():
        lm = motion.link(link.name)
        rigid = lm.point(link.stations)[0][0]                         # (n, 2)
        expected = rigid.copy()
        if link.name in local:
            u, w = local[link.name][:, 0], local[link.name][:, 1]
            c, s = math.cos(float(lm.angle[0])), math.sin(float(lm.angle[0]))
            expected += np.stack([c * u - s * w, s * u + c * w], -1)
            assert np.max(np.abs(expected - rigid)) > 1e-6              # the elastic part is there
        else:
            rigid_links += 1
        np.testing.assert_allclose(last.nodes[link.name][-1], expected, rtol=0, atol=1e-12)
    assert rigid_links == 1


# -- the backend, chosen once when the model is built (issue 33, item 3) ----------------------
def test_the_backend_is_checked_when_the_model_is_built(monkeypatch):
    """An unknown backend is refused naming it; 'compiled' without numba is refused, not run in
    numpy; the default is compiled where numba is installed, numpy where it is not."""
    from tmm_core import InputError, TimeDomain
    from tmm_core import backend as backend_module
    mechanism = load("slider_crank_600rpm").mechanism
    with pytest.raises(InputError, match="backend = 'fortran'"):
        TimeDomain(mechanism, backend="fortran")
    monkeypatch.setattr(backend_module, "AVAILABLE", False)
    with pytest.raises(InputError, match="needs numba"):
        TimeDomain(mechanism, backend="compiled")
    assert TimeDomain(mechanism).backend == "numpy"


def test_a_numpy_model_runs_no_compiled_kernel(monkeypatch):
    """Every stage of a numpy model reads its backend: the quasi-static start, the configurations
    and the march run without a compiled entry point (the quasi-static start took the compiled
    solve before the backend was the model's)."""
    from tmm_core import CrankMotion, TimeDomain
    from tmm_core.compiled import binding, statics

    def refuse(*args, **kwargs):
        raise AssertionError("a compiled kernel ran in a numpy model")
    for name in ("static_solve", "factored", "step_parts", "march", "linearized", "reduced_revolution"):
        monkeypatch.setattr(binding, name, refuse)
    monkeypatch.setattr(statics, "solve_static", refuse)
    sc = load("crank_rocker_373rpm")
    td = TimeDomain(sc.mechanism, backend="numpy", gauges=sc.gauges)
    crank = CrankMotion.constant_speed(sc.drive.speed_rad_s, step_deg=2.0, revolutions=0.05)
    result = td.run(crank, start="quasi_static")
    assert np.all(np.isfinite(result.drive_torque))
