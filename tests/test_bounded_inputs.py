"""Issue 32, "every input bounded": values whose arithmetic is unbounded, files that are not
regular files or never end, and nesting that would exhaust the recursion limit are refused
before they are used, each with a message naming the file (and the key)."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.files import FileRefused, read_bounded
from cosim.records import RecordError, load_record
from cosim.report import load_summary
from cosim.scenario import SCENARIO_DIR, ScenarioError, load

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize("value", ["9**9**9 in", "9^9^9 in", "2 in**100000000", "1 in ** (9**9)",
                                   "1\x07 in", "1" + "0" * 300 + " in"])
def test_unbounded_unit_arithmetic_is_refused_at_once(value):
    """Run in a child with a time limit: before the guard, "9**9**9 in" never returned."""
    code = ("from cosim.scenario import load, ScenarioError\n"
            "try:\n"
            f"    load('crank_rocker_373rpm').with_overrides({{'links.coupler.length': {value!r}}})\n"
            "except ScenarioError as exc:\n"
            "    print(exc)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert "key 'links.coupler.length'" in out.stdout, out.stdout + out.stderr


def _scenario_copy(tmp_path, name="rig"):
    text = (SCENARIO_DIR / "crank_rocker_373rpm.toml").read_text(encoding="utf-8")
    path = tmp_path / f"{name}.toml"
    path.write_text(text.replace('extends = "base/', f'extends = "{SCENARIO_DIR}/base/'), encoding="utf-8")
    return path


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_a_scenario_linked_to_a_device_is_refused(tmp_path):
    link = tmp_path / "zero.toml"
    link.symlink_to("/dev/zero")
    with pytest.raises(ScenarioError, match="zero.toml.*character device"):
        load(link)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    with pytest.raises(ScenarioError, match="FIFO"):
        load(fifo)
    with pytest.raises(FileRefused, match="FIFO"):
        read_bounded(fifo, 10)


def test_a_file_over_the_limit_is_refused(tmp_path):
    big = tmp_path / "big.txt"
    big.write_bytes(b"x" * 101)
    with pytest.raises(FileRefused, match="101 bytes"):
        read_bounded(big, 100)
    assert read_bounded(big, 101) == b"x" * 101


def test_deep_toml_nesting_is_a_scenario_error(tmp_path):
    deep = tmp_path / "deep.toml"
    deep.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(ScenarioError, match="deep.toml.*nested too deeply"):
        load(deep)


def test_a_long_extends_chain_is_refused(tmp_path):
    _scenario_copy(tmp_path, "f0")
    for i in range(1, 40):
        (tmp_path / f"f{i}.toml").write_text(f'extends = "f{i - 1}"\n', encoding="utf-8")
    with pytest.raises(ScenarioError, match="key 'extends' chains more than"):
        load(tmp_path / "f39.toml")
    assert load(tmp_path / "f3.toml").name     # a short chain still loads


def test_a_utf8_byte_order_mark_is_read(tmp_path):
    path = _scenario_copy(tmp_path)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert load(path).drive.speed_rpm == pytest.approx(373.0)


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="needs /dev/zero")
def test_records_and_summaries_linked_to_a_device_are_refused(tmp_path):
    (tmp_path / "summary.json").symlink_to("/dev/zero")
    with pytest.raises(ValueError, match="summary.json.*character device"):
        load_summary(tmp_path)
    (tmp_path / "rec.toml").symlink_to("/dev/zero")
    with pytest.raises(RecordError, match="rec.toml.*character device"):
        load_record(tmp_path / "rec.toml")


def test_a_number_too_small_for_its_arithmetic_is_refused_naming_the_key():
    """A gear ratio of 1e-300 is positive, but its square underflows and the motor's controller
    design divided by zero (found by tests/test_fuzz_scenarios.py): plain numbers, like
    quantities, are 0 or at least 1e-30 in magnitude."""
    with pytest.raises(ScenarioError) as refused:
        load("crank_rocker_373rpm_damping_0p5pct").with_overrides({"motor.gear_ratio": 1e-300})
    assert "motor.gear_ratio" in str(refused.value) and "1e-30" in str(refused.value), str(refused.value)
