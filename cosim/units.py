"""The bench's one unit system: a pint registry, used at the boundary (scenario files, records,
command-line options, printouts). Inside, everything is SI.

Owns: the registry (with microstrain defined: ``ue`` in file and column names, ``µε`` in the
display), the parsing of a value written with a unit (a number is required: pint alone would read
a bare ``"rpm"`` as one rpm), and the conversion factors the scripts and tests use.
"""
from __future__ import annotations

import functools
import math
import re

import pint

UREG = pint.UnitRegistry()
UREG.define("microstrain = 1e-6 = ue = µε")
UREG.define("strain = 1 = _ = in_per_in")

_NUMBER = re.compile(r"^\s*\(*\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
STRAIN = "µε"                  # how strain is written in the display


class UnitError(ValueError):
    """A text is not a number with a unit of the expected kind."""


def has_number(text: str) -> bool:
    """True if ``text`` starts with a number (a bare unit has none)."""
    return bool(_NUMBER.match(str(text)))


def quantity(text) -> pint.Quantity:
    """``"7 in"``, ``"5.292 slug/ft^3"`` or ``"(10.3e6 psi) * 100"`` as a pint quantity; a bare unit
    or text without a number raises :class:`UnitError`. Parses are kept (a scenario's few hundred
    values are the same text in every variant of a sweep or a sampling study: pint's parser was
    most of a scenario's load time); the quantity returned is shared, so never change it in place."""
    return _parsed(str(text))


@functools.lru_cache(maxsize=4096)
def _parsed(raw: str) -> pint.Quantity:
    if not has_number(raw):
        raise UnitError(f"{raw!r} has no number")
    try:
        q = UREG.Quantity(raw.replace("^", "**"))
        q = q if isinstance(q, pint.Quantity) else UREG.Quantity(q, "")
        q = UREG.Quantity(float(q.magnitude), q.units)      # "10**400 in": an int no float can hold
    except Exception:
        raise UnitError(f"{raw!r} is not a quantity with a unit") from None
    return q


# Names the sources use that pint spells otherwise (pint's "mil" is an angle).
_ALIASES = {"mil": "thou"}


def factor(unit: str, to: str) -> float:
    """How many ``to`` one ``unit`` is (``factor("in", "m") == 0.0254``); UnitError if the unit is
    unknown or of another kind."""
    try:
        return float(UREG.Quantity(1.0, _ALIASES.get(unit, unit).replace("^", "**")).to(to).magnitude)
    except Exception:
        raise UnitError(f"{unit!r} is not a unit of {to}") from None


def to_si(text, unit: str) -> float:
    """The value of ``text`` (a number with a unit) in ``unit``."""
    q = quantity(text)
    try:
        return float(q.to(unit).magnitude)
    except pint.DimensionalityError:
        raise UnitError(f"{text!r} is not in {unit}") from None


INCH = factor("in", "m")
FOOT = factor("ft", "m")
POUND_FORCE = factor("lbf", "N")
PSI = factor("psi", "Pa")
POUND_MASS = factor("lb", "kg")
SLUG = factor("slug", "kg")
RPM = factor("rpm", "rad/s")
assert math.isclose(RPM, 2 * math.pi / 60)
