"""The ``[joints.*]`` positions, joint references, and the ``[springs.*]`` and ``[loads.*]``
tables shared by the structure and linkage scenario formats: read once, with the loader's error
messages (file, key, value).

Owns: joint positions and references, springs and load vectors. Where a
load lands on a member's nodes is each format's own business (a structure places it by joint or
along a link, a linkage at the flexible link ending at the joint).
"""
from __future__ import annotations

import numpy as np

from tmm_core.structure import Spring


def joint_position(r, d: dict, key: str) -> np.ndarray:
    """A joint's ``position = ["x", "y"]`` [m] (a list of two lengths)."""
    pos = r.unwrap(d["position"], f"{key}.position")
    if not isinstance(pos, list) or len(pos) != 2:
        raise r.fail(f"{key}.position", "must be a list of two coordinates", pos)
    return np.array([r.quantity(p, f"{key}.position[{i}]", "m") for i, p in enumerate(pos)])


def joint_checker(r, names):
    """``joint_ref(value, key)``: the joint named by ``value``, refused naming the key unless it
    is one of ``names``."""
    names = set(names)

    def joint_ref(value, key):
        value = r.unwrap(value, key)
        if not isinstance(value, str) or value not in names:
            raise r.fail(key, f"unknown joint (joints: {', '.join(sorted(names))})", value)
        return value
    return joint_ref


def read_springs(r, top: dict, joint_ref) -> list:
    """Springs between two different joints: ``between``, ``stiffness`` [N/m], ``free_length`` [m].
    ``joint_ref(value, key)`` checks a joint name."""
    springs = []
    for name, d in r.names(top.get("springs", {}), "springs").items():
        key = f"springs.{name}"
        d = r.table(d, key, {"between", "stiffness", "free_length"}, {"between", "stiffness", "free_length"})
        ends = r.unwrap(d["between"], f"{key}.between")
        if not isinstance(ends, list) or len(ends) != 2:
            raise r.fail(f"{key}.between", "must list two joints", ends)
        a, b = joint_ref(ends[0], f"{key}.between"), joint_ref(ends[1], f"{key}.between")
        if a == b:
            raise r.fail(f"{key}.between", "a spring needs two different joints", ends)
        springs.append(Spring(name, a, b, r.quantity(d["stiffness"], f"{key}.stiffness", "N/m", positive=True),
                              r.quantity(d["free_length"], f"{key}.free_length", "m", nonnegative=True)))
    return springs


def read_loads(r, top: dict, keys: set, required: set = frozenset()):
    """Each ``[loads.<name>]`` as ``(key, table, vector)``: the table checked against ``keys``
    (``required`` among them) and the vector ``[Fx N, Fy N, M N m]`` (force default zero, a list
    of two components; moment default zero)."""
    for name, d in r.names(top.get("loads", {}), "loads").items():
        key = f"loads.{name}"
        d = r.table(d, key, keys, required)
        f = r.unwrap(d.get("force", ["0 N", "0 N"]), f"{key}.force")
        if not isinstance(f, list) or len(f) != 2:
            raise r.fail(f"{key}.force", "must be a list of two force components", f)
        vec = np.array([r.quantity(f[0], f"{key}.force[0]", "N"), r.quantity(f[1], f"{key}.force[1]", "N"),
                        r.quantity(d.get("moment", "0 N*m"), f"{key}.moment", "N*m")])
        yield key, d, vec
