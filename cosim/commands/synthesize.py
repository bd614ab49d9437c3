"""``cosim synthesize``: the link lengths of a rigid crank-rocker from its rocker swing and limit
positions (:mod:`tmm_core.synthesis`), values read with their units.

Owns: the synthesize command's use of its options. Boundaries: the mathematics is
:mod:`tmm_core.synthesis`, the scenario file :mod:`cosim.synthesis`.
"""
from __future__ import annotations

import json
import math

from tmm_core.synthesis import synthesize_case_one, synthesize_case_two

from ..defaults import SYNTHESIS_LIKE
from ..report import synthesis_table
from ..synthesis import result_record, write_scenario
from ..units import UREG, quantity


def main(args) -> int:
    """``cosim synthesize``: its options read (values with units), the crank-rocker synthesized
    (:mod:`tmm_core.synthesis`), printed (table or one JSON object), optionally written as a scenario."""
    ground = _quantity("--ground", args.ground, "length")
    oscillation = float(_quantity("--oscillation", args.oscillation, "angle").to("rad").magnitude)
    inputs = _case_inputs(args)
    result = (synthesize_case_one if args.case == "I" else synthesize_case_two)(
        float(ground.to("m").magnitude), oscillation, **inputs)
    written = (write_scenario(result, args.scenario_out, args.like or SYNTHESIS_LIKE, ground.units)
               if args.scenario_out is not None else None)
    record = result_record(result, ground.units, written)
    print(json.dumps(record) if args.json else synthesis_table(record))
    return 0


def _case_inputs(args) -> dict:
    """The case's angle options [rad]; an option of the other case is refused rather than ignored."""
    own = {"I": ("rocker_limit", "min_transmission"), "II": ("crank_limits",)}[args.case]
    for name in ("rocker_limit", "min_transmission", "crank_limits"):
        value, option = getattr(args, name), "--" + name.replace("_", "-")
        if (value is not None) != (name in own):
            raise ValueError(f"option {option} is required for case {args.case}" if value is None else
                             f"option {option} = {value!r}: is not used by case {args.case}")
    if args.like is not None and args.scenario_out is None:
        raise ValueError(f"option --like = {args.like!r}: is only used with --scenario-out")
    if args.overwrite and args.scenario_out is None:
        raise ValueError("option --overwrite: is only used with --scenario-out")
    out = args.scenario_out
    if out is not None and (out.exists() or out.is_symlink()) and not (args.overwrite and out.is_file()):
        raise ValueError(f"option --scenario-out = {str(out)!r}: already exists" +
                         ("; give another path, or --overwrite to replace it" if not out.is_dir() else
                          " and is a folder; give a file path"))
    given = ([(n, "--" + n.replace("_", "-"), getattr(args, n)) for n in own] if args.case == "I" else
             [(n, f"--crank-limits ({n.upper()})", t) for n, t in zip(("theta1", "theta3"), args.crank_limits)])
    return {name: float(_quantity(option, text, "angle").to("rad").magnitude) for name, option, text in given}


def _quantity(option: str, text: str, kind: str):
    """``text`` as a pint quantity of kind 'length' or 'angle'; a bare number is refused."""
    example = {"length": "in", "angle": "deg"}[kind]
    try:
        q = quantity(text)
    except Exception:
        raise ValueError(f"option {option} = {text!r}: not a quantity with a unit, e.g. '11 {example}'") from None
    if not hasattr(q, "units") or q.units == UREG.dimensionless:      # "81 %" has a unit: refused below
        raise ValueError(f"option {option} = {text!r}: has no unit; write it with one, e.g. '{text} {example}'")
    target = UREG.meter if kind == "length" else UREG.radian     # pint counts angles as dimensionless
    if UREG.get_root_units(q.units)[1] != target or not math.isfinite(q.magnitude):
        raise ValueError(f"option {option} = {text!r}: is not a finite {kind}")
    return q
