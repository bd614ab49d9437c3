"""Kineto-elastodynamics of the four-bar: quasi-static, time domain, integrators, materials."""
import math

import numpy as np
import pytest

from cosim.units import INCH, PSI, RPM
from tmm_core import (AssemblyError, Coupling, CrankMotion, Damping, Gauge, InputError, Joint, Link, Material,
                      PointMass, Section, SingularStructureError, StandardLinearSolid, TimeDomain, quasi_static,
                      soderberg, time_domain)
from tmm_core.mechanism import StaticMechanism

from scenarios.rigs import alexander_lawrence

W400 = -400 * RPM          # Shin: 400 rpm clockwise
#: The Alexander-Lawrence follower's largest angular acceleration [rad/s^2] at 400 rpm
#: (docs/validation.md, "Shin's Alexander-Lawrence stresses"), from an independent loop-closure
#: solution differentiated numerically:
#: ``python -m tests.benchmarks.kinematics_references --only alexander_lawrence_alpha``.
AL_ROCKER_MAX_ALPHA = 1769
ROCKER_MID = Gauge("rocker_mid", "rocker", 10.5 * INCH / 2, "top")
COUPLER_MID = Gauge("coupler_mid", "coupler", 11 * INCH / 2, "top")


def test_quasi_static_rocker_midspan_matches_closed_form():
    """Linear kineto-elastostatics of the rocker: pinned at D and C, it is a simply supported beam
    under its own inertia load rho A alpha x, so the midspan bending stress is
    (3/8) rho alpha4 L^3 / h at every crank position (docs/validation.md, "Shin's Alexander-Lawrence
    stresses sit about 2.7x above a closed form"), tension on the -y face for alpha4 > 0. The
    bearing masses sit on the coupler ends and load the rocker only at C."""
    mech = alexander_lawrence(16)
    th = np.radians(np.arange(0.0, 360.0, 2.0))
    qs = quasi_static(mech, th, W400, beam_column=False, gauges=[ROCKER_MID])
    rho, L, h, E = mech.rocker.material.density_kg_m3, mech.rocker.length_m, mech.rocker.section.depth_m, \
        mech.rocker.material.E_Pa
    expected = -(3.0 / 8.0) * rho * qs.motion.rocker.alpha * L**3 / h / E
    bending, axial = qs.gauges["rocker_mid"]
    peak = np.max(np.abs(expected))
    # Lumping the distributed load on 16 segments: agreement within 0.2 % of the peak.
    np.testing.assert_allclose(bending, expected, atol=2e-3 * peak)
    assert np.max(np.abs(qs.motion.rocker.alpha)) == pytest.approx(AL_ROCKER_MAX_ALPHA, rel=2e-3)


def test_quasi_static_converges_with_segment_count():
    th = np.radians(np.arange(0.0, 360.0, 5.0))
    peaks = []
    for n in (4, 8, 16, 32):
        qs = quasi_static(alexander_lawrence(n), th, W400, beam_column=True, gauges=[ROCKER_MID, COUPLER_MID])
        peaks.append([np.ptp(qs.gauges[g][0]) for g in ("rocker_mid", "coupler_mid")])
    d = np.abs(np.diff(np.array(peaks), axis=0))
    order = np.log2(d[:-1] / d[1:])
    assert np.all(order > 1.7), order          # lumped mass: second order in the segment length


def test_quasi_static_drive_torque_matches_rigid_inverse_dynamics():
    """With links 1000x stiffer, the crank-pivot reaction equals the rigid-body drive torque from
    virtual power, T w + sum(F . v) = 0, at every position (variable speed: alpha != 0)."""
    mech = alexander_lawrence(8, E_factor=1000.0)
    th = np.radians(np.arange(0.0, 360.0, 10.0))
    w, a = -30.0 + 5 * np.sin(th), 80.0 * np.cos(th)
    qs = quasi_static(mech, th, w, a, beam_column=True)
    unit = mech.motion(th, 1.0, 0.0)
    power = 0.0
    for link in mech.links():
        m, J = link.node_masses()
        lm = qs.motion.link(link.name)
        acc = lm.point(link.stations)[2]
        v = unit.link(link.name).point(link.stations)[1]
        power = power + np.sum(-m[:, None] * acc * v, axis=(-1, -2)) - np.sum(J * lm.alpha[:, None] * unit.link(link.name).omega[:, None], -1)
    np.testing.assert_allclose(qs.drive_torque, -power, rtol=2e-3, atol=2e-3 * np.max(np.abs(power)))


@pytest.mark.xfail(strict=True, reason=(
    "Shin Table 8.11/8.12 (follower midpoint, quasi-static, 400 rpm): max distortion 0.3443 in, S_alt 6900 psi, "
    "S_mean -2752 psi. The bench with Shin's mesh, 9 deg positions and beam-column iteration gives 0.173 in, "
    "3218 psi, -1653 psi (converged: 0.183 in, 3287 psi, -1718 psi; linear: 0.12 in, 2598 psi, -668 psi, "
    "matching the closed form (3/8) rho alpha L^3/h of docs/validation.md). Shin's values sit about 2x higher "
    "for inputs the dissertation does not print; nothing is tuned."))
def test_alexander_lawrence_quasi_static_vs_shin_tables_8_11_and_8_12():
    mech = alexander_lawrence(4)
    th = np.radians(np.arange(0.0, 360.0, 9.0))
    qs = quasi_static(mech, th, -41.87, beam_column=True, gauges=[ROCKER_MID])
    b, a = qs.gauges["rocker_mid"]
    stress = (a + b) * mech.rocker.material.E_Pa / PSI
    sf, mean, alt = soderberg(stress, 90e3, 45e3)
    dist = qs.solution.distortion("rocker")[:, 2] / INCH
    assert dist.max() == pytest.approx(0.3443, rel=0.10)
    assert alt == pytest.approx(6900, rel=0.10)
    assert mean == pytest.approx(-2752, rel=0.10)


@pytest.mark.xfail(strict=True, reason=(
    "Shin Tables 8.13/8.14 (Houbolt, 9 deg step, 3 cycles from rest, no damping): follower-midpoint distortion "
    "0.4845 in and S_alt 12760 psi. The bench with the same settings gives 0.191 in and 4070 psi; the "
    "converged answer (16 segments, generalized-alpha, 1 deg, 3 % damping, steady) is 0.213 in and 4190 psi "
    "(scenarios/alexander_lawrence_shin.py). Same input gap as the quasi-static case."))
def test_alexander_lawrence_time_domain_vs_shin_tables_8_13_and_8_14():
    mech = alexander_lawrence(4)
    crank = CrankMotion.constant_speed(-41.87, step_deg=9.0, revolutions=3)
    r = time_domain(mech, crank, integrator="houbolt", gauges=[ROCKER_MID], beam_column=True)
    last = slice(len(r.t) - 40, len(r.t))
    b, a = r.gauges["rocker_mid"]
    _, mean, alt = soderberg((a + b)[last] * mech.rocker.material.E_Pa / PSI, 90e3, 45e3)
    dist = np.hypot(*r.displacements["rocker"][last, 2, :2].T).max() / INCH
    assert dist == pytest.approx(0.4845, rel=0.15)
    assert alt == pytest.approx(12760, rel=0.15)


def _tip_mass_cantilever(F=3.0, m=0.2):
    """Massless steel cantilever with a tip mass: one transverse mode, w(t) = F/k (1 - cos w t)."""
    L = 0.25
    sec = Section.rectangle(0.02, 0.003)
    link = Link("beam", L, sec, Material("steel", 2.0e11, 0.0), 4, (PointMass(L, m, label="tip"),))
    loads = np.zeros((5, 3))
    loads[-1, 1] = F
    mech = StaticMechanism(((link, "A", "B", "rigid", "pin"),), (Joint("A", "clamped"), Joint("B")),
                           {"A": (0.0, 0.0), "B": (L, 0.0)}, {"beam": loads})
    k = 3 * 2.0e11 * sec.inertia_m4 / L**3
    return mech, F / k, np.sqrt(k / m)


@pytest.mark.parametrize("integrator", ["newmark", "houbolt", "generalized_alpha"])
def test_integrators_converge_at_second_order_on_an_exact_solution(integrator):
    """w(t) = w_s (1 - cos w t), started on the exact trajectory (the two past displacements too,
    which Houbolt needs: with a load step from rest it is only first order)."""
    mech, static, omega = _tip_mass_cantilever()
    td = TimeDomain(mech, integrator=integrator, beam_column=False)
    qs = quasi_static(mech, np.zeros(1), 0.0, beam_column=False)
    shape = td.stack({k: r.state[0, :, 0, :3] for k, r in qs.solution.members.items()})   # static field
    T = 2 * np.pi / omega
    errors = []
    for per_period in (40, 80, 160):
        dt = T / per_period
        t = np.arange(0, 2 * per_period + 1) * dt
        z = np.zeros_like(t)

        def field(tk):
            return (1 - np.cos(omega * tk)) * shape

        start = {"d": field(0.0), "v": 0.0 * shape, "a": omega**2 * shape, "previous": (field(-dt), field(-2 * dt))}
        r = td.run(CrankMotion(t, z, z, z), initial=start)
        w = r.displacements["beam"][:, -1, 1]
        errors.append(np.max(np.abs(w - static * (1 - np.cos(omega * t)))) / static)
    order = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((order > 1.8) & (order < 2.3)), (errors, order)
    assert errors[-1] < 2e-2


@pytest.mark.parametrize("integrator", ["generalized_alpha", "houbolt"])
def test_time_domain_reaches_a_steady_state_and_converges_in_time_step(integrator):
    mech = alexander_lawrence(6, damping=0.03)
    pp = []
    for step in (2.0, 1.0, 0.5):
        crank = CrankMotion.constant_speed(W400, step_deg=step, revolutions=40)
        r = time_domain(mech, crank, integrator=integrator, gauges=[COUPLER_MID, ROCKER_MID],
                        start="quasi_static", steady_tol=1e-3)
        assert r.steady and r.cycle_change < 1e-3
        N = r.info["steps_per_revolution"]
        pp.append([np.ptp(r.gauges[g][0][-N:]) for g in ("coupler_mid", "rocker_mid")])
    d = np.abs(np.diff(np.array(pp), axis=0))
    assert np.all(d[1] < 0.6 * d[0] + 1e-7), pp   # the change shrinks as the step is halved


def test_generalized_alpha_stays_bounded_where_newmark_average_acceleration_diverges():
    """Measured: the time-varying instantaneous structure pumps Newmark's undamped stiff modes."""
    mech = alexander_lawrence(8, damping=0.01)
    crank = CrankMotion.constant_speed(W400, step_deg=2.0, revolutions=12)
    pp = {}
    for integ in ("generalized_alpha", "newmark"):
        r = time_domain(mech, crank, integrator=integ, gauges=[COUPLER_MID], beam_column=False)
        N = r.info["steps_per_revolution"]
        pp[integ] = np.ptp(r.gauges["coupler_mid"][0][-N:])
    assert pp["generalized_alpha"] < 3e-3
    assert pp["newmark"] > 100 * pp["generalized_alpha"]


def test_crank_history_with_variable_speed_returns_drive_torque_per_step():
    """Stiff links: the time-domain drive torque follows the rigid inverse dynamics of the history.
    The links 1000x stiffer, their first mode moves from about 47 Hz to 47 sqrt(1000) Hz, where the
    3 % modal damping is declared (the short crank's own mode, 20x higher, then has 60 %)."""
    mech = alexander_lawrence(6, damping=0.03, damping_Hz=47.0 * math.sqrt(1000.0), E_factor=1000.0)
    n = 721
    t = np.arange(n) * 2e-4
    w = -20.0 - 40.0 * t / t[-1]                       # spin-up
    a = np.full(n, -40.0 / t[-1])
    th = -20.0 * t - 20.0 * t**2 / t[-1]
    r = time_domain(mech, CrankMotion(t, th, w, a), integrator="generalized_alpha", start="quasi_static")
    assert r.drive_torque.shape == (n,) and np.all(np.isfinite(r.drive_torque))
    rigid = quasi_static(mech, th, w, a, beam_column=False).drive_torque
    np.testing.assert_allclose(r.drive_torque, rigid, atol=0.02 * np.max(np.abs(rigid)))


def test_coupling_terms_change_the_response_and_are_off_by_default():
    mech = alexander_lawrence(6, damping=0.03)
    crank = CrankMotion.constant_speed(W400, step_deg=2.0, revolutions=6)
    base = time_domain(mech, crank, gauges=[COUPLER_MID], integrator="generalized_alpha")
    same = time_domain(mech, crank, gauges=[COUPLER_MID], integrator="generalized_alpha", coupling=Coupling())
    full = time_domain(mech, crank, gauges=[COUPLER_MID], integrator="generalized_alpha", coupling=Coupling.all())
    np.testing.assert_array_equal(base.gauges["coupler_mid"][0], same.gauges["coupler_mid"][0])
    diff = np.max(np.abs(full.gauges["coupler_mid"][0] - base.gauges["coupler_mid"][0]))
    assert diff > 0.01 * np.ptp(base.gauges["coupler_mid"][0])


def test_standard_linear_solid_creep_matches_closed_form():
    """Massless SLS cantilever under a tip load from t = 0: w(t) = F L^3 / (3 I) J(t)."""
    sls = StandardLinearSolid(2.0e9, 1.0e9, 0.5)
    sec = Section.rectangle(0.02, 0.005)
    L, F = 0.3, 2.0
    link = Link("beam", L, sec, Material("sls", 2.0e9, 0.0), 4, viscoelastic=sls)
    loads = np.zeros((5, 3))
    loads[-1, 1] = F
    mech = StaticMechanism(((link, "A", "B", "rigid", "pin"),), (Joint("A", "clamped"), Joint("B")),
                           {"A": (0.0, 0.0), "B": (L, 0.0)}, {"beam": loads})
    t = np.arange(0, 3.0 + 1e-12, 0.05)
    z = np.zeros_like(t)
    r = TimeDomain(mech, integrator="generalized_alpha", beam_column=False).run(CrankMotion(t, z, z, z),
                                                                               start="quasi_static")
    exact = F * L**3 / (3 * sec.inertia_m4) * sls.creep_compliance(t)
    np.testing.assert_allclose(r.displacements["beam"][:, -1, 1], exact, rtol=1e-2)
    assert exact[-1] / exact[0] > 1.9          # the test really spans the creep


def test_bad_dynamic_input_is_refused():
    mech = alexander_lawrence(6)
    with pytest.raises(InputError, match="damping stiffness_s"):
        Damping(stiffness_s=-1e-4)
    with pytest.raises(InputError, match="damping ratio"):
        Damping.modal(-0.01, 50.0)
    with pytest.raises(InputError, match="integrator must be one of"):
        TimeDomain(mech, integrator="euler")
    with pytest.raises(InputError, match="step_s"):
        CrankMotion.constant_speed(W400, step_s=-1e-3)
    # A toggle: coupler and rocker collinear (crank 1, coupler 2, rocker 1.5, ground 3).
    sec, mat = Section.rectangle(0.02, 0.004), Material("steel", 2e11, 7800.0)
    from tmm_core import FourBarMechanism
    toggle = FourBarMechanism(Link("crank", 1.0, sec, mat, 2), Link("coupler", 2.0, sec, mat, 2),
                              Link("rocker", 1.5, sec, mat, 2), 3.0)
    th_toggle = np.arccos((1.0 + 9.0 - 3.5**2) / 6.0)
    with pytest.raises(AssemblyError, match="toggle"):
        quasi_static(toggle, np.array([0.3, th_toggle]), 10.0)


def test_crank_speed_at_a_natural_frequency_is_refused():
    """With the centrifugal (spin-softening) term the instantaneous structure's stiffness
    K - w_link^2 M loses positive definiteness once the links' angular speeds pass its first
    natural frequency: the quasi-static analysis refuses such a speed and names it. (Each link
    softens with its own speed; coupler and rocker turn slower than the crank.)"""
    from tmm_core.frequencies import fourbar_frequencies
    mech = alexander_lawrence(8)
    th = np.array([0.3])
    w1 = 2 * np.pi * fourbar_frequencies(mech, th, 1, 500.0)[0, 0]
    ok = quasi_static(mech, th, 0.5 * w1, coupling=Coupling(centrifugal=True), beam_column=False)
    assert np.all(np.isfinite(ok.drive_torque))
    with pytest.raises(SingularStructureError, match=r"crank speed .* natural frequency"):
        quasi_static(mech, th, 4.0 * w1, coupling=Coupling(centrifugal=True), beam_column=False)


def test_wang_composite_with_viscoelastic_links_reaches_a_steady_state():
    from cosim.units import RPM
    from scenarios.rigs import wang_composite
    mech = wang_composite(4)
    g = Gauge("coupler_mid", "coupler", 4.5 * INCH)
    r = time_domain(mech, CrankMotion.constant_speed(280 * RPM, step_deg=2.0, revolutions=30),
                    integrator="generalized_alpha", gauges=[g], start="quasi_static", steady_tol=1e-3,
                    axial_force="quasi_static")     # the second-order step has no viscoelastic axial history
    assert r.steady
    w = r.displacements["coupler"][-180:, 3, 1]          # span mid-node (between the housings)
    assert 0.05e-3 < np.ptp(w) < 1.0e-3                  # order of a re-run of Wang's program made when reading the thesis (tenths of a mm)


def test_incremental_march_reproduces_the_batched_run():
    mech = alexander_lawrence(4, damping=0.03)
    crank = CrankMotion.constant_speed(W400, step_deg=3.0, revolutions=0.5)
    td = TimeDomain(mech, integrator="generalized_alpha", gauges=[COUPLER_MID])
    batched = td.run(crank, start="quasi_static")
    march = td.begin(crank.dt, crank.angle[0], crank.speed[0], start="quasi_static")
    torque = [march.out[0]]
    strain = [march.out[1]]
    for k in range(1, len(crank.t)):
        _, out = march.advance(crank.angle[k], crank.speed[k], crank.acceleration[k])
        torque.append(out[0])
        strain.append(out[1])
    np.testing.assert_allclose(torque, batched.drive_torque, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(strain, batched.gauges["coupler_mid"][0], rtol=1e-9, atol=1e-15)


def test_load_maps_in_chunks_and_riccati_sweeps_give_the_same_march(monkeypatch):
    """The time domain answers each step either from dense load-to-response maps (built in chunks
    of configurations) or from a Riccati load sweep; the three ways must agree to round-off."""
    import tmm_core.step_data as maps_module
    mech = alexander_lawrence(3, damping=0.02)
    crank = CrankMotion.constant_speed(400 * RPM, step_deg=4.0, revolutions=1.5)
    gauges = [ROCKER_MID, COUPLER_MID]

    def run(max_bytes=400e6):
        td = TimeDomain(mech, integrator="generalized_alpha", gauges=gauges, max_map_bytes=max_bytes)
        res = td.run(crank, start="quasi_static", record_displacements=False)
        return np.array([res.gauges[g.name][0] for g in gauges])
    whole = run()
    monkeypatch.setattr(maps_module, "MAP_CHUNK_BYTES", 1.0)      # one configuration per chunk (both paths)
    chunked = run()
    swept = run(max_bytes=0.0)
    scale = np.max(np.abs(whole))
    assert np.max(np.abs(chunked - whole)) <= 1e-9 * scale
    assert np.max(np.abs(swept - whole)) <= 1e-9 * scale
