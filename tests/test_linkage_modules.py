"""The complete module set of the component-module approach (Shin 1986, Ch. 2, Fig. 2.1, App. A):
the RPR dyad (``rpr``: Shin's types 7 and 8, the inverted slider-crank), the
PRP dyad (``prp``: a joint on two slides) and the RPP dyad (``rpp``: the Scotch yoke), beside the
crank, RRR and RRP modules of ``tests/test_linkage.py``.

For every new module, on small example linkages (inches; each turned through a revolution):
velocities and accelerations against central differences at twelve crank angles on both assembly
branches, loop closure and slide constraints over the revolution, a refusal naming the module and
the crank angle, and the ``type = "linkage"`` scenario format with the transfer-matrix
instantaneous structure checked by rigid-body virtual work.

Shin's type 7 against types 8 + 4, worked (``eccentric``): a follower pivoted at D = (0, -4) in
with an arm D-H of 1.5 in along x and its slot vertical through H (x = 1.5 in, 1.5 in off the
pivot); the block S on the slot carries a 1 in link to the crank tip B at 60 deg to the slot
(B = (1, 1.732) in at crank angle 60 deg, S = (1.5, 2.598) in). In the follower's frame B traces
the vertical line x = 1 in through its drawn position, 1 in off the pivot: type 8 (a block pinned
at B sliding on that line) gives the follower's turn, and type 4 (the block turning with it) gives
S. At crank angle 150 deg (B = (-1.7321, 1) in) both give the follower turned by 30 deg from its
drawn position, the block 0.5359 in back along the slot, and S = B + R(30 deg) (0.5, 0.8660) in
= (-1.7321, 2) in, on the real slot (1.5 in off the pivot, now through (1.2990, -3.25) in).

Measured (2026-11): largest relative difference between the closed-form velocities /
accelerations and the differences (h = 1e-5 s, every joint, body and slide) 6.0e-7 (rpr: shaper,
type 7, moving pivot, slider input; both branches), 1.0e-7 (prp), 1.4e-7 (rpp): the differences'
own truncation error. Rigid-body virtual work of the instantaneous structures to 2e-11 of the
drive torque's peak-to-peak.
"""
import math
import re
import tomllib

import numpy as np
import pytest

import cosim.scenario as cs
from tmm_core import AssemblyError, InputError, quasi_static
from tmm_core.linkage import MODULE_KINDS, SHIN_TYPES, LinkageKinematics, Module

IN = 0.0254


def unit(a):
    return np.array([math.cos(a), math.sin(a)])


def ang(v):
    return math.atan2(v[1], v[0])


def cross(a, b):
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _rot(v, a):
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


# -- example linkages --------------------------------------------------------------------------
def shaper(branch=0, crank=2.0, pivot_y=-3.0):
    """Shin's type 8, the crank-shaper (inverted slider-crank): crank A-B (2 in, drawn at 60 deg),
    a block pinned at B sliding along the follower D-G-E pivoted at D = (0, -3) in."""
    A, D = np.zeros(2), np.array([0.0, pivot_y]) * IN
    B = A + crank * IN * unit(math.radians(60))
    e = (B - D) / np.linalg.norm(B - D)
    P = {"A": A, "B": B, "D": D, "G": B.copy(), "E": D + 9 * IN * e}
    return LinkageKinematics(P, {"crank": ("A", "B"), "follower": ("D", "G", "E"), "blk": ("B",)}, ("A", "D"),
                             "crank", "A", "B", (Module("crank", "B", ("crank",)),
                                                 Module("rpr", "B", ("blk", "follower"), branch)),
                             guided={"blk": ("follower", ang(e))}, name="shaper")


def eccentric(branch=0, pivot_y=-4.0, traced=False):
    """Shin's type 7 (see the module docstring). ``traced``: the same follower with the type-8
    block of the worked example (pinned at B, sliding on the line B traces in the follower), and
    no S."""
    A, D, H = np.zeros(2), np.array([0.0, pivot_y]) * IN, np.array([1.5, pivot_y]) * IN
    B = 2 * IN * unit(math.radians(60))
    S = B + IN * unit(math.radians(60))                       # x = 1.5 in: on the slot
    P = {"A": A, "B": B, "D": D, "H": H, "G": S.copy(), "E": np.array([1.5, 6.0]) * IN, "S": S}
    bodies = {"crank": ("A", "B"), "follower": ("D", "H", "G", "E"), "blk": ("S", "B")}
    if traced:
        del P["S"]
        bodies["blk"] = ("B",)
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B",
                             (Module("crank", "B", ("crank",)), Module("rpr", "B", ("blk", "follower"), branch)),
                             guided={"blk": ("follower", math.pi / 2)}, name="type 7")


FOURBAR = {"A": (0, 0), "B": (3, 0), "C": (9.071429, 7.945927), "D": (10, 0), "E": (9.419643, 4.966204)}


def fourbar(with_e=False):
    """The Watt six-bar's first loop (crank 3, coupler 10, rocker 8, ground 10 in), drawn at 0 deg."""
    return {k: np.array(v, float) * IN for k, v in FOURBAR.items() if with_e or k != "E"}


def rpr_moving_pivot(branch=0):
    """RPR with both known joints moving: a block pinned at the coupler's mid-point M slides along a
    follower pivoted at the rocker's joint E."""
    P = fourbar(True)
    P["M"] = 0.5 * (P["B"] + P["C"])
    e = (P["M"] - P["E"]) / np.linalg.norm(P["M"] - P["E"])
    P["G"], P["F"] = P["M"].copy(), P["E"] + 7 * IN * e
    bodies = {"crank": ("A", "B"), "coupler": ("B", "M", "C"), "rocker": ("D", "E", "C"), "blk": ("M",),
              "follower": ("E", "G", "F")}
    mods = (Module("crank", "B", ("crank",)), Module("rrr", "C", ("coupler", "rocker")),
            Module("rpr", "M", ("blk", "follower"), branch))
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B", mods, guided={"blk": ("follower", ang(e))},
                             name="rpr on a moving pivot")


def slider_input(branch=0):
    """Shin's type 8 with his slider input: the slider C of a slider-crank (rrp on a horizontal
    ground slide) rides in the slot of a follower pivoted at D."""
    A = np.zeros(2)
    B = 2 * IN * unit(math.radians(45))
    C = np.array([B[0] + math.sqrt((6 * IN) ** 2 - B[1] ** 2), 0.0])
    D = np.array([5 * IN, -3 * IN])
    e = (C - D) / np.linalg.norm(C - D)
    P = {"A": A, "B": B, "C": C, "D": D, "G": C.copy(), "E": D + 8 * IN * e}
    bodies = {"crank": ("A", "B"), "rod": ("B", "C"), "blk": ("C",), "follower": ("D", "G", "E")}
    mods = (Module("crank", "B", ("crank",)), Module("rrp", "C", ("rod",)),
            Module("rpr", "C", ("blk", "follower"), branch))
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B", mods, ground_slides={"C": 0.0},
                             guided={"blk": ("follower", ang(e))}, name="slider input")


def prp_rocker(branch=0):
    """PRP: joint S on a horizontal ground slide and on the arm K-S (2 in, square to the rocker) of a
    block K sliding along the rocker of the four-bar."""
    P = fourbar()
    er = (P["C"] - P["D"]) / np.linalg.norm(P["C"] - P["D"])
    P["G"] = P["D"] + 6 * IN * er
    P["K"] = P["G"].copy()
    P["S"] = P["K"] + 2 * IN * np.array([-er[1], er[0]])
    bodies = {"crank": ("A", "B"), "coupler": ("B", "C"), "rocker": ("D", "G", "C"), "blk": ("K", "S")}
    mods = (Module("crank", "B", ("crank",)), Module("rrr", "C", ("coupler", "rocker")), Module("prp", "S"))
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B", mods, ground_slides={"S": 0.0},
                             guided={"blk": ("rocker", ang(er))}, name="prp on a rocker and the ground")


def prp_two_guides(branch=0):
    """PRP on two moving guides: S at the ends of the arms of a block along the rocker and a block
    along the coupler."""
    P = fourbar()
    er = (P["C"] - P["D"]) / np.linalg.norm(P["C"] - P["D"])
    ec = (P["C"] - P["B"]) / np.linalg.norm(P["C"] - P["B"])
    P["S"] = P["C"] + np.array([-2.0, -1.5]) * IN
    P["KR"] = P["D"] + ((P["S"] - P["D"]) @ er) * er
    P["KC"] = P["B"] + ((P["S"] - P["B"]) @ ec) * ec
    bodies = {"crank": ("A", "B"), "coupler": ("B", "C"), "rocker": ("D", "C"), "bR": ("KR", "S"), "bC": ("KC", "S")}
    mods = (Module("crank", "B", ("crank",)), Module("rrr", "C", ("coupler", "rocker")), Module("prp", "S"))
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B", mods,
                             guided={"bR": ("rocker", ang(er)), "bC": ("coupler", ang(ec))}, name="prp on two guides")


def scotch_yoke(branch=0, slot_deg=60.0):
    """RPP, the Scotch yoke: a block pinned at the crank tip B (2 in, drawn at 30 deg) slides in
    the yoke's slot (at ``slot_deg``), the yoke Y-G-Z along a horizontal ground slide at Y."""
    B = 2 * IN * unit(math.radians(30))
    e = unit(math.radians(slot_deg))
    P = {"A": np.zeros(2), "B": B, "G": B.copy(), "Y": B - 3 * IN * e, "Z": B + 3 * IN * e}
    return LinkageKinematics(P, {"crank": ("A", "B"), "yoke": ("Y", "G", "Z"), "blk": ("B",)}, ("A",), "crank", "A",
                             "B", (Module("crank", "B", ("crank",)), Module("rpp", "B", ("blk", "yoke"))),
                             ground_slides={"Y": 0.0}, guided={"blk": ("yoke", math.radians(slot_deg)),
                                                                "yoke": (None, 0.0)}, name="Scotch yoke")


def rpp_on_rocker(branch=0):
    """RPP on a moving guide: a sled sliding along the four-bar's rocker, its slot at 70 deg to the
    rocker, and a block pinned at the crank tip B sliding in the slot."""
    P = fourbar()
    er = (P["C"] - P["D"]) / np.linalg.norm(P["C"] - P["D"])
    es = unit(ang(er) + math.radians(70))
    t = np.linalg.solve(np.column_stack([er, -es]), P["B"] - P["D"])
    P["K"] = P["D"] + t[0] * er
    P["G2"], P["Z"] = P["B"].copy(), P["K"] + (t[1] + 2 * IN) * es
    bodies = {"crank": ("A", "B"), "coupler": ("B", "C"), "rocker": ("D", "C"), "sled": ("K", "G2", "Z"),
              "blk": ("B",)}
    mods = (Module("crank", "B", ("crank",)), Module("rrr", "C", ("coupler", "rocker")),
            Module("rpp", "B", ("blk", "sled")))
    return LinkageKinematics(P, bodies, ("A", "D"), "crank", "A", "B", mods,
                             guided={"sled": ("rocker", ang(er)), "blk": ("sled", ang(es))}, name="rpp on a rocker")


RPR = [shaper, eccentric, rpr_moving_pivot, slider_input]
CASES = [(f, b) for f in RPR for b in (1, -1)] + [(f, 0) for f in (prp_rocker, prp_two_guides, scotch_yoke,
                                                                   rpp_on_rocker)]
IDS = [f"{f.__name__}{'' if b == 0 else '+' if b > 0 else '-'}" for f, b in CASES]


def build(f, branch):
    """The example on branch ``branch`` (+1: the drawn one; -1: the other)."""
    kin = f()
    if branch >= 0:
        return kin
    i = next(k for k, m in enumerate(kin.modules) if m.kind == "rpr")
    return f(-kin.step(i)["branch"])


def fd_error(kin, angles, w=20.0, alpha=35.0, h=1e-5):
    """Largest relative difference between the closed-form velocities / accelerations of every
    joint, body and slide and central differences along theta(t) = theta0 + w t + alpha t^2 / 2."""
    worst = 0.0

    def rel(x, dx, ref):
        return abs((x[2] - x[0]) / (2 * h) - dx) / (1.0 + abs(ref))
    for th0 in angles:
        t = np.array([-h, 0.0, h])
        st = kin.solve(th0 + w * t + 0.5 * alpha * t**2, w + alpha * t, alpha)
        for p, v, a in st.joints.values():
            sv, sa = 1.0 + np.abs(v[1]).max(), 1.0 + np.abs(a[1]).max()
            worst = max(worst, np.abs((p[2] - p[0]) / (2 * h) - v[1]).max() / sv,
                        np.abs((v[2] - v[0]) / (2 * h) - a[1]).max() / sa)
        for b in st.bodies.values():
            worst = max(worst, rel(np.unwrap(b.rotation), b.omega[1], b.omega[1]), rel(b.omega, b.alpha[1], b.alpha[1]))
        for s, sd, sdd in list(st.block_slides.values()) + list(st.slides.values()):
            worst = max(worst, rel(s, sd[1], sd[1]), rel(sd, sdd[1], sdd[1]))
    return worst


def closure_error(kin, st):
    """Largest violation [m] over the batch of: every joint of every body where its pose puts it
    (rigid bodies, shared joints consistent), every sliding body turning with its guide and its
    joints on their slides at its slide, every ground slide's joint on its line."""
    worst = 0.0
    ref = kin.reference_position
    for b, joints in kin.bodies.items():
        bm, a0 = st.bodies[b], joints[0]
        for j in joints:
            want = st.joints[a0][0] + np.stack([_rot(ref(j) - ref(a0), r) for r in np.ravel(bm.rotation)])
            worst = max(worst, np.abs(st.joints[j][0] - want).max())
    for s, (g, d) in kin.guided.items():
        rot = np.ravel(st.bodies[g].rotation) if g is not None else np.zeros(st.crank_angle.size)
        worst = max(worst, np.abs(np.sin(np.ravel(st.bodies[s].rotation) - rot)).max() * IN)
        x = st.block_slides[s][0]
        for j in kin.bodies[s]:
            if g is None:
                on = ref(j) + x[:, None] * unit(d)
            else:
                ga = kin.bodies[g][0]
                on = np.stack([st.joints[ga][0][k] + _rot(ref(j) - ref(ga) + x[k] * unit(d), rot[k])
                               for k in range(rot.size)])
            worst = max(worst, np.abs(st.joints[j][0] - on).max())
    for j, d in kin.ground_slides.items():
        worst = max(worst, np.abs(cross(unit(d), st.joints[j][0] - ref(j))).max())
    return worst


# -- the module set ----------------------------------------------------------------------------
def test_every_shin_type_has_a_module():
    """Fig. 2.1's eight types: 1 crank, 2 rrr, 3/5/6 rrp, 4 automatic, 7/8 rpr; prp and rpp
    complete the planar dyads of lower pairs (RRR, RRP, RPR, PRP, RPP)."""
    assert sorted(SHIN_TYPES) == list(range(1, 9))
    assert {t: m for t, (m, _) in SHIN_TYPES.items()} == {1: "crank", 2: "rrr", 3: "rrp", 4: None, 5: "rrp",
                                                          6: "rrp", 7: "rpr", 8: "rpr"}
    assert set(MODULE_KINDS) == {"crank", "rrr", "rrp", "rpr", "prp", "rpp"}
    with pytest.raises(InputError, match="single assembly"):
        Module("prp", "S", (), 1)
    with pytest.raises(InputError, match="needs 0 link"):
        Module("prp", "S", ("a",))


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_new_modules_match_finite_differences(case):
    """Velocities and accelerations of every joint, body and slide at twelve crank angles."""
    kin = build(*case)
    assert fd_error(kin, np.radians(np.arange(0.0, 360.0, 30.0))) < 2e-6


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_new_modules_close_their_loops_over_a_revolution(case):
    """A revolution (360 positions) with no refusal; every constraint held to round-off; the drawn
    configuration reproduced on the drawn branch."""
    f, branch = case
    kin = build(f, branch)
    q = kin.reference_crank_angle + np.radians(np.arange(360.0))
    st = kin.solve(q, 20.0, 0.0)
    assert closure_error(kin, st) < 1e-13
    if branch >= 0:
        for j in kin.joint_names:
            np.testing.assert_allclose(st.joints[j][0][0], kin.reference_position(j), atol=1e-14)


@pytest.mark.parametrize("f", RPR)
def test_rpr_branches_are_the_two_assemblies(f):
    """The other branch turns the guide so that the known joint lies on the slide line's other side
    of the pivot's foot: same joint, same distance to the pivot, the other root."""
    a, b = f().solve(1.0), build(f, -1).solve(1.0)
    m = next(s for s in f().modules if s.kind == "rpr")
    blk, guide = m.links
    assert np.linalg.norm(a.joints[m.joint][0] - b.joints[m.joint][0]) < 1e-15
    assert abs(math.sin(a.bodies[guide].rotation - b.bodies[guide].rotation)) > 0.1 or \
        abs(math.cos(a.bodies[guide].rotation - b.bodies[guide].rotation) - 1) > 0.1
    assert a.block_slides[blk][0] != pytest.approx(b.block_slides[blk][0], abs=1e-4)


@pytest.mark.parametrize("branch", [1, -1])
def test_rpr_position_matches_the_half_angle_closed_form(branch):
    """Shin's App. A solves types 7/8 by A cos(psi) + B sin(psi) + C = 0, psi = 2 atan((-B +/-
    sqrt(A^2 + B^2 - C^2)) / (C - A)); re-derived from the loop closure (the appendix's type-8
    C carries a sign slip in the OCR): with d = P - Q and psi the slide's direction, the offset
    k = cross(e, P - Q) is constant, so A = d_y, B = -d_x, C = -k. One of the two roots is the
    follower of each branch."""
    kin = build(eccentric, branch)
    q = np.radians(np.arange(0.0, 360.0, 7.0))
    st = kin.solve(q)
    u = kin.reference_position("B") - kin.reference_position("D")
    k = float(cross(unit(math.pi / 2), u))
    d = st.joints["B"][0] - st.joints["D"][0]
    A, B, C = d[:, 1], -d[:, 0], -k
    psi = math.pi / 2 + st.bodies["follower"].rotation
    roots = [2 * np.arctan((-B + sgn * np.sqrt(A**2 + B**2 - C**2)) / (C - A)) for sgn in (1, -1)]
    miss = [np.abs(np.sin(0.5 * (psi - r))).max() for r in roots]
    assert min(miss) < 1e-12 and max(miss) > 0.1


def test_type_7_is_type_8_on_the_traced_line_then_type_4():
    """The worked example of the module docstring: the follower of Shin's type 7 turns as the
    follower of a type 8 whose block is pinned at B on the line B traces in it (x = 1 in, parallel
    to the slot), and the block's joint S is type 4 of that block: B + R(phi) (S - B)_drawn, with
    v_S = v_B + w k x r, a_S = a_B + alpha k x r - w^2 r. S stays on the real slot (x = 1.5 in)."""
    k7, k8 = eccentric(), eccentric(traced=True)
    q = np.radians(np.arange(0.0, 360.0, 5.0))
    s7, s8 = k7.solve(q, 20.0, 35.0), k8.solve(q, 20.0, 35.0)
    for j in ("D", "H", "G", "E", "B"):
        for x7, x8 in zip(s7.joints[j], s8.joints[j]):
            np.testing.assert_allclose(x7, x8, atol=1e-12 * (1 + np.abs(x8).max()))
    f7, f8 = s7.bodies["follower"], s8.bodies["follower"]
    for x7, x8 in zip((f7.rotation, f7.omega, f7.alpha), (f8.rotation, f8.omega, f8.alpha)):
        np.testing.assert_allclose(x7, x8, rtol=1e-12, atol=1e-12)
    # Type 4: S from the type-8 block's pose.
    r = np.stack([_rot(k7.reference_position("S") - k7.reference_position("B"), p) for p in f8.rotation])
    kr = np.stack([-r[:, 1], r[:, 0]], -1)
    pB, vB, aB = s8.joints["B"]
    w, al = f8.omega[:, None], f8.alpha[:, None]
    for x7, x4 in zip(s7.joints["S"], (pB + r, vB + w * kr, aB + al * kr - w**2 * r)):
        np.testing.assert_allclose(x7, x4, atol=1e-12 * (1 + np.abs(x4).max()))
    # S on the real slot: (S - H) along the follower's turned slot direction.
    slot = np.stack([unit(math.pi / 2 + p) for p in f8.rotation])
    assert np.abs(cross(slot, s7.joints["S"][0] - s7.joints["H"][0])).max() < 1e-14
    # The numbers of the docstring, at crank angle 150 deg.
    st = k7.solve(math.radians(150.0))
    assert math.degrees(st.bodies["follower"].rotation) == pytest.approx(30.0, abs=1e-12)
    np.testing.assert_allclose(st.joints["S"][0] / IN, (-math.sqrt(3), 2.0), atol=1e-12)
    np.testing.assert_allclose(st.joints["H"][0] / IN, (1.5 * math.cos(math.radians(30)), -3.25), atol=1e-12)
    assert st.block_slides["blk"][0] / IN == pytest.approx(-0.5359, abs=5e-5)


# -- refusals ----------------------------------------------------------------------------------
def revolution(kin, tol_deg=0.5):
    """The loader's check: a revolution CCW from the drawn position, 0.5 deg from any toggle."""
    kin.solve(kin.reference_crank_angle + np.linspace(0.0, 2 * math.pi, 1440, endpoint=False),
              lock_tolerance=math.sin(math.radians(tol_deg)))


def crank_angle_in(msg):
    return float(msg.split("at crank angle ")[1].split(" deg")[0])


def test_rpr_that_cannot_assemble_is_refused_naming_the_module_and_the_crank_angle():
    """Type 7 with the follower's pivot at (0, -2.5) in: B comes within 0.5 in of it, closer than
    the 1 in offset of the line it traces in the follower, from crank angle 180 + asin(0.925) deg."""
    with pytest.raises(AssemblyError) as err:
        revolution(eccentric(pivot_y=-2.5))
    msg = str(err.value)
    assert "module 2 (rpr at joint 'B', links 'blk', 'follower') cannot assemble: joints 'B' and 'D' are" in msg
    assert "less than the offset (0.0254 m) of the slide of block 'blk'" in msg
    assert crank_angle_in(msg) == pytest.approx(180 + math.degrees(math.asin(0.925)), abs=0.3)


def test_rpr_through_its_pivot_is_refused():
    """The shaper with crank 3 in and pivot (0, -3) in: B passes over the pivot at 270 deg."""
    kin = shaper(crank=3.0)
    kin.solve(np.radians([0.0, 100.0, 269.0]))
    with pytest.raises(AssemblyError, match=r"at crank angle 270 deg, module 2 \(rpr at joint 'B', links 'blk', "
                                            r"'follower'\) locks: joint 'B' is .* m from the pivot 'D'"):
        kin.solve(math.radians(270.0))


def test_prp_whose_slides_turn_parallel_is_refused():
    """A pin S on the vertical ground line x = 3 in and in a slot along the crank: the slides are
    parallel at crank angle 90 deg (the loader's 0.5 deg: from 89.5 deg)."""
    B = 2 * IN * unit(math.radians(30))
    S = np.array([3 * IN, 3 * IN * math.tan(math.radians(30))])
    kin = LinkageKinematics({"A": (0, 0), "B": B, "S": S}, {"crank": ("A", "B"), "blk": ("S",)}, ("A",), "crank",
                            "A", "B", (Module("crank", "B", ("crank",)), Module("prp", "S")),
                            ground_slides={"S": math.pi / 2}, guided={"blk": ("crank", math.radians(30))},
                            name="slotted crank")
    kin.solve(np.radians([0.0, 60.0, 88.0]))
    with pytest.raises(AssemblyError) as err:
        revolution(kin)
    msg = str(err.value)
    assert ("module 2 (prp at joint 'S') cannot assemble: its two slides (block 'blk' along 'crank', the ground "
            "slide) are 0.5 deg from parallel") in msg
    assert crank_angle_in(msg) == pytest.approx(89.5, abs=0.26)


def test_rpp_with_parallel_slides_is_refused():
    """The yoke's slot along its own slide: locked at every position (refused when built); 0.3 deg
    off, it passes the exact check but not the loader's 0.5 deg, at the first crank angle."""
    with pytest.raises(InputError, match=r"module 2 \(rpp at joint 'B', links 'blk', 'yoke'\): the slide of block "
                                         r"'blk' along link 'yoke' is parallel to the slide of 'yoke' along the "
                                         "ground: the linkage locks at every position"):
        scotch_yoke(slot_deg=0.0)
    kin = scotch_yoke(slot_deg=0.3)
    with pytest.raises(AssemblyError, match=r"at crank angle 30 deg, module 2 \(rpp at joint 'B', links 'blk', "
                                            r"'yoke'\) locks: the slide of block 'blk' along 'yoke' is 0.3 deg from "
                                            "parallel to the slide of 'yoke' along the ground"):
        revolution(kin)


RPR_MODS = (Module("crank", "B", ("crank",)), Module("rpr", "B", ("blk", "follower")))


@pytest.mark.parametrize("mods, guided, match", [
    (RPR_MODS, {"blk": ("follower", 1.0), "crank": ("follower", 1.0)},
     "module 1 (crank at joint 'B', link 'crank'): link 'crank' slides along link 'follower': place it by a module "
     "that keeps its slide"),
    (RPR_MODS, {"blk": ("crank", 1.0)}, "link 'blk' is not a block sliding along link 'follower'"),
    ((Module("crank", "B", ("crank",)), Module("rpr", "B", ("follower", "blk"))), {"blk": ("follower", 1.0)},
     "joint 'B' is not on link 'follower'"),
    ((Module("crank", "B", ("crank",)), Module("rpp", "B", ("blk", "follower"))), {"blk": ("follower", 1.0)},
     "link 'follower' does not slide"),
    ((Module("rpr", "B", ("blk", "follower")),), {"blk": ("follower", 1.0)}, "joint 'B' is not placed yet"),
])
def test_bad_module_order_is_refused(mods, guided, match):
    P = {j: shaper().reference_position(j) for j in shaper().joint_names}
    with pytest.raises(InputError, match=re.escape(match)):
        LinkageKinematics(P, {"crank": ("A", "B"), "follower": ("D", "G", "E"), "blk": ("B",)}, ("A", "D"), "crank",
                          "A", "B", mods, guided=guided)


# -- the scenario format and the transfer-matrix structure -------------------------------------
def _q(x):
    return f"{x / IN:.9f} in"


def scenario(kin, name, links, sliders, modules, slider_joints=None, gauge_link=None):
    """A ``type = "linkage"`` scenario of an example (the six-bar's strips, drive and solver)."""
    base = tomllib.loads((cs.SCENARIO_DIR / "watt_sixbar_600rpm.toml").read_text(encoding="utf-8"))
    data = {k: base[k] for k in ("materials", "sections", "drive", "solver", "coupling", "output")}
    data["scenario"] = {"name": name, "description": name, "sources": ["tests"], "rig": "none"}
    data["linkage"] = {"type": "linkage", "crank": "crank"}
    data["joints"] = {}
    for j in kin.joint_names:
        p = kin.reference_position(j)
        d = {"position": [_q(p[0]), _q(p[1])]}
        if j in kin.ground:
            d["support"] = "pinned"
        if j in (slider_joints or {}):
            d.update(support="slider", direction=slider_joints[j])
        data["joints"][j] = d
    data["links"] = {n: dict(section="strip", material="aluminium", **d) for n, d in links.items()}
    data["sliders"] = sliders
    data["modules"] = [{"type": "crank", "link": "crank"}] + list(modules)
    data["gauges"] = {"g": {"link": gauge_link, "position": "0.5 in", "face": "top"}}
    return data


def shaper_scenario():
    return scenario(shaper(), "shaper", {"crank": {"path": ["A", "B"]}, "follower": {"path": ["D", "G", "E"]}},
                    {"blk": {"block": "B", "guide": "G", "along": "follower"}},
                    [{"type": "rpr", "joint": "B", "link": "follower"}], gauge_link="follower")


def eccentric_scenario():
    return scenario(eccentric(), "type_7", {"crank": {"path": ["A", "B"]},
                                            "arm": {"path": ["B", "S"], "welded_at": ["S"]},
                                            "follower": {"path": ["H", "G", "E"], "welded_at": ["H"]},
                                            "follower_arm": {"path": ["D", "H"], "welded_at": ["H"]}},
                    {"blk": {"block": "S", "guide": "G", "along": "follower"}},
                    [{"type": "rpr", "joint": "B", "link": "follower"}], gauge_link="follower")


def prp_scenario():
    return scenario(prp_rocker(), "prp", {"crank": {"path": ["A", "B"]}, "coupler": {"path": ["B", "C"]},
                                          "rocker": {"path": ["D", "G", "C"]},
                                          "arm": {"path": ["K", "S"], "welded_at": ["K"]}},
                    {"blk": {"block": "K", "guide": "G", "along": "rocker"}},
                    [{"type": "rrr", "joint": "C", "links": ["coupler", "rocker"]}, {"type": "prp", "joint": "S"}],
                    slider_joints={"S": "0 deg"}, gauge_link="rocker")


def yoke_scenario():
    return scenario(scotch_yoke(), "yoke", {"crank": {"path": ["A", "B"]},
                                            "yoke": {"path": ["Y", "G", "Z"], "welded_at": ["Y"]}},
                    {"blk": {"block": "B", "guide": "G", "along": "yoke"}},
                    [{"type": "rpp", "joint": "B", "link": "yoke"}], slider_joints={"Y": "0 deg"}, gauge_link="yoke")


SCENARIOS = {"rpr_type_8": (shaper_scenario, shaper), "rpr_type_7": (eccentric_scenario, eccentric),
             "prp": (prp_scenario, prp_rocker), "rpp": (yoke_scenario, scotch_yoke)}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_new_modules_in_the_scenario_format(name):
    """Each example as a scenario: the loader builds the same kinematics (the crank turned through
    its revolution check), and the instantaneous structure (sliders riding their guides, the yoke
    on a sliding clamp) passes rigid-body virtual work: under inertia alone the clamped crank's
    reaction is the equivalent-inertia torque J'(q) w^2 / 2 of the lumped mass model."""
    make, example = SCENARIOS[name]
    sc = cs.from_dict(make(), name)
    m, ref = sc.mechanism, example()
    q = ref.reference_crank_angle + np.radians(np.arange(0.0, 360.0, 15.0))
    a, b = m.kinematics.solve(q, 20.0, 3.0), ref.solve(q, 20.0, 3.0)
    for j in ref.joint_names:
        for x, y in zip(a.joints[j], b.joints[j]):
            np.testing.assert_allclose(x, y, atol=1e-9 * (1 + np.abs(y).max()), err_msg=j)
    st = m.structure()
    if name == "rpp":
        assert st.joint("Y").support == "sliding_clamp" and m.kinematics.sliding_blocks == {"Y": "yoke"}
    w = sc.drive.speed_rad_s
    _, dJ, _ = m.crank_inertia(q, lumped=True)
    qs = quasi_static(m, q, w, beam_column=False)
    np.testing.assert_allclose(qs.drive_torque, 0.5 * dJ * w**2, atol=1e-9 * np.ptp(qs.drive_torque))


def test_scenario_refuses_an_rpr_that_cannot_assemble():
    """The type-7 scenario with its follower's pivot 1.5 in higher (as the refusal above)."""
    data = eccentric_scenario()
    for j in ("D", "H"):
        data["joints"][j]["position"][1] = "-2.5 in"
    with pytest.raises(cs.ScenarioError, match=r"key 'modules'.*the crank cannot turn a full revolution: .*at crank "
                                               r"angle 247\.\d+ deg, module 2 \(rpr at joint 'B', links 'blk', "
                                               r"'follower'\) cannot assemble"):
        cs.from_dict(data, "type_7_too_close")


@pytest.mark.parametrize("edit, key, match", [
    (lambda d: d["modules"][1].update(link="crank"), "modules[1].joint", "no [sliders] block along link 'crank'"),
    (lambda d: d["modules"][1].update(type="prp"), "modules[1].link", "a 'prp' module names 0 links"),
    (lambda d: d["modules"][1].update(branch=1), "modules[1]", "single assembly"),
    (lambda d: d["modules"][1].pop("joint"), "modules[1].joint", "is required"),
])
def test_bad_new_module_input_names_the_key(edit, key, match):
    data = yoke_scenario()
    edit(data)
    with pytest.raises(cs.ScenarioError) as err:
        cs.from_dict(data, "bad_yoke")
    assert f"key '{key}'" in str(err.value) and match in str(err.value)


def test_mujoco_refuses_a_module_its_tree_builder_does_not_have():
    """MuJoCo's builder knows crank, rrr and rrp: an rpr linkage is refused naming the module
    (the transfer-matrix model and exudyn run it)."""
    from cosim.engines import make_engine
    sc = cs.from_dict(shaper_scenario(), "shaper")
    with pytest.raises(InputError, match=r"module 2 is 'rpr'.*--engines tmm,exudyn"):
        make_engine("mujoco").reset(sc, 0.0, sc.mechanism.kinematics.reference_crank_angle, 1.0)
