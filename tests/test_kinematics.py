"""Closed-form four-bar and slider-crank kinematics."""
import numpy as np
import pytest

from cosim.units import INCH
from tmm_core import AssemblyError, FourBarGeometry, SliderCrankGeometry, fourbar_motion, slider_crank_motion

AL = FourBarGeometry(4 * INCH, 11 * INCH, 10.5 * INCH, 10 * INCH)


def test_shin_table_8_9_and_8_10_initial_position():
    """Shin Tables 8.9/8.10: crank angle 0, omega = -41.87 rad/s."""
    m = fourbar_motion(AL, 0.0, -41.87, 0.0)
    np.testing.assert_allclose(m.C / INCH, [7.896, 10.29], rtol=1e-3)
    np.testing.assert_allclose(m.B / INCH, [4.000, 0.0], atol=1e-12)
    aC = m.coupler.point(11 * INCH)[2] / INCH
    np.testing.assert_allclose(aC, [-5949, -9568], rtol=1e-3)
    aB = m.crank.point(4 * INCH)[2] / INCH
    assert aB[0] == pytest.approx(-7012, rel=1e-3)
    assert m.coupler.alpha == pytest.approx(-398.4, rel=1e-3)
    assert m.rocker.alpha == pytest.approx(737.7, rel=1e-3)
    # The rocker end computed from D agrees with the coupler end computed from B.
    np.testing.assert_allclose(m.rocker.point(10.5 * INCH)[2], m.coupler.point(11 * INCH)[2], rtol=1e-12)


def _fd_check(motion_fn, geom, links, theta0, w, a, h=1e-6):
    """Velocity and acceleration against central differences along theta(t) = th0 + w t + a t^2/2."""
    def at(t):
        return motion_fn(geom, theta0 + w * t + 0.5 * a * t**2, w + a * t, a)
    m0, mp, mm = at(0.0), at(h), at(-h)
    for name in links:
        lk0, lkp, lkm = m0.link(name), mp.link(name), mm.link(name)
        for x in (0.0, 0.37 * INCH, 2.5 * INCH):
            p0, v0, a0 = lk0.point(x, 0.3 * INCH)
            pp, _, _ = lkp.point(x, 0.3 * INCH)
            pm, _, _ = lkm.point(x, 0.3 * INCH)
            scale_v = np.abs(v0).max() + abs(w) * INCH
            scale_a = np.abs(a0).max() + (w**2 + abs(a)) * INCH
            np.testing.assert_allclose((pp - pm) / (2 * h), v0, atol=1e-6 * scale_v)
            np.testing.assert_allclose((pp - 2 * p0 + pm) / h**2, a0, atol=1e-4 * scale_a)
        ang = np.unwrap([lkm.angle, lk0.angle, lkp.angle])
        assert (ang[2] - ang[0]) / (2 * h) == pytest.approx(lk0.omega, abs=1e-6 * (abs(lk0.omega) + 1))
        assert (ang[2] - 2 * ang[1] + ang[0]) / h**2 == pytest.approx(lk0.alpha, abs=1e-3 * (abs(lk0.alpha) + w**2))


@pytest.mark.parametrize("branch", [1, -1])
@pytest.mark.parametrize("theta0", [0.3, 1.9, 3.5, 5.6])
def test_fourbar_velocity_and_acceleration_match_finite_differences(branch, theta0):
    geom = FourBarGeometry(4 * INCH, 11 * INCH, 10.5 * INCH, 10 * INCH, pivot=(0.1, -0.2), ground_angle=0.4,
                           branch=branch)
    _fd_check(fourbar_motion, geom, ("crank", "coupler", "rocker"), theta0, -41.87, 350.0)


@pytest.mark.parametrize("branch", [1, -1])
@pytest.mark.parametrize("theta0", [0.2, 2.2, 4.0])
def test_slider_crank_velocity_and_acceleration_match_finite_differences(branch, theta0):
    geom = SliderCrankGeometry(3 * INCH, 10 * INCH, offset=1 * INCH, pivot=(0.05, 0.0), ground_angle=-0.3,
                               branch=branch)
    _fd_check(slider_crank_motion, geom, ("crank", "coupler"), theta0, 60.0, -900.0)


def test_centred_slider_crank_position_closed_form():
    a, b = 0.05, 0.2
    th = np.linspace(0, 2 * np.pi, 37)
    m = slider_crank_motion(SliderCrankGeometry(a, b), th)
    np.testing.assert_allclose(m.slider_position, a * np.cos(th) + np.sqrt(b**2 - (a * np.sin(th))**2), rtol=1e-14)


def test_loop_closes_for_every_crank_angle_and_both_branches():
    th = np.linspace(0, 2 * np.pi, 361)
    for branch in (1, -1):
        g = FourBarGeometry(AL.crank, AL.coupler, AL.rocker, AL.ground, branch=branch)
        m = fourbar_motion(g, th, 3.0, 1.0)
        np.testing.assert_allclose(np.hypot(*(m.C - m.B).T), g.coupler, rtol=1e-13)
        np.testing.assert_allclose(np.hypot(*(m.C - m.D).T), g.rocker, rtol=1e-13)
        d, c = m.D - m.B, m.C - m.B
        side = np.sign(d[:, 0] * c[:, 1] - d[:, 1] * c[:, 0])
        assert np.all(side == branch)


def test_linkage_that_cannot_assemble_is_refused_with_the_geometry_named():
    # Non-Grashof: the crank cannot turn past about 100 deg.
    g = FourBarGeometry(8 * INCH, 5 * INCH, 6 * INCH, 10 * INCH)
    with pytest.raises(AssemblyError, match=r"cannot assemble at crank angle 180 deg.*coupler \+ rocker"):
        fourbar_motion(g, np.radians([0.0, 180.0]))
    with pytest.raises(AssemblyError, match="slider-crank.*cannot assemble"):
        slider_crank_motion(SliderCrankGeometry(0.1, 0.05), np.pi / 2)


def test_toggle_is_refused():
    """Crank 1, coupler 2, rocker 1.5, ground 3: at the crank angle where |BD| = coupler + rocker,
    coupler and rocker are collinear and the rocker speed is undefined."""
    g = FourBarGeometry(1.0, 2.0, 1.5, 3.0)
    th_toggle = np.arccos((1.0 + 9.0 - 3.5**2) / (2 * 1.0 * 3.0))
    with pytest.raises(AssemblyError, match="toggle"):
        fourbar_motion(g, th_toggle)
    with pytest.raises(AssemblyError, match="toggle"):
        slider_crank_motion(SliderCrankGeometry(1.0, 1.0, offset=0.0), np.pi / 2)


def test_rigid_body_and_reflected_inertia():
    """A uniform rod with a point mass: mass, centre and central inertia in closed form; the
    crank's reflected inertia J(q) of a four-bar and its derivative against finite differences
    of the closed-form positions (kinetic energy at unit crank speed)."""
    from tmm_core import FourBarMechanism, Link, Material, PointMass, Section
    mat = Material("al", 70e9, 2700.0)
    sec = Section.rectangle(0.02, 0.005)
    L, m_p = 0.3, 0.05
    rod = Link("coupler", L, sec, mat, 6, (PointMass(L, m_p, 1e-6, "tip"),))
    m_rod = 2700.0 * sec.area_m2 * L
    m, xc, J = rod.rigid_body()
    assert m == pytest.approx(m_rod + m_p)
    assert xc == pytest.approx((m_rod * L / 2 + m_p * L) / m)
    assert J == pytest.approx(m_rod * L**2 / 12 + m_rod * (L / 2 - xc) ** 2 + m_p * (L - xc) ** 2 + 1e-6)
    mech = FourBarMechanism(Link("crank", 0.1, sec, mat, 4), rod, Link("rocker", 0.28, sec, mat, 4), 0.25)
    q = np.linspace(0.1, 6.0, 7)
    Jq, dJ, _ = mech.crank_inertia(q)
    h = 1e-6
    ke = np.zeros_like(q)
    for link in mech.links():
        mm, x, Jc = link.rigid_body()
        p1, p0 = mech.motion(q + h).link(link.name), mech.motion(q - h).link(link.name)
        v = (p1.point(x)[0] - p0.point(x)[0]) / (2 * h)
        w = (p1.angle - p0.angle) / (2 * h)
        ke += mm * np.sum(v**2, -1) + Jc * w**2
    np.testing.assert_allclose(Jq, ke, rtol=1e-7)
    np.testing.assert_allclose(dJ, (mech.crank_inertia(q + 1e-5)[0] - mech.crank_inertia(q - 1e-5)[0]) / 2e-5,
                               rtol=1e-5, atol=1e-9)
