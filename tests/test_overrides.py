"""Scenario variants through Scenario.with_overrides (one typed API over key paths, validated by
the loader), and the refusal of a bare unit with no number."""
import pytest

from cosim.scenario import ScenarioError, load


def test_overrides_reach_every_kind_of_key():
    base = load("crank_rocker_373rpm")
    v = base.with_overrides({"drive.speed": "300 rpm", "links.coupler.damping.ratio": "3 %",
                             "links.coupler.point_masses[0].weight": "0.06564 lbf", "solver.tmm.segments": 16})
    assert v.drive.speed_rad_s == pytest.approx(300 * 3.141592653589793 / 30)
    assert v.tmm.segments == 16 and v.mechanism.coupler.n_segments == 16
    assert v.mechanism.coupler.point_masses[0].mass_kg == pytest.approx(0.06564 * 4.4482216152605 / 9.80665)
    assert v.mechanism.coupler.damping.stiffness_s == pytest.approx(2 * 0.03 / (2 * 3.141592653589793 * 79))
    # The base is unchanged, and a value with provenance keeps it.
    assert base.tmm.segments == 8
    assert any(a.key == "links.coupler.point_masses[0]" for a in v.assumptions)


@pytest.mark.parametrize("key, value, named", [
    ("links.nolink.length", "3 in", "links.nolink"),
    ("links.coupler.point_masses[5].weight", "1 lbf", "point_masses[5]"),
    ("drive.speed", "3 kg", "drive.speed"),
    ("links.coupler.damping.ratio", "-1 %", "links.coupler.damping.ratio"),
])
def test_bad_overrides_are_refused_naming_the_key(key, value, named):
    with pytest.raises(ScenarioError, match=named.replace("[", r"\[").replace("]", r"\]")):
        load("crank_rocker_373rpm").with_overrides({key: value})


@pytest.mark.parametrize("key, value", [("drive.speed", "rpm"), ("materials.aluminium.E", "psi"),
                                        ("solver.tmm.step", "abc"), ("solver.tmm.step", " ")])
def test_a_bare_unit_or_text_without_a_number_is_refused(key, value):
    with pytest.raises(ScenarioError, match=rf"key '{key}'.*(no number|not a quantity)"):
        load("crank_rocker_373rpm").with_overrides({key: value})


def test_none_removes_a_key_and_a_solver_table_can_be_added():
    base = load("crank_rocker_373rpm")
    assert base.motor is not None
    bare = base.with_overrides({"motor": None, "drive.mode": "prescribed"})
    assert bare.motor is None
    v = base.with_overrides({"solver.exudyn.elements": 6})
    assert v.raw["solver"]["exudyn"]["elements"] == 6


def test_load_returns_a_loaded_scenario_of_any_kind_as_it_is():
    for name in ("crank_rocker_373rpm", "shin_multiloop_small"):
        variant = load(name).with_overrides({"scenario.description": "variant"})
        assert load(variant) is variant


@pytest.mark.parametrize("key", ["drive.speed", "links.coupler.point_masses[0].weight", "solver.exudyn.elements",
                                 "links.nolink.length", "links.coupler.point_masses[5].weight", "drive.speed.x.y",
                                 "links.coupler.damping.ratio.x"])
def test_checking_a_key_path_leaves_the_tree_alone_and_agrees_with_setting_it(key):
    """set_key(write=False) (the loader's check of [uncertainty] keys) refuses exactly what setting
    the key refuses, and changes nothing."""
    import copy
    from cosim.overrides import OverrideError, set_key
    raw = load("crank_rocker_373rpm").raw
    before = copy.deepcopy(raw)
    outcomes = []
    for write in (False, True):
        try:
            set_key(copy.deepcopy(raw) if write else raw, key, 0, write=write)
            outcomes.append(None)
        except OverrideError as exc:
            outcomes.append(str(exc))
    assert outcomes[0] == outcomes[1]
    assert raw == before


def test_a_value_read_twice_gives_the_same_number_and_the_same_refusal():
    """Unit parsing is kept per text (cosim.scenario_reader): a second read converts the same way
    and refuses the same way, naming the key."""
    a = load("crank_rocker_373rpm").with_overrides({"drive.speed": "301 rpm"})
    b = load("crank_rocker_373rpm").with_overrides({"drive.speed": "301 rpm"})
    assert a.drive.speed_rad_s == b.drive.speed_rad_s == pytest.approx(301 * 3.141592653589793 / 30)
    for _ in range(2):
        with pytest.raises(ScenarioError, match="drive.speed.*wrong dimension"):
            load("crank_rocker_373rpm").with_overrides({"drive.speed": "3 kg"})
