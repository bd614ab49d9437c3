"""The bench's side of ``cosim synthesize``: a synthesized crank-rocker
(:mod:`tmm_core.synthesis`, FE thesis Ch. III) written as a scenario of the bench, and its result
as one record in the unit of the ground length.

Owns: the synthesized linkage as a scenario file and as the command's result record. Boundaries:
the mathematics is tmm_core.synthesis; the options are read and the result printed by cosim.commands.synthesize,
its table written by cosim.report.
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

import tomli_w
from tmm_core import InputError
from tmm_core.synthesis import FourBarSynthesis

from .files import write_atomic
from .scenario import from_dict, load
from .units import UREG, quantity

SOURCE = "cosim synthesize, case {case} (FE thesis Ch. III)"
#: The angles of a synthesis reported in degrees (module docstring of tmm_core.synthesis).
ANGLES = ("oscillation", "phi2", "phi4", "mu1", "mu2", "mu4", "theta1", "theta3")


def _scaled(value, ratio: float):
    """A position along a link written with a unit (string or {value = ...}), times ``ratio``."""
    if isinstance(value, dict):
        return value | {"value": _scaled(value["value"], ratio)}
    q = quantity(value) * ratio if isinstance(value, str) else None
    return value if q is None else f"{q.magnitude:.6g} {q.units:~}"     # a bare number is left to the loader


def write_scenario(result: FourBarSynthesis, path: Path, like: str, unit) -> Path:
    """Write scenario ``like`` with the link lengths and ground of ``result`` [m], written in ``unit``,
    to ``path``, validated first. Gauges and point masses keep their fraction of the link length (a
    mid-span gauge stays mid-span); ``scenario.rig`` is dropped, its records are of another linkage."""
    base = load(like)
    if base.raw.get("linkage", {}).get("type") != "four-bar":
        raise InputError(f"option --like = {like!r}: is not a four-bar scenario")
    data, source = copy.deepcopy(base.raw), SOURCE.format(case=result.case)

    def length(metres):
        return {"value": f"{(metres * UREG.m).to(unit).magnitude:.6g} {unit:~}", "source": source}

    data["linkage"]["ground"] = length(result.ground)
    for link in base.mechanism.links():
        table, ratio = data["links"][link.name], getattr(result, link.name) / link.length_m
        table["length"] = length(getattr(result, link.name))
        for item in table.get("point_masses", []) + [g for g in data.get("gauges", {}).values()
                                                    if g.get("link") == link.name]:
            item["position"] = _scaled(item["position"], ratio)
    data["scenario"] = {k: v for k, v in data.get("scenario", {}).items() if k != "rig"} | {
        "name": path.stem, "sources": list(base.sources) + [source],
        "description": f"synthesized crank-rocker (case {result.case}) on the sections and drive of {base.name}"}
    from_dict(data, str(path), default_name=path.stem)
    write_atomic(path, f"# `cosim synthesize --case {result.case}` on scenario {base.name}: link lengths, ground, "
                       f"gauge and point-mass positions differ\n" + tomli_w.dumps(data))
    return path


def result_record(result: FourBarSynthesis, unit, written: Path | None = None) -> dict:
    """The command's result: lengths in ``unit`` (a pint unit, named under the key ``unit``), angles
    in degrees (``<name>_deg``), the limit positions of :func:`tmm_core.fourbar_limits.limit_positions` in degrees,
    the residual of the thesis equations and the scenario written (None if none)."""
    return ({"case": result.case, "unit": f"{unit:~}", "grashof": result.limits["grashof"]}
            | {k: float((getattr(result, k) * UREG.m).to(unit).magnitude)
               for k in ("crank", "coupler", "rocker", "ground")}
            | {f"{k}_deg": math.degrees(getattr(result, k)) for k in ANGLES}
            | {k.replace("_rad", "_deg"): math.degrees(v) if k.endswith("_rad") else v
               for k, v in result.limits.items() if k != "grashof"}
            | {"residual": result.residual, "scenario": str(written) if written else None})
