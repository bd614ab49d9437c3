"""The FMU's overhead per macro step against the native engine (issue 38; docs/fmi.md).

Exports the transfer-matrix engine on a scenario as an FMU, then advances the native engine
(``Engine.advance`` with the same prescribed crank the FMU builds from its inputs) and the FMU
(FMPy: set the three crank inputs, ``fmi2DoStep``, get the drive torque and every strain) over
the same macro steps, and prints the wall time per macro step of each and their difference.
A PythonFMU binary corrupts the interpreter it is loaded into (cosim.fmi.host), so this script
is a process of its own, loading one instance, and ends without tearing it down:

    python -m tests.benchmarks.fmu_overhead crank_rocker_373rpm --degrees 2
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from pathlib import Path


def native_seconds(scenario, H: float, steps: int, rounds: int) -> float:
    """Least wall time of ``steps`` macro steps of ``H`` [s] of the native tmm engine over
    ``rounds`` successive rounds after a first one (a round of a revolution meets the
    configurations the engine keeps from the first)."""
    from cosim.engines import make_engine
    from cosim.engines.base import DriveInput
    from cosim.interface_signals import crank_extrapolation
    engine = make_engine("tmm")
    w = scenario.drive.speed_rad_s
    engine.reset(scenario, 0.0, 0.0, w)
    times = []
    for r in range(rounds + 1):
        tic = time.perf_counter()
        for k in range(r * steps, (r + 1) * steps):
            t = k * H
            engine.advance(t + H, DriveInput(prescribed=crank_extrapolation(t, w * t, w, 0.0)))
        times.append(time.perf_counter() - tic)
    return min(times[1:])


def fmu_seconds(path: Path, scenario, H: float, steps: int, rounds: int) -> float:
    """The same through the FMU (inputs set, step, outputs read)."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(path)),
                    modelIdentifier=md.coSimulation.modelIdentifier, instanceName="overhead")
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    w = scenario.drive.speed_rad_s
    inputs = [vr["crank_angle"], vr["crank_speed"], vr["crank_acceleration"]]
    times = []
    for r in range(rounds + 1):
        tic = time.perf_counter()
        for k in range(r * steps, (r + 1) * steps):
            t = k * H
            fmu.setReal(inputs, [w * t, w, 0.0])
            fmu.doStep(currentCommunicationPoint=t, communicationStepSize=H)
            fmu.getReal(outputs)
        times.append(time.perf_counter() - tic)
    return min(times[1:])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="crank_rocker_373rpm")
    p.add_argument("--revolutions", type=int, default=3, help="revolutions timed after a first one (least kept)")
    p.add_argument("--degrees", type=float, default=2.0, help="macro step as crank angle [deg]")
    args = p.parse_args(argv)
    from cosim.fmi.export import export_fmu
    from cosim.scenario import load
    sc = load(args.scenario)
    h = sc.engine_step_s("tmm")
    H = h * max(1, round(math.radians(args.degrees) / abs(sc.drive.speed_rad_s) / h))
    steps = round(2 * math.pi / abs(sc.drive.speed_rad_s) / H)           # a revolution's macro steps
    with tempfile.TemporaryDirectory() as tmp:
        path = export_fmu(sc, Path(tmp) / "linkage.fmu")
        native = native_seconds(sc, H, steps, args.revolutions)
        fmu = fmu_seconds(path, sc, H, steps, args.revolutions)
    per = 1e3 / steps
    print(f"{args.scenario}: macro step {H * 1e3:.4g} ms ({math.degrees(H * abs(sc.drive.speed_rad_s)):.3g} deg, "
          f"{round(H / h)} engine steps), {steps} steps a revolution, least of {args.revolutions} revolutions")
    print(f"native engine {native * per:.3f} ms/step, FMU {fmu * per:.3f} ms/step, "
          f"overhead {(fmu - native) * per:.3f} ms/step ({(fmu / native - 1) * 100:.1f} %)")
    sys.stdout.flush()
    os._exit(0)          # PythonFMU's instance is not torn down (cosim.fmi.host)


if __name__ == "__main__":
    sys.exit(main())
