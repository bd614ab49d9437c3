"""FMI co-simulation (issue 38): the exported FMU under a real importer (FMPy) against the bench's
own master, and FMUs as the master's drive against the bench's own motor.

References are independent runs of the bench: the native master (prescribed crank, or the
scenario's [motor]) with the same engine and the same macro step; the FMU paths never compute
them. Runs are short (half a revolution) once numba's kernels are cached.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

from cosim.fmi.drive import FmuRefused                      # noqa: E402
from cosim.fmi.export import export_fmu                     # noqa: E402
from cosim.master import CoSimulation                       # noqa: E402
from cosim.scenario import ScenarioError, load              # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
GAUGE_RTOL = 1e-4          # strain difference / the native run's peak-to-peak strain
SPEED_RTOL = 1e-5          # crank speed difference / the drive speed
TORQUE_RTOL = 2e-3         # drive torque difference / the native run's largest drive torque


@pytest.fixture(scope="module")
def fe_linkage_fmu(tmp_path_factory):
    return export_fmu("crank_rocker_373rpm", tmp_path_factory.mktemp("fmu") / "linkage.fmu", engine="tmm")


def test_exported_fmu_validates_with_units(fe_linkage_fmu):
    from fmpy.validation import validate_fmu
    assert validate_fmu(str(fe_linkage_fmu)) == []
    md = fmpy.read_model_description(str(fe_linkage_fmu), validate=True)
    units = {v.name: (v.causality, v.unit) for v in md.modelVariables}
    assert units["crank_angle"] == ("input", "rad") and units["crank_speed"] == ("input", "rad/s")
    assert units["crank_acceleration"] == ("input", "rad/s2") and units["drive_torque"] == ("output", "N.m")
    sc = load("crank_rocker_373rpm")
    for g in sc.gauges:
        assert units[f"{g.name}.bending"] == ("output", "1") and units[f"{g.name}.axial"] == ("output", "1")
    assert units["internal_step"][0] == "calculatedParameter"
    assert units["coupler.length"] == ("calculatedParameter", "m")
    starts = {v.name: v.start for v in md.modelVariables}
    assert starts["coupler_mid.position"] is None                 # calculated: read after initialisation
    assert md.coSimulation.canGetAndSetFMUstate
    assert {u.name for u in md.unitDefinitions} >= {"rad", "rad/s", "N.m", "1"}


def _python(code: str, *args) -> None:
    """Run ``code`` in a Python process of its own: a PythonFMU 0.7 binary loaded into an
    interpreter corrupts it (cosim.fmi.host), so FMPy's in-process use stays out of the tests'."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, "-c", code, *map(str, args)], check=True, env=env, timeout=600)


# FMPy's simulate_fmu on an instance of our own (simulate_fmu would free its own, and a freed
# PythonFMU instance corrupts the interpreter); the process ends without tearing the FMU down.
SIMULATE = """
import os, sys, numpy as np, fmpy
path = sys.argv[1]
md = fmpy.read_model_description(path, validate=True)
unzipdir = fmpy.extract(path)
fmu = fmpy.instantiate_fmu(unzipdir, md, "CoSimulation")
res = fmpy.simulate_fmu(path, stop_time=float(sys.argv[3]), output_interval=float(sys.argv[4]),
                        input=np.load(sys.argv[2]), output=sys.argv[6:], model_description=md,
                        fmu_instance=fmu, terminate=False)
np.save(sys.argv[5], res)
os._exit(0)
"""


def test_fmu_under_fmpy_equals_native_master(fe_linkage_fmu, tmp_path):
    """simulate_fmu with the crank from an input table, at the native run's macro step."""
    sc = load("crank_rocker_373rpm")
    sim = CoSimulation(sc, ("tmm",), mode="prescribed")
    H, w = sim.macro_step_s, sc.drive.speed_rad_s
    n = 18                                                  # half a revolution of 10 deg steps
    native = sim.run(n * H)["tmm"].run
    T = n * H
    table = np.array([(0.0, 0.0, w, 0.0), (T, w * T, w, 0.0)],
                     dtype=[("time", float), ("crank_angle", float), ("crank_speed", float), ("crank_acceleration", float)])
    names = ["drive_torque"] + [f"{g}.{k}" for g in native.gauges for k in ("bending", "axial")]
    np.save(tmp_path / "input.npy", table)
    _python(SIMULATE, fe_linkage_fmu, tmp_path / "input.npy", repr(T), repr(H), tmp_path / "out.npy", *names)
    res = np.load(tmp_path / "out.npy")
    t = res["time"][1:]
    assert len(t) == n and np.allclose(t, H * np.arange(1, n + 1), rtol=0, atol=1e-12)
    at = np.searchsorted(native.t, t - 1e-12)               # the native samples at the macro-step ends
    assert np.allclose(native.t[at], t, rtol=0, atol=1e-12)
    for g, (bending, axial) in native.gauges.items():
        for k, ref in (("bending", bending), ("axial", axial)):
            assert np.max(np.abs(res[f"{g}.{k}"][1:] - ref[at])) <= GAUGE_RTOL * np.ptp(ref), (g, k)
    assert np.max(np.abs(res["drive_torque"][1:] - native.drive_torque[at])) <= \
        TORQUE_RTOL * np.max(np.abs(native.drive_torque))


STATE = """
import os, sys, fmpy
from fmpy import extract
from fmpy.fmi2 import FMU2Slave
path = sys.argv[1]
md = fmpy.read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName="a")
fmu.instantiate()
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
fmu.exitInitializationMode()
assert abs(fmu.getReal([vr["coupler.length"]])[0] - 10 * 0.0254) < 1e-12      # the FE rig's 10 in coupler
step = fmu.getReal([vr["internal_step"]])[0] * 4
fmu.doStep(0.0, step)
saved = fmu.getFMUState()
out = [vr["drive_torque"], vr["coupler_mid.bending"]]
fmu.doStep(step, step)
first = fmu.getReal(out)
fmu.doStep(2 * step, step)
moved = fmu.getReal(out)
fmu.setFMUState(saved)
fmu.doStep(step, step)
again = fmu.getReal(out)
assert again == first != moved, (first, again, moved)
os._exit(0)
"""


def test_fmu_state_save_and_restore(fe_linkage_fmu):
    """fmi2GetFMUstate / fmi2SetFMUstate: a repeated step gives the same outputs."""
    _python(STATE, fe_linkage_fmu)


def _fmu_drive(fmu, **change) -> dict:
    mapping = {"file": str(fmu), "torque": {"variable": "drive_torque", "unit": "N*m"},
               "speed": {"variable": "crank_speed", "unit": "rad/s"}, "angle": {"variable": "crank_angle", "unit": "rad"},
               "inertia": {"variable": "crank_side_inertia", "unit": "kg*m^2"}}
    mapping.update(change)
    return {"drive.mode": "motor", "drive.type": "fmu", "drive.fmu": mapping}


@pytest.mark.parametrize("scenario", ["crank_rocker_373rpm", "wang_composite_205rpm"])
def test_motor_fmu_drive_equals_native_motor(scenario, tmp_path):
    """The bench's DC motor exported as an FMU drives the master as its own motor does."""
    sc = load(scenario)
    fmu = export_fmu(sc, tmp_path / "motor.fmu", engine="motor")
    native = CoSimulation(sc.with_overrides({"drive.mode": "motor"}), ("tmm",)).run(revolutions=0.5)["tmm"]
    driven = CoSimulation(sc.with_overrides(_fmu_drive(fmu)), ("tmm",)).run(revolutions=0.5)["tmm"]
    assert native.status == driven.status == "completed", driven.error
    a, b = native.run, driven.run
    assert np.array_equal(a.t, b.t)
    assert np.max(np.abs(a.crank_speed - b.crank_speed)) <= SPEED_RTOL * abs(sc.drive.speed_rad_s)
    for g, (bending, _) in a.gauges.items():
        assert np.max(np.abs(b.gauges[g][0] - bending)) <= GAUGE_RTOL * np.ptp(bending), g
    drive = native.motor.drive_torque_Nm
    assert np.max(np.abs(drive - driven.motor.drive_torque_Nm)) <= TORQUE_RTOL * np.max(np.abs(drive))


@pytest.mark.slow
def test_motor_fmu_drives_a_torque_driven_engine_as_the_native_motor(tmp_path):
    """MuJoCo carries the drive's inertia (read from the FMU before the run) and takes the FMU's
    torque; the crank and strains equal the native motor's run (slow: two FMU processes and a
    round trip per MuJoCo sample, about 8 s)."""
    sc = load("crank_rocker_373rpm")
    fmu = export_fmu(sc, tmp_path / "motor.fmu", engine="motor")
    native = CoSimulation(sc.with_overrides({"drive.mode": "motor"}), ("mujoco",)).run(revolutions=0.5)["mujoco"]
    driven = CoSimulation(sc.with_overrides(_fmu_drive(fmu)), ("mujoco",)).run(revolutions=0.5)["mujoco"]
    assert native.status == driven.status == "completed", driven.error
    assert np.max(np.abs(native.run.crank_speed - driven.run.crank_speed)) <= SPEED_RTOL * abs(sc.drive.speed_rad_s)
    for g, (bending, _) in native.run.gauges.items():
        assert np.max(np.abs(driven.run.gauges[g][0] - bending)) <= GAUGE_RTOL * np.ptp(bending), g


def test_iterated_coupling_repeats_steps_through_the_fmu_state(tmp_path):
    """The iterated scheme restores the FMU drive's state to repeat a macro step and converges to
    the native motor's iterated run."""
    sc = load("crank_rocker_373rpm")
    fmu = export_fmu(sc, tmp_path / "motor.fmu", engine="motor")
    iterated = {"coupling.scheme": "iterated"}
    native = CoSimulation(sc.with_overrides({"drive.mode": "motor", **iterated}), ("tmm",)).run(revolutions=0.1)["tmm"]
    driven = CoSimulation(sc.with_overrides({**_fmu_drive(fmu), **iterated}), ("tmm",)).run(revolutions=0.1)["tmm"]
    assert native.status == driven.status == "completed", driven.error
    assert np.max(driven.passes) > 1                          # steps were repeated
    assert np.max(np.abs(native.run.crank_speed - driven.run.crank_speed)) <= SPEED_RTOL * abs(sc.drive.speed_rad_s)


@pytest.fixture(scope="module")
def fe_motor_fmu(tmp_path_factory):
    return export_fmu("crank_rocker_373rpm", tmp_path_factory.mktemp("fmu") / "motor.fmu", engine="motor")


def _refused(fmu_overrides) -> str:
    sc = load("crank_rocker_373rpm").with_overrides(fmu_overrides)
    with pytest.raises(FmuRefused) as info:
        CoSimulation(sc, ("tmm",)).run(revolutions=0.01)
    return str(info.value)


def test_missing_variable_refused(fe_motor_fmu):
    msg = _refused(_fmu_drive(fe_motor_fmu, torque={"variable": "shaft_torque", "unit": "N*m"}))
    assert str(fe_motor_fmu) in msg and "'shaft_torque'" in msg and "drive.fmu.torque" in msg


def test_wrong_causality_refused(fe_motor_fmu):
    msg = _refused(_fmu_drive(fe_motor_fmu, speed={"variable": "motor_speed", "unit": "rad/s"}))
    assert str(fe_motor_fmu) in msg and "'motor_speed'" in msg and "causality 'output'" in msg


def test_unit_of_another_kind_refused(fe_motor_fmu):
    msg = _refused(_fmu_drive(fe_motor_fmu, torque={"variable": "current", "unit": "N*m"}))
    assert str(fe_motor_fmu) in msg and "'current'" in msg and "is in A" in msg


def test_model_exchange_only_refused(fe_motor_fmu, tmp_path):
    bad = tmp_path / "me_only.fmu"
    with zipfile.ZipFile(fe_motor_fmu) as src, zipfile.ZipFile(bad, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb"<CoSimulation[^>]*>", b'<ModelExchange modelIdentifier="me_only"/>', data)
            dst.writestr(item, data)
    msg = _refused(_fmu_drive(bad))
    assert str(bad) in msg and "model exchange" in msg


def test_corrupt_archive_refused(tmp_path):
    bad = tmp_path / "corrupt.fmu"
    bad.write_bytes(b"PK\x03\x04 not really a zip archive")
    msg = _refused(_fmu_drive(bad))
    assert str(bad) in msg and "not an FMU" in msg


def test_mapping_errors_name_the_key(fe_motor_fmu, tmp_path):
    with pytest.raises(ScenarioError, match=r"drive\.fmu\.file"):
        load("crank_rocker_373rpm").with_overrides(_fmu_drive(tmp_path / "absent.fmu"))
    with pytest.raises(ScenarioError, match=r"drive\.fmu\.torque\.unit"):
        load("crank_rocker_373rpm").with_overrides(_fmu_drive(fe_motor_fmu, torque={"variable": "drive_torque",
                                                                                     "unit": "rad/s"}))


def test_torque_input_refused_for_a_kinematic_engine(tmp_path):
    from tmm_core import InputError
    with pytest.raises(InputError, match="clamps its crank"):
        export_fmu("crank_rocker_373rpm", tmp_path / "x.fmu", engine="tmm", drive_input="torque")


TORQUE = """
import os, sys, numpy as np, fmpy
from fmpy.fmi2 import FMU2Slave
from cosim.engines import make_engine
from cosim.engines.base import DriveInput
from cosim.scenario import load
path, J, T = sys.argv[1], 0.4, 5.0                  # drive inertia [kg m^2], held torque [N m]
sc = load("crank_rocker_373rpm")
H = 10 * sc.engine_step_s("mujoco")
engine = make_engine("mujoco")
engine.reset(sc, 0.0, sc.drive.start_angle_rad, sc.drive.speed_rad_s, drive_inertia_kg_m2=J)
native = [engine.advance((k + 1) * H, DriveInput(torque=T)) for k in range(20)]
md = fmpy.read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(path), modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName="torque")
fmu.instantiate()
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
fmu.setReal([vr["drive_inertia"]], [J])
fmu.exitInitializationMode()
out = []
for k in range(20):
    fmu.setReal([vr["drive_torque"]], [T])
    fmu.doStep(k * H, H)
    out.append(fmu.getReal([vr["crank_speed"], vr["coupler_mid.bending"]]))
out = np.array(out)
speed = np.array([o.crank_speed[-1] for o in native])
bending = np.array([o.gauges["coupler_mid"][0][-1] for o in native])
assert np.max(np.abs(out[:, 0] - speed)) <= 1e-9 * np.max(np.abs(speed)), (out[:, 0], speed)
assert np.max(np.abs(out[:, 1] - bending)) <= 1e-9 * np.ptp(bending), (out[:, 1], bending)
os._exit(0)
"""


def test_torque_input_fmu_equals_the_engine_under_the_same_torque(tmp_path):
    """A torque-driven engine's FMU (MuJoCo, --input torque) integrates the crank as the engine
    does under the same held torque and drive inertia (the engine run directly is the reference)."""
    fmu = export_fmu("crank_rocker_373rpm", tmp_path / "rigid.fmu", engine="mujoco", drive_input="torque")
    md = fmpy.read_model_description(str(fmu), validate=True)
    causality = {v.name: v.causality for v in md.modelVariables}
    assert causality["drive_torque"] == "input" and causality["crank_speed"] == "output"
    _python(TORQUE, fmu)
