"""Rigid four-bar synthesis, limit positions (tmm_core.synthesis) and `cosim synthesize` (cosim.commands.synthesize,
cosim.synthesis).

Expected values are the publication's, never this code's: the FE thesis, Ch. III (Case Studies I
and II, Eqs. 3.4-3.17) prescribes angles of its Ch. IX rig, crank 7, coupler 10, rocker 12, ground
11 in; docs/validation.md, "The FE thesis's synthesis example", lists the inputs and the printed digits of the other angles (phi2 95.216,
mu2 40.119, theta1 44.665, phi4 14.141, mu4 63.612 deg), and the rig's limit positions (44.66 and
282.247 deg, swing 81.075 deg, time ratio 1.941) and its minimum transmission angle (18.195 deg at
crank angle 0 from the lengths; the thesis prints 17.76 deg).
"""
import json
import math

import numpy as np
import pytest

from cosim.cli import main
from cosim.scenario import load
from cosim.units import INCH
from tmm_core import FourBarGeometry, InputError, fourbar_motion
from tmm_core.fourbar_limits import grashof_class, limit_positions
from tmm_core.synthesis import synthesize_case_one, synthesize_case_two

DEG = math.radians
FE_RIG_IN = (7.0, 10.0, 12.0, 11.0)                 # crank, coupler, rocker, ground [in], thesis Ch. IX
CASE_ONE = ["--case", "I", "--ground", "11 in", "--oscillation", "81.0748 deg", "--rocker-limit", "14.1411 deg",
            "--min-transmission", "18.1949 deg"]


def _printed(value_rad, printed_deg):
    """Agreement to the printed digits: within half a unit of the last printed decimal."""
    decimals = len(str(printed_deg).split(".")[1])
    return abs(math.degrees(value_rad) - printed_deg) <= 0.5 * 10.0 ** -decimals


def _lengths_in(s):
    return np.array([s.crank, s.coupler, s.rocker]) / INCH


def test_case_one_gives_the_fe_rig():
    # Thesis Ch. III Case Study I with the rig's angles (docs/validation.md, "The FE thesis's synthesis example").
    s = synthesize_case_one(11 * INCH, DEG(81.0748), DEG(14.1411), DEG(18.1949))
    np.testing.assert_allclose(_lengths_in(s), FE_RIG_IN[:3], rtol=1e-3)
    assert _printed(s.phi2, 95.216) and _printed(s.mu2, 40.119) and _printed(s.theta1, 44.665)
    assert s.residual < 1e-12 and s.limits["grashof"] == "crank-rocker"


def test_case_two_gives_the_fe_rig():
    # Thesis Ch. III Case Study II with the rig's crank limit positions (docs/validation.md, "The FE thesis's synthesis example").
    s = synthesize_case_two(11 * INCH, DEG(81.0748), DEG(44.6649), DEG(102.2467))
    np.testing.assert_allclose(_lengths_in(s), FE_RIG_IN[:3], rtol=1e-3)
    assert _printed(s.phi4, 14.141) and _printed(s.mu4, 63.612)
    assert s.residual < 1e-12 and s.limits["grashof"] == "crank-rocker"


def test_limit_positions_of_the_fe_rig_match_the_collinear_triangles_and_sampling():
    a, b, c, d = (x * INCH for x in FE_RIG_IN)
    lim = limit_positions(FourBarGeometry(a, b, c, d))
    # Independent: law of cosines at the two collinear configurations (crank and coupler in line).
    extended = math.acos((d * d + (a + b) ** 2 - c * c) / (2 * d * (a + b)))
    folded = math.pi + math.acos((d * d + (b - a) ** 2 - c * c) / (2 * d * (b - a)))
    rocker_ext = math.pi - math.acos((c * c + d * d - (a + b) ** 2) / (2 * c * d))
    rocker_fold = math.pi - math.acos((c * c + d * d - (b - a) ** 2) / (2 * c * d))
    assert lim["crank_angle_extended_rad"] == pytest.approx(extended, abs=1e-9)
    assert lim["crank_angle_folded_rad"] == pytest.approx(folded, abs=1e-9)
    assert lim["rocker_angle_extended_rad"] == pytest.approx(rocker_ext, abs=1e-9)
    assert lim["rocker_angle_folded_rad"] == pytest.approx(rocker_fold, abs=1e-9)
    assert math.degrees(extended) == pytest.approx(44.665, abs=5e-4)       # docs/validation.md, synthesis example
    assert math.degrees(folded) == pytest.approx(282.247, abs=5e-4)
    assert math.degrees(lim["oscillation_rad"]) == pytest.approx(81.075, abs=5e-4)
    assert lim["time_ratio"] == pytest.approx(1.941, abs=5e-4)
    # Independent: brute-force sampling of the revolution, transmission angle from the joint positions.
    m = fourbar_motion(FourBarGeometry(a, b, c, d), np.linspace(0, 2 * np.pi, 36001))
    cb, cd = m.B - m.C, m.D - m.C
    mu = np.arccos(np.sum(cb * cd, -1) / np.hypot(*cb.T) / np.hypot(*cd.T))
    assert lim["transmission_min_rad"] == pytest.approx(mu.min(), abs=1e-9)
    assert lim["transmission_max_rad"] == pytest.approx(mu.max(), abs=1e-9)
    assert math.degrees(lim["transmission_min_rad"]) == pytest.approx(18.2, abs=0.01)   # thesis prints 17.76
    rocker = np.unwrap(m.rocker.angle)
    assert lim["oscillation_rad"] == pytest.approx(rocker.max() - rocker.min(), abs=1e-7)


@pytest.mark.parametrize("call, named", [
    (lambda: synthesize_case_one(0.28, DEG(81), DEG(14), DEG(100)), "min_transmission = 100 deg"),
    (lambda: synthesize_case_one(0.28, DEG(190), DEG(14), DEG(18)), "oscillation = 190 deg"),
    (lambda: synthesize_case_one(0.28, DEG(81), DEG(120), DEG(18)), "rocker_limit + oscillation"),
    (lambda: synthesize_case_one(-0.28, DEG(81), DEG(14), DEG(18)), "ground must be positive"),
    (lambda: synthesize_case_two(0.28, DEG(81.0748), DEG(102.2467), DEG(44.6649)), "theta1 = 102.247 deg"),
    (lambda: limit_positions(FourBarGeometry(0.07, 0.10, 0.12, 0.20)), "is a non-Grashof triple-rocker"),
])
def test_infeasible_inputs_are_refused_with_the_input_named(call, named):
    with pytest.raises(InputError, match=named.replace("+", r"\+")):
        call()


def test_grashof_classes():
    assert grashof_class(7, 10, 12, 11) == "crank-rocker"
    assert grashof_class(7, 10, 12, 4) == "double-crank"
    assert grashof_class(7, 4, 12, 11) == "double-rocker"
    assert grashof_class(7, 10, 12, 20) == "non-Grashof triple-rocker"
    assert grashof_class(2, 4, 3, 3) == "crank-rocker (change point)"


def test_cli_json_is_one_object_in_the_unit_of_the_ground(capsys):
    assert main(["synthesize"] + CASE_ONE + ["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["unit"] == "in" and data["grashof"] == "crank-rocker"
    np.testing.assert_allclose([data["crank"], data["coupler"], data["rocker"]], FE_RIG_IN[:3], rtol=1e-3)
    assert data["transmission_min_deg"] == pytest.approx(18.1949, abs=1e-3)


@pytest.mark.parametrize("change, named", [
    (("--ground", "11"), "--ground = '11': has no unit"),
    (("--oscillation", "81.0748"), "--oscillation = '81.0748': has no unit"),
    (("--min-transmission", "18 %"), "--min-transmission = '18 %': is not a finite angle"),
    (("--case", "II"), "--rocker-limit = '14.1411 deg': is not used by case II"),
])
def test_cli_bad_input_ends_with_one_error_line(capsys, change, named):
    argv = list(CASE_ONE)
    argv[argv.index(change[0]) + 1] = change[1]
    assert main(["synthesize"] + argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and named in err[0]


def test_cli_scenario_out_loads_with_the_synthesized_lengths(tmp_path, capsys):
    path = tmp_path / "fe_synthesized.toml"
    assert main(["synthesize", "--case", "II", "--ground", "11 in", "--oscillation", "81.0748 deg",
                 "--crank-limits", "44.6649 deg", "102.2467 deg", "--scenario-out", str(path)]) == 0
    assert f"scenario written to {path}" in capsys.readouterr().out
    sc = load(path)
    g = sc.mechanism.geometry
    np.testing.assert_allclose(np.array([g.crank, g.coupler, g.rocker, g.ground]) / INCH, FE_RIG_IN, rtol=1e-3)
    base = load("crank_rocker_373rpm")
    assert sc.rig is None and sc.drive == base.drive
    assert [(x.name, x.link) for x in sc.gauges] == [(x.name, x.link) for x in base.gauges]


def test_every_four_bar_run_reports_its_limit_positions_and_transmission_range():
    """The run summary's `linkage` entry (cosim.runs.linkage_summary) for the FE rig, against the
    thesis's values (docs/validation.md, synthesis example: theta1 = 44.665 deg, oscillation 81.0748 deg, mu1 = 18.1949 deg)."""
    from cosim.runs import linkage_summary
    from cosim.scenario import load
    lk = linkage_summary(load("crank_rocker_373rpm"))
    assert lk["crank_angle_extended_deg"] == pytest.approx(44.665, abs=1e-3)
    assert lk["oscillation_deg"] == pytest.approx(81.0748, abs=1e-4)
    assert lk["transmission_min_deg"] == pytest.approx(18.1949, abs=1e-4)
    assert linkage_summary(load("slider_crank_600rpm")) is None


@pytest.mark.parametrize("branch", [1, -1])
@pytest.mark.parametrize("ground_angle", [0.0, 0.7])
def test_limit_positions_are_where_the_sampled_rocker_speed_changes_sign(branch, ground_angle):
    # Independent of the closed form: the rocker's speed sampled over a revolution at 1e-4 rad.
    g = FourBarGeometry(0.05, 0.2, 0.15, 0.18, ground_angle=ground_angle, branch=branch)
    lim = limit_positions(g)
    angle = np.linspace(0, 2 * np.pi, 62832)
    w = fourbar_motion(g, angle, 1.0).rocker.omega
    reversals = angle[np.flatnonzero(np.sign(w[:-1]) != np.sign(w[1:]))]
    assert sorted([lim["crank_angle_extended_rad"], lim["crank_angle_folded_rad"]]) == \
        pytest.approx(sorted(reversals), abs=2e-4)
    m = fourbar_motion(g, np.array([lim["crank_angle_extended_rad"], lim["crank_angle_folded_rad"]]))
    assert np.hypot(*(m.C - m.A).T) == pytest.approx([0.25, 0.15], rel=1e-12)      # in line: a + b, b - a
