"""Shared test helpers: small structures and the equilibrium assertion."""
from __future__ import annotations

import numpy as np

from tmm_core import Joint, LoadCase, Material, Member, Section, Structure, external_resultant


def assert_equilibrium(solution, load_scale, length_scale, deformed=False, rtol=1e-9, moment_rtol=None):
    """Reactions balance the applied loads: the external resultant vanishes.

    Forces to ``rtol`` of ``load_scale`` [N]; moments to ``moment_rtol`` (default ``rtol``) of
    ``load_scale * length_scale`` [N m]."""
    res = external_resultant(solution, deformed=deformed)
    moment_rtol = rtol if moment_rtol is None else moment_rtol
    assert np.all(np.abs(res[..., :2]) <= rtol * load_scale), f"force residual {res[..., :2]}"
    assert np.all(np.abs(res[..., 2]) <= moment_rtol * load_scale * length_scale), f"moment residual {res[..., 2]}"


def cantilever(n_segments, length=1.0, EI=2.0e3, EA=4.0e8, depth=0.01):
    """Clamped-free straight cantilever along +x with given stiffnesses (SI)."""
    E = 2.0e11
    section = Section(EA / E, EI / E, depth)
    material = Material("steel", E)
    member = Member.uniform("beam", "A", "B", length, n_segments, section, material, start_connection="rigid")
    structure = Structure((Joint("A", "clamped"), Joint("B")), (member,))
    return structure, member


def tip_load_case(member, force, length=1.0):
    """Load case with ``force`` = (Fx, Fy, Mz) at the tip of a cantilever along +x."""
    loads = np.zeros((member.n_segments + 1, 3))
    loads[-1] = force
    return LoadCase({"A": np.zeros(2), "B": np.array([length, 0.0])}, {member.name: loads})
