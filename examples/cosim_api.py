"""The bench from a script, with the names ``cosim`` exports: load a scenario, run it through the
transfer-matrix engine, read the results as a pandas DataFrame, and vary the scenario.

Run it with ``python examples/cosim_api.py``; ``tests/test_examples.py`` runs it too. The run is
the FE thesis's crank-rocker at 373 rpm (``scenarios/crank_rocker_373rpm.toml``), prescribed
speed, until the TMM is steady (about a second); its folder is the one ``cosim run
crank_rocker_373rpm --engines tmm --no-record`` writes.
"""
import sys
import tempfile
from pathlib import Path

import cosim

GAUGE = "coupler_mid"


def main(out: Path | None = None) -> dict:
    """Run the rig and return a few of its numbers: the coupler's peak bending strain [microstrain]
    from the summary and from the traces, the crank speed [rad/s] and a variant's speed [rpm]."""
    sc = cosim.load("crank_rocker_373rpm")
    data = cosim.run(sc, engines=["tmm"], out=out, figures=False)
    peak_summary = data.summary["engines"]["tmm"]["gauges"][GAUGE]["bending_max_ue"]
    last = data.last_revolution("tmm")                    # the long DataFrame's last revolution
    bending = last[(last["gauge"] == GAUGE) & (last["quantity"] == "bending")]["value"]
    speed = data.traces[data.traces["quantity"] == "crank_speed"]["value"]
    slower = sc.with_overrides({"drive.speed": "241 rpm"})
    return {"folder": str(data.folder), "status": data.summary["status"],
            "peak_summary_ue": float(peak_summary), "peak_traces_ue": float(bending.max()),
            "crank_speed_rad_s": float(speed.median()), "variant_rpm": slower.drive.speed_rpm}


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        for key, value in main(Path(tmp) / "run").items():
            print(f"{key}: {value}")
    sys.exit(0)
