"""Every pinned number has a script that regenerates it (issue 36), and the scripts and the tests
cannot drift apart silently: each ``tests/benchmarks/*_references.py`` maps its ``--only`` names
to the test constants it regenerates (``PINNED``) and reads the pinned values through that map,
so a renamed or removed constant fails here, in the default run, instead of when someone starts
an hour of refined runs. The scripts themselves are not run here (docs/validation.md, "Pinned
numbers and the scripts that regenerate them").
"""
import importlib
import math
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = sorted(p.stem for p in (ROOT / "tests" / "benchmarks").glob("*_references.py"))


def _numbers(value):
    """Every number inside a pinned value (nested tuples, lists, dicts)."""
    if isinstance(value, dict):
        return [x for v in value.values() for x in _numbers(v)]
    if isinstance(value, (list, tuple)):
        return [x for v in value for x in _numbers(v)]
    return [value] if isinstance(value, (int, float)) and not isinstance(value, bool) else []


def test_the_scripts_are_found():
    assert {"pinned_references", "frequency_references", "kinematics_references"} <= set(SCRIPTS)


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_pinned_name_maps_to_an_existing_numeric_constant(script):
    module = importlib.import_module(f"tests.benchmarks.{script}")
    assert module.PINNED, script
    for name, (test_module, constant) in module.PINNED.items():
        assert test_module.startswith("tests.test_"), (name, test_module)
        value = module.pinned(module.PINNED, name)
        numbers = _numbers(value)
        assert numbers and all(math.isfinite(x) for x in numbers), (name, constant, value)


def test_every_test_that_names_a_script_is_named_back_by_it():
    """A test module whose comments send the reader to ``python -m tests.benchmarks.X`` holds at
    least one constant X's ``PINNED`` names."""
    for path in sorted((ROOT / "tests").glob("test_*.py")):
        for script in set(re.findall(r"python -m tests\.benchmarks\.(\w+_references)", path.read_text("utf-8"))):
            assert script in SCRIPTS, (path.name, script)
            named = {module for module, _ in importlib.import_module(f"tests.benchmarks.{script}").PINNED.values()}
            assert f"tests.{path.stem}" in named, (path.name, script)
