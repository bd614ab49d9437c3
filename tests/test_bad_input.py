"""Bad input raises a clear error naming what is wrong; the solver never returns NaN."""
import numpy as np
import pytest

from tmm_core import (AssemblyError, BucklingError, InputError, Joint, Link, LoadCase, Material, Member, Section,
                      SingularStructureError, Structure, solve_static)
from tmm_core.kinematics import FourBarGeometry

from .helpers import cantilever, tip_load_case

STEEL = Material("steel", 2e11, 7850.0)
SEC = Section.rectangle(0.02, 0.005)


@pytest.mark.parametrize("build, field", [
    (lambda: Member.uniform("coupler", "A", "B", 0.0, 4, SEC, STEEL), "member 'coupler': length"),
    (lambda: Member.uniform("coupler", "A", "B", -0.3, 4, SEC, STEEL), "member 'coupler': length"),
    (lambda: Member.uniform("coupler", "A", "B", 0.3, 0, SEC, STEEL), "n_segments"),
    (lambda: Section.rectangle(0.0, 0.005), "section width_m"),
    (lambda: Section.rectangle(0.02, -1.0), "section depth_m"),
    (lambda: Section(1e-4, 0.0, 0.01), "section inertia_m4"),
    (lambda: Material("alu", 0.0), "material 'alu': E_Pa"),
    (lambda: Material("alu", -7e10), "material 'alu': E_Pa"),
    (lambda: Material("alu", float("nan")), "material 'alu': E_Pa"),
    (lambda: FourBarGeometry(0.1, 0.3, -0.2, 0.25), "rocker length"),
    (lambda: Joint("A", "welded"), "joint 'A': support"),
])
def test_bad_parameters_name_the_field_and_value(build, field):
    with pytest.raises(InputError, match=field):
        build()


def test_error_message_contains_the_value():
    with pytest.raises(InputError, match=r"-0\.3"):
        Member.uniform("coupler", "A", "B", -0.3, 4, SEC, STEEL)


def test_joint_positions_that_do_not_match_the_member_length():
    structure, member = cantilever(3)
    case = LoadCase({"A": np.zeros(2), "B": np.array([1.2, 0.0])})
    with pytest.raises(InputError, match="member 'beam': length 1 m does not match"):
        solve_static(structure, case)


def test_nan_loads_are_refused():
    structure, member = cantilever(3)
    with pytest.raises(InputError, match="node_loads"):
        solve_static(structure, tip_load_case(member, (0.0, float("nan"), 0.0)))


def test_fourbar_that_cannot_assemble_names_the_geometry():
    al = Material("al", 7e10, 2700.0)
    thin = Section.rectangle(0.025, 0.0016)
    from tmm_core import FourBarMechanism
    fb = FourBarMechanism(Link("crank", 0.2, thin, al), Link("coupler", 0.1, thin, al), Link("rocker", 0.12, thin, al), 0.25)
    with pytest.raises(AssemblyError, match=r"four-bar \(crank 0\.2 m, coupler 0\.1 m, rocker 0\.12 m, ground 0\.25 m\)"):
        fb.motion(np.radians(180.0))


def _strut(n):
    """Pinned-pinned strut along +x with a transverse spring (roller) at B, so an axial load at B
    compresses it. Euler load pi^2 EI / L^2."""
    L = 0.5
    member = Member.uniform("strut", "A", "B", L, n, SEC, STEEL)
    structure = Structure((Joint("A", "pinned"), Joint("B")), (member,))
    K = np.zeros((n + 1, 3, 3))
    K[-1, 1, 1] = 1e9
    return structure, member, L, K


@pytest.mark.parametrize("n", [1, 8])
def test_member_beyond_its_buckling_load_is_refused(n):
    structure, member, L, K = _strut(n)
    EI = STEEL.E_Pa * SEC.inertia_m4
    P_euler = np.pi**2 * EI / L**2

    def case(P):
        loads = np.zeros((n + 1, 3))
        loads[-1] = (-P, 0.0, 0.0)
        loads[n // 2 if n > 1 else 1, 1] += 1.0   # small imperfection load
        return LoadCase({"A": np.zeros(2), "B": np.array([L, 0.0])}, {"strut": loads}, node_stiffness={"strut": K})

    ok = solve_static(structure, case(0.9 * P_euler), beam_column=True)
    assert all(np.all(np.isfinite(r.state)) for r in ok.members.values())
    with pytest.raises(BucklingError, match="buckling load.*'strut'"):
        solve_static(structure, case(1.5 * P_euler), beam_column=True)
    with pytest.raises(BucklingError):
        solve_static(structure, case(5.0 * P_euler), beam_column=True)


def test_cantilever_at_and_beyond_euler_load():
    structure, member = cantilever(4)
    Pcr = np.pi**2 * 2.0e3 / 4.0
    with pytest.raises(SingularStructureError):
        solve_static(structure, tip_load_case(member, (-Pcr, 1.0, 0.0)), beam_column=True)
    with pytest.raises(BucklingError):
        solve_static(structure, tip_load_case(member, (-1.3 * Pcr, 1.0, 0.0)), beam_column=True)


def test_single_segment_beyond_its_own_clamped_clamped_load_counts():
    """One segment compressed past k L = 2 pi is counted through the J0 term."""
    from tmm_core.buckling import clamped_clamped_buckling_count
    kl = np.array([1.0, 2 * np.pi - 1e-6, 2 * np.pi + 1e-6, 8.98, 9.0, 4 * np.pi + 0.01, 16.0])
    assert list(clamped_clamped_buckling_count(-kl**2)) == [0, 0, 1, 1, 2, 3, 4]


def test_unconstrained_structure_is_singular():
    member = Member.uniform("bar", "A", "B", 1.0, 2, SEC, STEEL)
    structure = Structure((Joint("A", "pinned"), Joint("B")), (member,))   # free to swing about A
    with pytest.raises(SingularStructureError, match="singular"):
        solve_static(structure, LoadCase({"A": np.zeros(2), "B": np.array([1.0, 0.0])}))


def test_structure_topology_errors():
    with pytest.raises(InputError, match="unknown joint 'Q'"):
        Structure((Joint("A"), Joint("B")), (Member.uniform("bar", "A", "Q", 1.0, 2, SEC, STEEL),))
    with pytest.raises(InputError, match=r"joint 'C': nothing \(member, spring, plate\) is attached"):
        Structure((Joint("A"), Joint("B"), Joint("C")), (Member.uniform("bar", "A", "B", 1.0, 2, SEC, STEEL),))
