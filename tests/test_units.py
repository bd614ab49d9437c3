"""The unit conventions of angles and rates (cosim.units.magnitude_in): every angular rate of
the scenario format reads a frequency in hertz as revolutions per unit time, and an angle unit
where none belongs is refused. Expected values are closed forms (1 rev = 2 pi rad)."""
import math

import pytest

from cosim.records import RecordError, quantity_value
from cosim.scenario import ScenarioError, load, resolved
from cosim.units import AngleUnitError, to_si


@pytest.mark.parametrize("text, unit, expected", [
    ("10 Hz", "rad/s", 20 * math.pi),            # revolutions per second, not 10 rad/s
    ("10 Hz", "rpm", 600.0),
    ("0.5 kHz", "rpm", 30000.0),
    ("600 rpm", "Hz", 10.0),                     # a natural frequency written as a speed
    ("10 rev/s", "rad/s", 20 * math.pi),
    ("62.5 rad/s", "rad/s", 62.5),
    ("1 V*s", "V*s/rad", 1.0),                   # per radian, radian = 1 as in SI
    ("0.6 1/s", "1/s", 0.6),
    ("90 deg", "rad", math.pi / 2),
])
def test_angles_and_rates_convert_by_their_conventions(text, unit, expected):
    assert to_si(text, unit) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("text, unit", [
    ("10 1/s", "rad/s"), ("95 rpm/rad", "rad/s"), ("7 in/rad", "m"), ("1 deg deg", "rad"),
    ("373 rpm", "1/s"), ("1 deg", "m/m"),
])
def test_misplaced_angles_are_refused(text, unit):
    with pytest.raises(AngleUnitError, match="angle"):
        to_si(text, unit)


def test_a_speed_in_hertz_runs_at_revolutions_per_second():
    sc = load("crank_rocker_373rpm").with_overrides({"drive.speed": "10 Hz"})
    assert sc.drive.speed_rpm == pytest.approx(600.0, rel=1e-12)
    assert sc.revolution_period_s == pytest.approx(0.1, rel=1e-12)
    assert resolved(sc)["resolved"]["drive"]["speed_rpm"] == pytest.approx(600.0, rel=1e-12)


def test_a_rate_without_angle_says_how_to_write_a_speed():
    with pytest.raises(ScenarioError, match=r"key 'drive.speed' = '10 1/s'.*'600 rpm'.*Hz"):
        load("crank_rocker_373rpm").with_overrides({"drive.speed": "10 1/s"})


def test_a_record_speed_in_hertz_is_revolutions_per_second(tmp_path):
    assert quantity_value("6.2 Hz", tmp_path / "r.toml", "record.speed", "rpm") == pytest.approx(372.0)
    with pytest.raises(RecordError, match="record.speed"):
        quantity_value("373 rpm/rad", tmp_path / "r.toml", "record.speed", "rpm")
