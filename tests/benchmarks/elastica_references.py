"""Regenerate the pinned tip displacements of Shin's §8.5 stepped beam (tests/test_statics.py)
independently of the transfer-matrix solver: the planar rod equations of the beam integrated
along its length (scipy DOP853, rtol 1e-12) and shot from the pin to the tip (the pin's rotation
and reaction found so that the tip carries exactly the tip load and no moment).

The beam (the test's ``_stepped_beam``): 500 mm of steel, E = 207 GPa, pinned at x = 0; 5 x 5 mm
up to 250 mm, then 2.5 x 2.5 mm; vertical sliding springs of 2 N/mm at 150 and 400 mm (their
force stays vertical, -k times the point's vertical displacement); 15 N down at the tip and the
self-weight 76.5e-6 N/mm^3 (dead loads per undeformed length). Inextensible (the axial strain,
below 1e-5, moves the tip by less than the pinned digits).

* ``stepped_beam_elastica``: the exact elastica's tip displacement (x, y) [mm] and rotation [deg];
* ``stepped_beam_linear``: small-deflection theory (x = s, rotation = slope, moments about the
  undeformed axis): the tip's deflection [mm].

Under a second::

    python -m tests.benchmarks.elastica_references
"""
from __future__ import annotations

import math
import sys

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from tests.benchmarks.pinned_references import pinned, selection, write_json

#: ``--only`` name -> (test module, module-level constant) that it regenerates.
PINNED = {"stepped_beam_elastica": ("tests.test_statics", "STEPPED_BEAM_ELASTICA_TIP_MM"),
          "stepped_beam_linear": ("tests.test_statics", "STEPPED_BEAM_LINEAR_TIP_MM")}
E, WEIGHT = 207e9, 76.5e3          # Pa, N/m^3
LENGTH, STEP_AT = 0.5, 0.25        # m: the beam, where its section steps down
SPRINGS = {0.15: 2000.0, 0.40: 2000.0}       # position [m]: stiffness [N/m]
TIP_LOAD = 15.0                    # N, downward


def side(s: float) -> float:
    """The square section's side [m] at arc length ``s`` [m]."""
    return 5e-3 if s < STEP_AT else 2.5e-3


def rod(linear: bool):
    """d/ds of the state (x, y, rotation, force (nx, ny) and moment m that the beam beyond s
    exerts on the beam before it) [m, rad, N, N m], between springs and section steps."""
    def f(s, z):
        x, y, th, nx, ny, m = z
        b = side(s)
        tangent = (1.0, th) if linear else (math.cos(th), math.sin(th))
        moment_arm = ny if linear else tangent[0] * ny - tangent[1] * nx
        return [tangent[0], tangent[1], m / (E * b**4 / 12), 0.0, WEIGHT * b * b, -moment_arm]
    return f


def shoot(unknowns, linear: bool) -> np.ndarray:
    """The state at the tip from the pin's rotation [rad] and the force (nx, ny) [N] there."""
    th0, nx0, ny0 = unknowns
    z = np.array([0.0, 0.0, th0, nx0, ny0, 0.0])
    knots = sorted({0.0, STEP_AT, LENGTH, *SPRINGS})
    for a, b in zip(knots[:-1], knots[1:]):
        if a in SPRINGS:
            z[4] += SPRINGS[a] * z[1]            # the spring's force -k y no longer lies beyond s
        z = solve_ivp(rod(linear), (a, b), z, method="DOP853", rtol=1e-12, atol=1e-15).y[:, -1]
    return z


def tip_state(linear: bool) -> dict:
    """The tip's displacement (x, y) [mm] and rotation [deg] with the tip load exactly carried."""
    gap = (lambda u: (shoot(u, linear)[3:] - [0.0, -TIP_LOAD, 0.0]) * [1.0, 1.0, 10.0])
    u, info, ok, msg = fsolve(gap, [-0.1, 0.0, -10.0], xtol=1e-13, full_output=True)
    if ok != 1:
        raise RuntimeError(f"the shooting did not converge: {msg}")
    z = shoot(u, linear)
    return {"tip_mm": [1e3 * (z[0] - LENGTH), 1e3 * z[1]], "tip_rotation_deg": math.degrees(z[2]),
            "pin_reaction_N": [-u[1], -u[2]], "tip_residual": float(np.max(np.abs(gap(u))))}


def main(argv=None) -> dict:
    args, wanted = selection(argv, PINNED, "python -m tests.benchmarks.elastica_references", __doc__)
    out = {}
    if wanted("stepped_beam_elastica"):
        out["stepped_beam_elastica"] = r = tip_state(linear=False)
        print(f"stepped beam, elastica: tip ({r['tip_mm'][0]:.4f}, {r['tip_mm'][1]:.4f}) mm, rotation "
              f"{r['tip_rotation_deg']:.3f} deg (pinned {pinned(PINNED, 'stepped_beam_elastica')} mm)")
    if wanted("stepped_beam_linear"):
        out["stepped_beam_linear"] = r = tip_state(linear=True)
        print(f"stepped beam, small deflection: tip {r['tip_mm'][1]:.3f} mm "
              f"(pinned {pinned(PINNED, 'stepped_beam_linear')} mm)")
    write_json(args.json, out)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
