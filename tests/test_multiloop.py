"""Shin's multiloop mechanism (issue 8): general structures with plates, springs, sliders and
sub-loops, against the dissertation's Tables 8.1-8.8, and the scenario
format's topology errors."""
import math

import numpy as np
import pytest

from cosim import scenario as sc
from cosim.structure_scenario import results, solve

IN, LBF = 0.0254, 4.4482216152605


@pytest.fixture(scope="module")
def small():
    s = sc.load("shin_multiloop_small")
    sol = solve(s)
    return s, sol, results(s, sol)[1]


@pytest.fixture(scope="module")
def large():
    s = sc.load("shin_multiloop_large")
    sol = solve(s)
    return s, sol, results(s, sol)[1]


def test_small_deflection_distortion_and_springs(small):
    """Max distortion 0.0787 in at node 11; spring forces 244.9 (ground) and 229.8 lb (4-11).
    Measured: 0.07889 in (+0.2 %), 244.88 and 229.81 lb."""
    s, sol, summary = small
    d11 = summary["joints"]["11"]
    assert math.hypot(d11["dX_m"], d11["dY_m"]) / IN == pytest.approx(0.0787, rel=0.01)
    md = summary["max_distortion"]
    assert md["value_m"] / IN == pytest.approx(0.0787, rel=0.01)
    assert md["value_m"] == pytest.approx(math.hypot(d11["dX_m"], d11["dY_m"]), rel=1e-6)   # at node 11
    assert summary["spring_forces_N"]["spring_3_ground"] / LBF == pytest.approx(244.9, rel=0.002)
    assert summary["spring_forces_N"]["spring_4_11"] / LBF == pytest.approx(229.8, rel=0.002)


def test_small_deflection_crank_pivot_reaction(small):
    """Table 8.3: (130.4, 329.6, -207.0). Forces within 1 %. The bench's moment is -211.4 lb in:
    Shin's -207.0 equals the crank's transverse tip force times its length (41.4 lb x 5 in here,
    -207.1), without the P-delta moment of the 353 lb axial force on the tip deflection (4.3 lb in)
    that the beam-column field matrices carry; so the moment is checked as V L within 1 % and as a
    whole within 2.5 %."""
    s, sol, summary = small
    r = summary["reactions"]["1"]
    assert r["Fx_N"] / LBF == pytest.approx(130.4, rel=0.01)
    assert r["Fy_N"] / LBF == pytest.approx(329.6, rel=0.01)
    assert r["M_Nm"] / (LBF * IN) == pytest.approx(-207.0, rel=0.025)
    crank = sol.linear.members["crank"] if hasattr(sol, "linear") else sol.members["crank"]
    V = float(crank.V[0, 1])
    L = crank.member.length
    assert abs(V) * L / (LBF * IN) == pytest.approx(207.0, rel=0.01)


def test_small_deflection_min_safety_factor_at_node_3(small):
    """Min SF 1.86 at node 3 (Table 8.4). Shin's key-node stress uses HORIZ/A as the axial part
    (notes §7.5); on the coupler's 3-4 side the bench gives 1.853 (0.4 %), and its true minimum
    is 1.824 on the 2-3 side, where the compressive force adds (1.9 % below Shin)."""
    s, sol, summary = small
    sf = summary["min_safety_factor"]
    assert sf["member"] == "coupler[2-3]" and sf["node"] == 4            # the node at joint 3
    assert sf["value"] == pytest.approx(1.86, rel=0.02)
    rows, _ = results(s, sol)
    right = [r for r in rows if r["member"] == "coupler[3-4]" and r["node"] == 0][0]
    assert right["safety_factor"] == pytest.approx(1.86, rel=0.01)


def test_small_deflection_rigid_plate_and_slider(small):
    """The plate moves rigidly (Table 8.1: nodes 9, 10, 11 share one rotation) and the slider arm
    and link 7-8 carry no load (Table 8.2)."""
    s, sol, summary = small
    lin = sol.linear if hasattr(sol, "linear") else sol
    P = s.case.joint_positions
    d = {j: lin.joint_displacement[j] for j in ("9", "10", "11", "3")}
    # Small rotation: d_v - d_9 = theta x (r_v - r_9), the same theta for every vertex.
    def cross(a, b):
        return a[0] * b[1] - a[1] * b[0]
    th = [float(cross(P[v] - P["9"], d[v] - d["9"]) / np.dot(P[v] - P["9"], P[v] - P["9"])) for v in ("10", "11", "3")]
    assert np.ptp(th) < 1e-9 * max(abs(t) for t in th)
    for m in ("arm", "link_8_7"):
        assert np.max(np.abs(lin.members[m].N)) < 1e-6 and np.max(np.abs(lin.members[m].M)) < 1e-6


def test_large_deflection_against_tables_8_5_to_8_8(large):
    """Max distortion 4.097 in at node 33 and min SF 0.261 at node 3, within 5 %. Measured: 4.051
    in (-1.1 %) at the follower's 4th node from 4 (Shin's node 33) and 0.2609."""
    s, sol, summary = large
    md = summary["max_distortion"]
    assert md["member"] == "follower[4-5]" and md["node"] == 4
    assert md["value_m"] / IN == pytest.approx(4.097, rel=0.05)
    sf = summary["min_safety_factor"]
    assert sf["member"].startswith("coupler") and sf["value"] == pytest.approx(0.261, rel=0.05)
    # Reactions balance the two 300 lb loads exactly.
    R = summary["reactions"]
    fx = sum(v["Fx_N"] for v in R.values()) / LBF
    fy = sum(v["Fy_N"] for v in R.values()) / LBF
    assert fx == pytest.approx(300.0, rel=1e-9) and fy == pytest.approx(300.0, rel=1e-9)
    assert R["6"]["Fx_N"] / LBF == pytest.approx(136.2, rel=0.02)
    assert R["6"]["Fy_N"] / LBF == pytest.approx(84.53, rel=0.02)


@pytest.mark.parametrize("overrides, words", [
    ({"links.crank.path": ["1", "2", "99"]}, r"links.crank.path.*unknown joint"),
    ({"sliders.block5.along": "nolink"}, r"sliders.block5.along.*unknown link"),
    ({"plates.plate.vertices": ["3", "10", "10"]}, r"plates.plate.vertices.*already a vertex"),
    ({"links.extra": {"path": ["13", "X"], "section": "bar", "material": "aisi4340"},
      "joints.X": {"position": ["20 in", "20 in"]}}, r"links.extra.*dangles at joint 'X'"),
    ({"linkage.type": "six-bar"}, r"linkage.type.*must be one of"),
    ({"loads.slider_13.joint": "12x"}, r"loads.slider_13"),
])
def test_topology_errors_name_the_item(overrides, words):
    with pytest.raises(sc.ScenarioError, match=words):
        sc.load("shin_multiloop_small").with_overrides(overrides)


def test_cosim_run_does_the_static_analysis(tmp_path):
    from cosim.cli import main
    assert main(["run", "shin_multiloop_large", "--out", str(tmp_path / "ml")]) == 0
    import json
    summary = json.loads((tmp_path / "ml" / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["kind"] == "structure"
    assert (tmp_path / "ml" / "nodes.csv").exists()


# -- Shin's four one-degree-of-freedom sub-loop (branch) types, each against a closed form ---------
from tmm_core import Joint, LoadCase, Material, Member, Section, Structure, solve_static   # noqa: E402
from tmm_core.structure import SliderJoint   # noqa: E402

E_ST = 200e9
SEC = Section.rectangle(0.02, 0.02)
MAT = Material("s", E_ST, 7850.0)
EI, EA = E_ST * SEC.inertia_m4, E_ST * SEC.area_m2


def _solve(joints, members, positions, loads, **kw):
    s = Structure(tuple(joints), tuple(members), **kw)
    return solve_static(s, LoadCase({k: np.asarray(v, float) for k, v in positions.items()}, loads)).linear


def test_branch_case_1_free_end_on_a_welded_branch_point():
    """A cantilever branch E-F welded to the top of a clamped post A-E, tip load P at F:
    delta_F = P a^3/(3EI) + P a^2 L/(EI) + P L/(EA) (branch bending, post rotation, post shortening)."""
    L, a, P = 1.0, 0.6, 100.0
    post = Member.uniform("post", "A", "E", L, 8, SEC, MAT, start_connection="rigid", end_connection="rigid")
    arm = Member.uniform("arm", "E", "F", a, 8, SEC, MAT, start_connection="rigid", end_connection="rigid")
    loads = {"arm": np.zeros((9, 3))}
    loads["arm"][-1] = (0.0, -P, 0.0)
    sol = _solve([Joint("A", "clamped"), Joint("E"), Joint("F")], [post, arm],
                 {"A": (0, 0), "E": (0, L), "F": (a, L)}, loads)
    dF = -sol.joint_displacement["F"][1]
    assert dF == pytest.approx(P * a**3 / (3 * EI) + P * a**2 * L / EI + P * L / EA, rel=1e-9)


def test_branch_case_2_slider_end_on_a_revolute_branch_point():
    """A link E-F hinged at E to a clamped post and ending on a horizontal slider F: a pinned
    block on a frictionless guide takes no horizontal force, so a horizontal load at E bends the
    post alone (tip deflection P L^3/(3EI)) and the link carries no axial force."""
    L, a, P = 1.0, 0.8, 50.0
    post = Member.uniform("post", "A", "E", L, 8, SEC, MAT, start_connection="rigid")
    link = Member.uniform("link", "E", "F", a, 8, SEC, MAT)
    loads = {"post": np.zeros((9, 3))}
    loads["post"][-1] = (P, 0.0, 0.0)
    sol = _solve([Joint("A", "clamped"), Joint("E"), Joint("F", "slider", 0.0)], [post, link],
                 {"A": (0, 0), "E": (0, L), "F": (a, L)}, loads)
    assert sol.joint_displacement["E"][0] == pytest.approx(P * L**3 / (3 * EI), rel=1e-9)
    assert np.max(np.abs(sol.members["link"].N)) < 1e-9 * P
    assert abs(sol.reactions["F"][0]) < 1e-9 * P


def test_branch_case_3_pinned_end_on_a_revolute_branch_point():
    """A two-force strut E-F pinned to the ground at F and hinged to the tip E of a clamped
    cantilever A-E, which carries a vertical tip load P. Compatibility: the cantilever's tip
    force from the strut S satisfies (P - S sin) L^3/(3EI) sin = S c / (EA) ... solved in closed
    form for a vertical strut: S = P k_s/(k_s + k_b), k_b = 3EI/L^3, k_s = EA/h."""
    L, h, P = 1.0, 0.5, 80.0
    beam = Member.uniform("beam", "A", "E", L, 8, SEC, MAT, start_connection="rigid")
    strut = Member.uniform("strut", "F", "E", h, 4, SEC, MAT)
    loads = {"beam": np.zeros((9, 3))}
    loads["beam"][-1] = (0.0, -P, 0.0)
    sol = _solve([Joint("A", "clamped"), Joint("E"), Joint("F", "pinned")], [beam, strut],
                 {"A": (0, 0), "E": (L, 0), "F": (L, -h)}, loads)
    kb, ks = 3 * EI / L**3, EA / h
    S = P * ks / (ks + kb)
    assert -float(sol.members["strut"].N[0, 1]) == pytest.approx(S, rel=1e-6)
    assert -sol.joint_displacement["E"][1] == pytest.approx(P / (ks + kb), rel=1e-6)


def test_branch_case_4_pinned_end_on_a_slider_branch_point():
    """An inclined strut pinned to the ground at F whose block E rides on a simply supported beam
    A-B at mid-span. A frictionless block passes only the force normal to the beam, and the
    strut, being inclined, can only push along itself: so the strut carries nothing and the
    block slides instead. The beam then deflects as if alone, P L^3 / (48 EI), and the block
    follows the beam's mid-span point normal to the beam."""
    L, h, c, P = 2.0, 0.5, 0.3, 120.0
    left = Member.uniform("left", "A", "M", L / 2, 8, SEC, MAT, end_connection="rigid")
    right = Member.uniform("right", "M", "B", L / 2, 8, SEC, MAT, start_connection="rigid")
    strut = Member.uniform("strut", "F", "E", float(np.hypot(c, h)), 4, SEC, MAT)
    loads = {"left": np.zeros((9, 3))}
    loads["left"][-1] = (0.0, -P, 0.0)
    sol = _solve([Joint("A", "pinned"), Joint("M"), Joint("B", "slider", 0.0), Joint("E"), Joint("F", "pinned")],
                 [left, right, strut], {"A": (0, 0), "M": (L / 2, 0), "B": (L, 0), "E": (L / 2, 0),
                                        "F": (L / 2 - c, -h)},
                 loads, sliders=(SliderJoint("block", "E", "M", "left"),))
    assert -sol.joint_displacement["M"][1] == pytest.approx(P * L**3 / (48 * EI), rel=1e-9)
    assert np.max(np.abs(sol.members["strut"].N)) < 1e-9 * P
    assert sol.joint_displacement["E"][1] == pytest.approx(sol.joint_displacement["M"][1], rel=1e-12)
    # The block slid along the beam so that the strut keeps its length: (E - F) . dE = 0.
    dE = sol.joint_displacement["E"]
    assert abs(c * dE[0] + h * dE[1]) < 1e-12
