"""Scenario variants through one typed API: key paths of the scenario file set to new values.

``Scenario.with_overrides({"drive.speed": "300 rpm", "links.coupler.damping.ratio": "3 %"})``
sets each key path in the scenario's TOML tree (a copy) and loads it again, so every value is
validated by the loader with its usual messages (which name the key). A path names tables with
dots and list items with ``[i]`` (``links.coupler.point_masses[0].weight``). A ``{value = ...,
assumption = ...}`` table keeps its provenance and takes the new value. A path whose parent table
does not exist is refused, naming the path, except a top-level table or one table below it
(``solver.exudyn``), which the loader then validates; a new key in an existing table is allowed
(the loader refuses it if the table does not know it). The value ``None`` removes the key, so
its default applies again (``{"motor": None}`` drops the motor table).

A value may also be typed: a number with its unit (``UREG.Quantity(241.0, "rpm")``, see :func:`prescribed_speed`), which the loader converts
without writing and parsing text (a sweep's speeds are floats: a float turned into "241.0 rpm"
and read back is a round trip through pint's parser).

Owns: key-path editing of scenario trees. Used by the scenario types' ``with_overrides``, sweeps,
uncertainty bands, the rigs of the scripts and tests; nothing else edits ``Scenario.raw``.
Boundaries: it knows no scenario type and no loader (it sits below both: imports run one way).
"""
from __future__ import annotations

import copy
import re

from .units import UREG

_INDEX = re.compile(r"^(\w+)\[(\d+)\]$")


class OverrideError(ValueError):
    """A key path does not lead anywhere in the scenario file."""


def set_key(raw: dict, key: str, value, *, write: bool = True) -> None:
    """Set the key path ``key`` (``a.b[0].c``) in the TOML tree ``raw`` in place; ``write=False``
    only checks that it could be set (``raw`` unchanged: no copy of the tree to validate a key)."""
    node = raw
    parts = key.split(".")
    for i, part in enumerate(parts):
        m = _INDEX.match(part)
        last = i == len(parts) - 1
        if m:
            name, j = m.group(1), int(m.group(2))
            if not isinstance(node, dict) or not isinstance(node.get(name), list) or j >= len(node[name]):
                raise OverrideError(f"key '{key}': there is no list item {part}")
            if last:
                if write:
                    node[name][j] = value
                return
            node = node[name][j]
            continue
        if not isinstance(node, dict):
            raise OverrideError(f"key '{key}': '{'.'.join(parts[:i])}' is not a table")
        if last:
            if not write:
                return
            if value is None:
                node.pop(part, None)
            elif isinstance(node.get(part), dict) and "value" in node[part]:
                node[part] = dict(node[part], value=value)
            else:
                node[part] = value
            return
        if part not in node:
            if i <= 1:
                # A table the file does not have yet (e.g. solver.exudyn).
                if not write:
                    node = {}
                    continue
                node[part] = {}
            else:
                raise OverrideError(f"key '{key}': there is no table '{'.'.join(parts[:i + 1])}'")
        node = node[part]


def prescribed_speed(rpm: float) -> dict:
    """The overrides of a prescribed-speed run at ``rpm`` [rev/min], typed (a number with its
    unit, no text): what a sweep point and its cost estimate set."""
    return {"drive.speed": UREG.Quantity(float(rpm), "rpm"), "drive.mode": "prescribed"}


def apply_overrides(raw: dict, overrides: dict) -> dict:
    """A copy of ``raw`` with every ``{key path: value}`` of ``overrides`` set."""
    data = copy.deepcopy(raw)
    for key, value in overrides.items():
        set_key(data, str(key), value)
    return data
