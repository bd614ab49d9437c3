"""Regenerate the pinned rigid-body kinematics of tests/test_linkage.py and tests/test_ked.py
independently of the bench's closed-form modules: each linkage's loop-closure equations, solved
for its link angles by a general root finder (scipy) at crank angles around the one wanted, and
differentiated in the crank angle by five-point central differences (step 1e-3 rad; truncation
and round-off both far below the pinned digits). At constant crank speed omega the accelerations
are omega^2 times the second derivatives.

* ``table_2_1``: Shin's Table 2.1 multiloop at 75 deg, 20 rad/s: joint accelerations [in/s^2]
  beside the re-derived and the printed entries that check out, and the bodies' angular
  accelerations [rad/s^2]. The re-derived entries belong to Shin's link lengths
  (``TABLE_2_1_LENGTHS_IN``) with the ground pivots where drawn; the test's linkage takes every
  length from the four-digit drawn coordinates (``TABLE_2_1_DRAWN_IN``), which moves the
  accelerations by up to 0.1 %, so both are printed;
* ``alexander_lawrence_alpha``: the Alexander-Lawrence four-bar (crank 4, coupler 11, follower
  10.5, ground 10 in, open branch) at 400 rpm: the follower's largest angular acceleration
  [rad/s^2] over a revolution, and on the test's 2 deg grid.

A second or two::

    python -m tests.benchmarks.kinematics_references
    python -m tests.benchmarks.kinematics_references --only table_2_1 --json logs/kinematics.json
"""
from __future__ import annotations

import math
import sys

import numpy as np
from scipy.optimize import minimize_scalar, root

from tests.benchmarks.pinned_references import pinned, selection, write_json
from tests.test_linkage import TABLE_2_1_DRAWN_IN, TABLE_2_1_PRINTED_OK

#: ``--only`` name -> (test module, module-level constant) that it regenerates.
PINNED = {"table_2_1": ("tests.test_linkage", "TABLE_2_1_REDERIVED"),
          "table_2_1_alphas": ("tests.test_linkage", "TABLE_2_1_ALPHAS"),
          "alexander_lawrence_alpha": ("tests.test_ked", "AL_ROCKER_MAX_ALPHA")}
#: Shin's Table 2.1 link lengths [in] (the drawn coordinates give them to four digits); the arm
#: 5-7 stands square to the follower at the block.
TABLE_2_1_LENGTHS_IN = {"crank": 5.0, "coupler": 15.0, "follower": 12.0, "l78": 15.0, "l39": 10.0, "l910": 10.0,
                        "arm": 5.0}
STEP = 1e-3                                               # rad of crank angle
WEIGHTS_2 = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / 12  # five-point second derivative (times 1/h^2)


def unit(angle):
    """The unit vector at ``angle`` [rad]."""
    return np.array([math.cos(angle), math.sin(angle)])


class Table21:
    """Shin's Table 2.1 multiloop as loop closures in q = (coupler, follower angle [rad], the
    block's slide along the follower from 6 [in], link 8-7, link 3-9, link 10-9 angle [rad]).
    Lengths [in] from the drawn coordinates, or from ``lengths`` (TABLE_2_1_LENGTHS_IN's keys)."""

    def __init__(self, drawn: dict, lengths: dict | None = None):
        P = {k: np.array(v, float) for k, v in drawn.items()}
        P["3"] = 0.5 * (P["2"] + P["4"])                  # the coupler's mid-length
        self.P, self.crank = P, float(np.linalg.norm(P["2"] - P["1"]))
        self.Lc, self.Lf = np.linalg.norm(P["4"] - P["2"]), np.linalg.norm(P["4"] - P["6"])
        e = (P["4"] - P["6"]) / self.Lf
        P5 = 0.5 * (P["6"] + P["4"])
        self.arm = ((P["7"] - P5) @ e, (P["7"] - P5) @ np.array([-e[1], e[0]]))   # along, across the follower
        self.L78, self.L39, self.L910 = (np.linalg.norm(P[a] - P[b]) for a, b in (("7", "8"), ("9", "3"), ("9", "10")))
        angle = (lambda a, b: math.atan2(*(P[b] - P[a])[::-1]))
        self.q_drawn = np.array([angle("2", "4"), angle("6", "4"), self.Lf / 2, angle("8", "7"),
                                 angle("3", "9"), angle("10", "9")])
        self.theta_drawn = angle("1", "2")
        if lengths:
            self.crank, self.Lc, self.Lf = lengths["crank"], lengths["coupler"], lengths["follower"]
            self.L78, self.L39, self.L910 = lengths["l78"], lengths["l39"], lengths["l910"]
            self.arm = (0.0, math.copysign(lengths["arm"], self.arm[1]))

    def joints(self, q, theta) -> dict:
        """Every joint's position [in] at link coordinates ``q`` and crank angle ``theta`` [rad]."""
        P, (phc, phf, s, _, ph39, _) = self.P, q
        n = unit(phf + math.pi / 2)
        j = {"2": P["1"] + self.crank * unit(theta), "4": P["6"] + self.Lf * unit(phf),
             "5": P["6"] + 0.5 * self.Lf * unit(phf), "5b": P["6"] + s * unit(phf)}
        j["3"] = j["2"] + 0.5 * self.Lc * unit(phc)
        j["7"] = j["5b"] + self.arm[0] * unit(phf) + self.arm[1] * n
        j["9"] = j["3"] + self.L39 * unit(ph39)
        return j

    def residual(self, q, theta) -> np.ndarray:
        """The loop-closure gaps [in]: the coupler and follower meet at 4, the arm and link 8-7 at
        7, links 3-9 and 10-9 at 9."""
        P, j = self.P, self.joints(q, theta)
        return np.concatenate([j["2"] + self.Lc * unit(q[0]) - j["4"], P["8"] + self.L78 * unit(q[3]) - j["7"],
                               P["10"] + self.L910 * unit(q[5]) - j["9"]])


def solve(residual, guess, theta) -> np.ndarray:
    """The root of ``residual(q, theta)`` nearest ``guess`` (scipy's hybrid Powell method), its
    gaps below 1e-12 in (the method may stop at round-off with a warning; the gaps decide)."""
    sol = root(residual, guess, args=(theta,), method="hybr", tol=1e-14)
    if np.max(np.abs(residual(sol.x, theta))) > 1e-12:
        raise RuntimeError(f"loop closure not solved at {math.degrees(theta):.3f} deg: {sol.message}")
    return sol.x


def stencil(residual, guess, theta) -> list:
    """Solutions at crank angles theta + k STEP, k = -2..2, each started from its neighbour."""
    out, q = [], solve(residual, guess, theta)
    for k in (-2, -1, 0, 1, 2):
        out.append(solve(residual, q, theta + k * STEP))
    return out


def table_2_1(lengths: dict | None, omega: float = 20.0) -> dict:
    """Table 2.1 (``Table21(TABLE_2_1_DRAWN_IN, lengths)``) at its drawn crank angle and ``omega``
    [rad/s], alpha = 0: joint accelerations [in/s^2] and the bodies' angular accelerations [rad/s^2]."""
    mech = Table21(TABLE_2_1_DRAWN_IN, lengths)
    th = mech.theta_drawn
    qs = stencil(mech.residual, mech.q_drawn, th)
    js = [mech.joints(q, th + k * STEP) for q, k in zip(qs, (-2, -1, 0, 1, 2))]
    acc = {j: (omega**2 * WEIGHTS_2 @ np.array([x[j] for x in js]) / STEP**2).tolist() for j in js[0]}
    q2 = omega**2 * WEIGHTS_2 @ np.array(qs) / STEP**2
    alphas = {"coupler": q2[0], "follower": q2[1], "arm": q2[1], "l78": q2[3], "l39": q2[4], "l910": q2[5]}
    return {"crank_angle_deg": math.degrees(th), "joint_acceleration_in_s2": acc,
            "alpha_rad_s2": {k: float(v) for k, v in alphas.items()}}


def fourbar_residual(lengths):
    """Loop closure of a four-bar (crank, coupler, follower, ground along +x) in q = (coupler,
    follower angle) [rad]: the coupler's end meets the follower's."""
    a, b, c, d = lengths
    return lambda q, th: a * unit(th) + b * unit(q[0]) - np.array([d, 0.0]) - c * unit(q[1])


def follower_alpha(residual, guess, theta, omega) -> tuple:
    """(follower angular acceleration [rad/s^2], follower and coupler angles [rad]) at crank
    angle ``theta`` and constant ``omega`` [rad/s]."""
    qs = stencil(residual, guess, theta)
    return omega**2 * (WEIGHTS_2 @ np.array(qs))[1] / STEP**2, qs[2]


def alexander_lawrence_alpha(rpm: float = 400.0) -> dict:
    """The Alexander-Lawrence follower's largest |angular acceleration| [rad/s^2] at constant
    ``rpm`` [rev/min]: on the test's 2 deg grid and the true maximum (a 0.5 deg scan refined by a
    bounded search)."""
    res, omega = fourbar_residual((4.0, 11.0, 10.5, 10.0)), rpm * 2 * math.pi / 60
    q = np.array([math.atan2(10.29, 7.896 - 4.0), math.atan2(10.29, 7.896 - 10.0)])   # Shin Table 8.9 at 0
    scan = {}
    for deg in np.arange(0.0, 360.0, 0.5):                 # continued along the open branch
        scan[deg] = follower_alpha(res, q, math.radians(deg), omega)
        q = scan[deg][1]
    grid = max(abs(scan[d][0]) for d in np.arange(0.0, 360.0, 2.0))
    best = max(scan, key=lambda d: abs(scan[d][0]))
    peak = minimize_scalar(lambda d: -abs(follower_alpha(res, scan[best][1], math.radians(d), omega)[0]),
                           bounds=(best - 0.5, best + 0.5), method="bounded", options={"xatol": 1e-6})
    return {"max_alpha_2deg_grid": float(grid), "max_alpha": float(-peak.fun), "at_crank_deg": float(peak.x)}


def main(argv=None) -> dict:
    args, wanted = selection(argv, PINNED, "python -m tests.benchmarks.kinematics_references", __doc__)
    out = {}
    if wanted("table_2_1", "table_2_1_alphas"):
        out["table_2_1"] = r = table_2_1(TABLE_2_1_LENGTHS_IN)
        out["table_2_1_drawn_lengths"] = d = table_2_1(None)
        for label, table in (("re-derived", pinned(PINNED, "table_2_1")), ("printed", TABLE_2_1_PRINTED_OK)):
            for j, ref in table.items():
                a, b = r["joint_acceleration_in_s2"][j], d["joint_acceleration_in_s2"][j]
                print(f"Table 2.1 joint {j}: ({a[0]:.1f}, {a[1]:.1f}) in/s^2, drawn lengths ({b[0]:.1f}, {b[1]:.1f}) "
                      f"({label} {ref})")
        for body, ref in pinned(PINNED, "table_2_1_alphas").items():
            print(f"Table 2.1 {body}: alpha {r['alpha_rad_s2'][body]:.3f} rad/s^2, drawn lengths "
                  f"{d['alpha_rad_s2'][body]:.3f} (pinned {ref})")
    if wanted("alexander_lawrence_alpha"):
        out["alexander_lawrence_alpha"] = r = alexander_lawrence_alpha()
        print(f"Alexander-Lawrence at 400 rpm: largest follower |alpha| {r['max_alpha']:.1f} rad/s^2 at crank "
              f"{r['at_crank_deg']:.2f} deg, {r['max_alpha_2deg_grid']:.1f} on a 2 deg grid "
              f"(pinned {pinned(PINNED, 'alexander_lawrence_alpha')})")
    write_json(args.json, out)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
