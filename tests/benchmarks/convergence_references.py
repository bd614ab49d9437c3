"""Regenerate the bench's own converged answers pinned in tests by their convergence study: the
transfer-matrix model repeated with finer meshes and steps until the pinned digits stop moving.

* ``alexander_lawrence_s_alt``: Alexander-Lawrence at Shin's 41.87 rad/s, quasi-static with the
  beam-column iteration (scenarios/alexander_lawrence_shin.py's ``quasi_static_case``): the
  follower-midpoint Soderberg stress amplitude [psi] over segments per link x kinematics step
  [deg]; tests/test_example_and_cli.py pins the 16 x 1 deg answer.

A few seconds::

    python -m tests.benchmarks.convergence_references
"""
from __future__ import annotations

import sys

from scenarios.alexander_lawrence_shin import quasi_static_case
from tests.benchmarks.pinned_references import pinned, selection, write_json

#: ``--only`` name -> (test module, module-level constant) that it regenerates.
PINNED = {"alexander_lawrence_s_alt": ("tests.test_example_and_cli", "AL_CONVERGED_S_ALT_PSI")}
SETTINGS = ((4, 4.0), (8, 2.0), (16, 1.0), (32, 1.0), (16, 0.5), (32, 0.5))   # (segments per link, step [deg])


def alexander_lawrence_s_alt() -> dict:
    """The follower-midpoint stress amplitude [psi] and largest distortion [in] per setting."""
    return {f"{n} x {step} deg": quasi_static_case(n, step) for n, step in SETTINGS}


def main(argv=None) -> dict:
    args, wanted = selection(argv, PINNED, "python -m tests.benchmarks.convergence_references", __doc__)
    out = {}
    if wanted("alexander_lawrence_s_alt"):
        out["alexander_lawrence_s_alt"] = study = alexander_lawrence_s_alt()
        for setting, r in study.items():
            print(f"Alexander-Lawrence quasi-static, {setting}: S_alt {r['S_alt_psi']:.1f} psi, "
                  f"distortion {r['max_distortion_in']:.4f} in")
        print(f"(pinned {pinned(PINNED, 'alexander_lawrence_s_alt')} psi at 16 x 1.0 deg)")
    write_json(args.json, out)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
