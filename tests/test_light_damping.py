"""Light damping (issue 34, docs/light_damping.md): the representative case of the default
selection. The FE rig at 241 rpm with 0.5 % damping, where the rocker stays well below its Euler
load and turns 2 deg: there the transfer-matrix model's error at light damping is its time step
alone. Its periodic orbit at 0.25 deg against exudyn's steady state (an independent engine:
geometrically exact cables, 16 elements / 0.2 deg, from rest until the last two revolutions agree
to 4e-11; `python -m studies.light_damping exudyn --cases 241:0.5`, kept in
studies/light_damping_exudyn.json). At the rig's 0.5 deg the coupler's negative peak is 5.3 % off
(the integrator's period error, which the resonance 1.6 % from the 20th harmonic amplifies)."""
from pathlib import Path

import numpy as np
import pytest

from cosim.scenario import load
from studies import light_damping
from tmm_core.periodic import periodic_steady_state

#: exudyn's steady peaks [microstrain]: bending max, min, axial max, min.
EXUDYN_241RPM_HALF_PERCENT = {"coupler_mid": (304.67, -173.82, 33.31, -34.97),
                              "rocker_mid": (240.45, -515.31, 40.86, -24.72)}


@pytest.fixture(scope="module")
def orbit():
    sc = load("crank_rocker_241rpm").with_overrides({"links.coupler.damping.ratio": "0.5 %",
                                                    "links.rocker.damping.ratio": "0.5 %",
                                                    "solver.tmm.step": "0.25 deg"})
    return periodic_steady_state(sc.time_domain(), sc.drive.speed_rad_s, step_s=sc.engine_step_s("tmm"))


def test_the_orbit_is_stable(orbit):
    """Measured: largest multiplier 0.54 (the rocker mode's decay at 0.5 %: exp(-zeta omega T))."""
    assert abs(orbit.multipliers[0]) < 1


def test_every_peak_within_2_percent_of_exudyn(orbit):
    """Measured: bending within 0.6 %, axial within 0.4 %."""
    for gauge, expected in EXUDYN_241RPM_HALF_PERCENT.items():
        bending, axial = orbit.gauges[gauge]
        peaks = 1e6 * np.array([bending.max(), bending.min(), axial.max(), axial.min()])
        np.testing.assert_allclose(peaks, expected, rtol=0.02, err_msg=gauge)


def test_the_amplitude_table_of_the_docs_is_the_studys(capsys):
    """docs/light_damping.md, "The same speed at smaller amplitude": every row the study prints
    from its cached runs (studies/light_damping_tmm.json; no engine runs here) is in the doc."""
    light_damping.main(["amplitude"])
    rows = capsys.readouterr().out.strip().splitlines()
    doc = (Path(__file__).resolve().parents[1] / "docs" / "light_damping.md").read_text(encoding="utf-8")
    assert len(rows) == len(light_damping.CRANKS_IN)
    for row in rows:
        assert row in doc, row


#: Issue 34's grid on the FE rig (light_damping.CASES: the cases with an exudyn reference) and the
#: TMM step of each: 0.25 deg, except 373 rpm at 0.5 %, whose march reaches the stable orbit from
#: its quasi-static start at 0.125 deg (as the shipped variant runs; at 0.25 deg it stays in the
#: irregular response that coexists with the orbit, docs/light_damping.md).
GRID = [(rpm, zeta, 0.125 if (rpm, zeta) == (373, 0.5) else 0.25) for rpm, zeta in light_damping.CASES]


@pytest.mark.slow
@pytest.mark.parametrize("rpm, zeta, step_deg", GRID, ids=[f"{r}rpm-{z:g}pct" for r, z, _ in GRID])
def test_the_march_settles_within_2_percent_of_exudyn(rpm, zeta, step_deg):
    """The TMM with its default (co-rotational) segments, marched from its quasi-static start
    (light_damping.march, 40 revolutions, 60 at 0.5 %), settles, and every bending and axial peak
    of both gauges lies within 2 % of exudyn's finest steady run of the case (an independent,
    geometrically exact engine; studies/light_damping_exudyn.json: 32 elements / 0.1 deg where
    run, else 16 / 0.2 deg). Measured (docs/light_damping.md): within 1.7 % at 0.25 deg, and
    within 0.8 % at 373 rpm, 0.5 %, 0.125 deg."""
    spec = {**light_damping.VARIANTS["corotational"][1], "step_deg": step_deg}
    result = light_damping.march(rpm, zeta, spec, revolutions=60 if zeta < 1 else 40)
    assert result["change"] < 1e-3, (result["change"], result["trend"])
    reference, _ = light_damping.reference(rpm, zeta)
    errors = light_damping.errors(result["last"], reference, 4)
    assert max(abs(e) for peaks in errors.values() for e in peaks) < 2.0, errors
