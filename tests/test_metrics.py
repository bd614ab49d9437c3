"""The revolution metrics on synthetic traces whose answer is known in closed form: a motor-like
crank (speed varying within the revolution, samples uniform in time so none falls on a revolution's
edge) carrying signals that repeat exactly in crank angle, or drift by a known amount."""
import math
import warnings

import numpy as np
import pytest

from cosim.metrics import SteadyWatch, speed_fluctuation
from tmm_core.revolution import last_revolution, revolution_change

OMEGA = 373 * math.pi / 30          # mean crank speed [rad/s]
PERIOD = 2 * math.pi / OMEGA        # [s]
SWING = 0.3                         # crank angle theta = OMEGA t + SWING sin(OMEGA t): speed +-30 %


def motor_like(revolutions=5.3, samples_per_revolution=997.3, angle0=0.7):
    """Times [s] and crank angles [rad] of a crank whose speed swings by 30 % each revolution,
    sampled uniformly in time (the revolution is not a whole number of samples)."""
    t = np.arange(0.0, revolutions * PERIOD, PERIOD / samples_per_revolution)
    return t, angle0 + OMEGA * t + SWING * np.sin(OMEGA * t)


def periodic_signal(theta):
    """A gauge-like signal that repeats exactly every revolution of crank angle [rad]."""
    return np.sin(theta) + 0.4 * np.sin(3 * theta + 0.2) + 0.1 * np.sin(8 * theta)


def interpolation_bound(t, theta, x):
    """Largest relative error of linear interpolation in crank angle: max|x''| dtheta^2 / 8
    over the peak-to-peak (x'' bounded term by term from periodic_signal)."""
    d2 = 1 + 0.4 * 9 + 0.1 * 64
    dtheta = OMEGA * (1 + SWING) * (t[1] - t[0])
    return d2 * dtheta ** 2 / 8 / np.ptp(x[last_revolution(theta)])


@pytest.mark.parametrize("samples_per_revolution", [997.3, 500.7, 1210.45])
def test_revolutions_that_repeat_exactly_in_angle_show_no_change(samples_per_revolution):
    t, theta = motor_like(samples_per_revolution=samples_per_revolution)
    x = periodic_signal(theta)
    change = revolution_change(theta, [x])
    # The window's edge samples compared with the previous revolution's end values (not
    # interpolated) gave 0.3-1 % here.
    assert change <= interpolation_bound(t, theta, x)


def test_a_known_drift_per_revolution_is_reported():
    t, theta = motor_like()
    drift = 0.02                          # added per revolution of crank angle
    x = periodic_signal(theta) + drift * (theta - theta[0]) / (2 * math.pi)
    expected = drift / np.ptp(x[last_revolution(theta)])
    assert revolution_change(theta, [x]) == pytest.approx(expected, abs=interpolation_bound(t, theta, x))


def test_the_comparison_holds_in_either_direction_of_rotation():
    t, theta = motor_like()
    x = periodic_signal(-theta)
    assert revolution_change(-theta, [x]) <= interpolation_bound(t, theta, x)


def test_steady_watch_calls_an_exactly_repeating_motor_run_steady():
    """Fed macro step by macro step, as the master does, with a tolerance of 0.1 %."""
    t, theta = motor_like(revolutions=6.2)
    x = periodic_signal(theta)
    watch = SteadyWatch(tolerance=1e-3)

    class Out:                            # the fields of cosim.engines.base.EngineOutput it reads
        def __init__(self, sel):
            self.t, self.crank_angle, self.drive_torque = t[sel], theta[sel], 2 * x[sel]
            self.gauges = {"g": (x[sel], 0 * x[sel])}
    for start in range(0, len(t), 37):
        watch.add("tmm", Out(slice(start, start + 37)))
    assert watch.steady("tmm")
    assert watch.change["tmm"] <= interpolation_bound(t, theta, x)


def test_speed_fluctuation_of_a_run_holding_only_its_last_revolutions_warns_nothing():
    """A run that keeps only its last revolutions (cosim.master, keep_revolutions) starts after
    revolutions it cannot time: they are left out, never divided by a zero duration."""
    t, theta = motor_like(revolutions=9.5, angle0=0.0)
    held = t > 5.2 * PERIOD
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f = speed_fluctuation(t[held], theta[held], np.gradient(theta, t)[held], start_angle=0.0, t0=0.0)
    # Revolution k ends at t = k PERIOD exactly (sin(OMEGA k PERIOD) = 0): the held samples
    # (from 5.2 periods) cover revolutions 7 to 9 whole; the 6th is cut.
    assert f["t_start"] == pytest.approx(PERIOD * np.arange(6, 9), rel=1e-6)
    assert f["t_end"] == pytest.approx(PERIOD * np.arange(7, 10), rel=1e-6)
    assert f["mean"] == pytest.approx(OMEGA, rel=1e-5)
    # (max - min) / mean of the speed OMEGA (1 + SWING cos(OMEGA t)) over a revolution.
    assert f["fluctuation"] == pytest.approx(2 * SWING, rel=1e-3)


@pytest.mark.parametrize("kind", ["grows", "decays slowly", "bounded, not periodic"])
def test_a_run_that_is_not_steady_says_what_it_sees(kind):
    """revolution_trend on signals whose behaviour is known: an amplitude growing 5 % per
    revolution, a transient whose revolution change falls to 0.7 of itself per revolution, and a
    quasi-periodic response (an incommensurate ringing) that neither grows nor settles."""
    from cosim.metrics import revolution_trend
    t, theta = motor_like(revolutions=8.3)
    rev = (theta - theta[0]) / (2 * math.pi)
    base = periodic_signal(theta)
    x = {"grows": base * 1.05 ** rev,
         "decays slowly": base + 0.3 * 0.7 ** rev * np.sin(5 * theta + 0.4),
         "bounded, not periodic": base + 0.3 * np.sin(math.sqrt(2) * theta)}[kind]
    trend = revolution_trend(theta, [x], tolerance=5e-3)
    assert trend["kind"] == kind and trend["revolutions"] == 6 and kind.split(",")[0] in trend["text"]
    if kind == "grows":
        assert trend["peak_to_peak_ratio_per_revolution"] == pytest.approx(1.05, abs=0.01)
    if kind == "decays slowly":
        assert trend["change_ratio_per_revolution"] == pytest.approx(0.7, abs=0.05)
        # At 0.7 per revolution from the last change down to 0.5 %.
        assert trend["revolutions_to_steady"] == math.ceil(math.log(5e-3 / trend["changes"][-1]) / math.log(0.7))
    assert revolution_trend(theta[theta < theta[0] + 2.5 * 2 * math.pi], [x[theta < theta[0] + 2.5 * 2 * math.pi]]) \
        is None
