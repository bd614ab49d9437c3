"""Issue 17: property-based fuzz (Hypothesis) of the scenario loader and of short TMM runs.

Each example takes a shipped scenario's TOML tree and mutates it: a value replaced by a random
number, string, unit string, list or table, a key deleted, or a quantity scaled by 10^k. The
property: loading ends in a clean project error (``ScenarioError`` / ``InputError``, both
``tmm_core.TMMError``) or a valid scenario, never any other exception. The run fuzz marches a
quarter revolution of a mutated four-bar, slider-crank or six-bar on 2 segments per link: a clean
error (``TMMError``, ``EngineError``, a cost refusal) or a finite result.

The default selection takes a small budget (a few seconds); ``-m slow`` the large one."""
import copy
import math
import re

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings, strategies as st  # noqa: E402

from cosim.scenario import from_dict, load, scenario_names  # noqa: E402
from tmm_core import TMMError  # noqa: E402

_RAW = {}


def raw(name: str) -> dict:
    if name not in _RAW:
        _RAW[name] = load(name).raw
    return copy.deepcopy(_RAW[name])


def paths(tree, prefix=()):
    """Every key path of a TOML tree (tables, list items and leaves)."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for k, v in items:
        yield prefix + (k,)
        yield from paths(v, prefix + (k,))


UNITS = ["in", "m", "mm", "deg", "rad", "rpm", "Hz", "s", "ms", "kg", "lb", "lbf", "N", "psi", "Pa", "GPa",
         "slug/ft^3", "kg/m^3", "%", "N*m", "kg*m^2", "V", "ohm", "A", "hp", "W", "1/s", "m/s^2", "furlong", "degC"]
NUMBERS = st.one_of(st.integers(-10 ** 20, 10 ** 20), st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0, -1, 1, 1e-300, 1e308, 10 ** 400]))
TEXT = st.one_of(st.text(max_size=12), st.sampled_from(["", " ", "abc", "top", "crank", "../x", "/etc/passwd",
                                                          "1/0 in", "(1 in", "10**400 in", "nan in", "3,5 in"]))
UNIT_TEXT = st.builds(lambda x, u: f"{x} {u}", NUMBERS, st.sampled_from(UNITS)) | st.sampled_from(UNITS)
LEAF = st.one_of(NUMBERS, TEXT, UNIT_TEXT, st.booleans())
VALUE = st.one_of(LEAF, st.lists(LEAF, max_size=3), st.dictionaries(st.sampled_from(["value", "x", "ratio", "link"]),
                                                                    LEAF, max_size=2))
_QUANTITY = re.compile(r"^\s*([-+]?[0-9.]+(?:[eE][-+]?\d+)?)\s+(.+)$")


def scaled(value, k: int):
    """A quantity (``"7 in"``, a number, or a ``{value = ...}`` table's value) times 10^k."""
    if isinstance(value, dict) and "value" in value:
        return dict(value, value=scaled(value["value"], k))
    if isinstance(value, bool):
        return value
    if isinstance(value, (int, float)):
        try:
            return value * 10.0 ** k
        except OverflowError:           # an int beyond float range (an earlier mutation's): as it is
            return value
    m = _QUANTITY.match(value) if isinstance(value, str) else None
    return f"{float(m.group(1)) * 10.0 ** k:g} {m.group(2)}" if m else value


@st.composite
def mutated(draw, names=None):
    """``(name, tree, what was done)``: a shipped scenario's tree with one to three mutations."""
    name = draw(st.sampled_from(names or scenario_names()))
    tree = raw(name)
    done = []
    for _ in range(draw(st.integers(1, 3))):
        every = list(paths(tree))
        if not every:
            break
        path = every[draw(st.integers(0, len(every) - 1))]
        node = tree
        for p in path[:-1]:
            node = node[p]
        op = draw(st.sampled_from(["replace", "delete", "scale", "scale"]))
        if op == "delete" and isinstance(node, dict):
            node.pop(path[-1])
        elif op == "scale":
            node[path[-1]] = scaled(node[path[-1]], draw(st.integers(-40, 40)))
        else:
            node[path[-1]] = draw(VALUE)
        done.append((op, path))
    return name, tree, done


def load_or_refuse(tree):
    """The property: a scenario or a clean project error; anything else propagates (a bug)."""
    try:
        return from_dict(tree, "fuzz.toml")
    except TMMError:
        return None


SMALL = settings(max_examples=50, deadline=None, database=None, suppress_health_check=list(HealthCheck))
LARGE = settings(max_examples=2500, deadline=None, database=None, suppress_health_check=list(HealthCheck))


@SMALL
@given(mutated())
def test_a_mutated_scenario_loads_or_is_refused_cleanly(case):
    load_or_refuse(case[1])


@pytest.mark.slow
@LARGE
@given(mutated())
def test_a_mutated_scenario_loads_or_is_refused_cleanly_large_budget(case):
    load_or_refuse(case[1])


# -- short TMM runs of mutated mechanisms ---------------------------------------------------------------
RUNNABLE = ["crank_rocker_373rpm", "slider_crank_600rpm", "watt_sixbar_600rpm"]


@st.composite
def scaled_mechanism(draw):
    """A runnable scenario with one or two quantities of its mechanism scaled by 10^k (k small,
    so that most variants still assemble and run)."""
    name = draw(st.sampled_from(RUNNABLE))
    tree = raw(name)
    leaves = [p for p in paths(tree) if p[0] in ("linkage", "materials", "sections", "links", "joints", "drive")
              and (not isinstance(_get(tree, p), (dict, list)) or "value" in _get(tree, p))]
    for _ in range(draw(st.integers(1, 2))):
        path = leaves[draw(st.integers(0, len(leaves) - 1))]
        node = _get(tree, path[:-1])
        node[path[-1]] = scaled(node[path[-1]], draw(st.integers(-3, 3)))
    tree.setdefault("solver", {}).setdefault("tmm", {})["segments"] = 2
    for link in tree.get("links", {}).values():
        if isinstance(link, dict):
            link.pop("segments", None)
            link.pop("point_masses", None)       # masses sit on the shipped mesh's nodes, not on 2 segments
    return name, tree


def _get(tree, path):
    for p in path:
        tree = tree[p]
    return tree


def march_or_refuse(tree):
    from cosim.engines import EngineError, make_engine
    from cosim.master import run_prescribed
    from cosim.run_guards import check_cost
    try:
        sc = from_dict(tree, "fuzz.toml")
    except TMMError:
        return None
    duration = 0.25 * 2 * math.pi / abs(sc.drive.speed_rad_s)
    try:
        check_cost(sc, ["tmm"], duration, sc.engine_step_s("tmm"), max_hours=20 / 3600)   # at most ~20 s
    except ValueError:
        return None                                  # refused before it starts, with its estimate
    try:
        run = run_prescribed(make_engine("tmm"), sc, revolutions=0.25)
    except (TMMError, EngineError):
        return None
    assert np.all(np.isfinite(run.drive_torque)) and len(run.t) > 0
    return run


@settings(max_examples=6, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(scaled_mechanism())
def test_a_short_run_of_a_mutated_mechanism_ends_cleanly(case):
    march_or_refuse(case[1])


@pytest.mark.slow
@settings(max_examples=300, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(scaled_mechanism())
def test_a_short_run_of_a_mutated_mechanism_ends_cleanly_large_budget(case):
    march_or_refuse(case[1])
