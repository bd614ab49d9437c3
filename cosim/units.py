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



def _registry() -> pint.UnitRegistry:
    """pint's registry with its parsed definitions cached on disk (pint's own cache, in the user's
    cache folder, as numba caches its kernels beside the sources): parsing the definitions file
    took 0.3-0.4 s of every command's start-up, reading the cache takes 0.04 s. A cache that
    cannot be written or read (a read-only home) is skipped."""
    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except Exception:          # pint's cache is an optimisation; any failure of it is not the user's
        return pint.UnitRegistry()


UREG = _registry()
UREG.define("microstrain = 1e-6 = ue = µε")
UREG.define("strain = 1 = _ = in_per_in")
UREG.define("@alias turn = rev")       # "10 rev/s", the spelling the messages suggest

_NUMBER = re.compile(r"^\s*\(*\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
STRAIN = "µε"                  # how strain is written in the display


class UnitError(ValueError):
    """A text is not a number with a unit of the expected kind."""


class AngleUnitError(UnitError):
    """A value's angle units do not fit the quantity meant (its message says how to write it).

    pint takes the radian as 1, so without this check ``"7 in/rad"`` would be read as 7 inches,
    ``"95 rpm/rad"`` as 95 rpm, ``"1 deg deg"`` as 0.0175 deg and ``"10 Hz"`` as 10 rad/s."""


def has_number(text: str) -> bool:
    """True if ``text`` starts with a number (a bare unit has none)."""
    return bool(_NUMBER.match(str(text)))


def quantity(text) -> pint.Quantity:
    """``"7 in"``, ``"5.292 slug/ft^3"`` or ``"(10.3e6 psi) * 100"`` as a pint quantity; a bare unit
    or text without a number raises :class:`UnitError`. Parses are kept (a scenario's few hundred
    values are the same text in every variant of a sweep or a sampling study: pint's parser was
    most of a scenario's load time); the quantity returned is shared, so never change it in place."""
    return _parsed(str(text))


#: The longest text read as a quantity ("(10.3e6 psi) * 100" is 18 characters).
MAX_TEXT = 200
#: The largest exponent a quantity may carry (units go to the 4th power: m**4 of an area moment).
MAX_EXPONENT = 12
# An exponent: '**' then a plain number, optionally signed or in parentheses; group 2 is a
# second '**' right after it (pint evaluates "9**9**9" as 9**(9**9) on Python integers: a hang).
_PLAIN = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_EXPONENT = re.compile(rf"\*\*\s*(\(\s*{_PLAIN}\s*\)|{_PLAIN})(\s*\*\*)?")


def _bounded(expr: str) -> None:
    """Refuse, before pint evaluates it, a text whose arithmetic is unbounded: too long, a
    control character, or an exponent that is not a small plain number (pint computes powers of
    integers exactly, so a 12-byte "9**9**9 in" would run until memory is gone)."""
    if len(expr) > MAX_TEXT:
        raise UnitError(f"{expr[:40]!r}... is {len(expr)} characters; a quantity has at most {MAX_TEXT}")
    if any(ord(c) < 32 or ord(c) == 127 for c in expr):
        raise UnitError(f"{expr!r} contains a control character")
    at = expr.find("**")
    while at >= 0:
        m = _EXPONENT.match(expr, at)
        if m is None or m.group(2) or abs(float(m.group(1).strip("() ") or "nan")) > MAX_EXPONENT:
            raise UnitError(f"{expr!r}: an exponent must be a plain number of at most {MAX_EXPONENT} "
                            "(no powers of powers)")
        at = expr.find("**", m.end(1))


@functools.lru_cache(maxsize=4096)
def _parsed(raw: str) -> pint.Quantity:
    if not has_number(raw):
        raise UnitError(f"{raw!r} has no number")
    _bounded(raw.replace("^", "**"))
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
    """The value of ``text`` (a number with a unit) in ``unit``, angles counted as in
    :func:`magnitude_in`."""
    q = quantity(text)
    try:
        return magnitude_in(q, unit)
    except pint.DimensionalityError:
        raise UnitError(f"{text!r} is not in {unit}") from None
    except AngleUnitError as exc:
        raise AngleUnitError(f"{text!r} {exc}") from None


def angle_power(q) -> float:
    """The power of the angle in a quantity's units (``rpm``: 1, ``Hz``: 0, ``N*m/rad``: -1,
    ``deg**2``: 2), counted on its root units, where every angle unit becomes the radian."""
    return dict(q.to_root_units().unit_items()).get("radian", 0)


def _is_hertz(q) -> bool:
    """Whether a quantity is written in hertz (Hz, kHz, ...): a cycle frequency, not a rate."""
    items = list(q.unit_items())
    return bool(items) and all(name.endswith("hertz") and power == 1 for name, power in items)


def magnitude_in(q: pint.Quantity, unit: str) -> float:
    """The magnitude of ``q`` in ``unit`` with the angle kept as a dimension of its own.

    The conventions (every angular rate of the bench alike):

    * a frequency in hertz where an angular rate is meant counts revolutions per unit time:
      ``10 Hz`` is 600 rpm (62.83 rad/s), not 10 rad/s;
    * an angular rate where a frequency in hertz is meant counts revolutions too: ``600 rpm`` is
      10 Hz;
    * a coefficient per radian (``N*m/rad``, ``V*s/rad``) may be written without the radian, as
      in SI (``N*m``), since there the radian is 1 by definition;
    * every other mismatch of angles is refused (:class:`AngleUnitError`): an angle where a length
      is meant (``in/rad``), a rate without an angle where a speed is meant (``1/s``, ``rpm/rad``),
      two angles where one is meant (``deg deg``).

    Raises ``pint.DimensionalityError`` when the dimensions (angles aside) differ."""
    target = UREG.Quantity(1.0, unit)
    value = float(q.to(unit).magnitude)
    have, want = angle_power(q), angle_power(target)
    if have == want:
        return value
    if want - have == 1 and _is_hertz(q):
        return float((q * UREG.turn).to(unit).magnitude)
    if have - want == 1 and _is_hertz(target):
        return float((q / UREG.turn).to(unit).magnitude)
    if have == 0 and want < 0:
        return value
    if want == 1 and have == 0:
        raise AngleUnitError("is a rate without an angle where an angular speed is meant: write it as "
                             "'600 rpm', '62.8 rad/s', '10 rev/s' or '10 Hz' (hertz are read as revolutions per "
                             "second)")
    raise AngleUnitError(f"carries angle^{have:g} where {unit} carries angle^{want:g}: an angle unit is "
                         "missing or one too many (radians are dimensionless to the unit parser, so it would "
                         "be read silently as something else)")


INCH = factor("in", "m")
FOOT = factor("ft", "m")
POUND_FORCE = factor("lbf", "N")
PSI = factor("psi", "Pa")
POUND_MASS = factor("lb", "kg")
SLUG = factor("slug", "kg")
RPM = factor("rpm", "rad/s")
assert math.isclose(RPM, 2 * math.pi / 60)
