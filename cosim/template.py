"""``cosim new NAME``: a commented scenario file to start a rig of one's own.

Without ``--like`` it writes a complete four-bar (an aluminium crank-rocker) in which every key
is explained and every value the user must replace is marked as an assumption; with ``--like
SCENARIO`` it copies that scenario's file (comments kept) and the base files it ``extends``,
with the new name. Either way the written file is loaded before this returns, so a template that
does not load is an error here, not at the user's first run. An existing file is never
overwritten.

The scenario format itself is described in docs/scenario-format.md, the one home of the
schema, which the written file points to.

Owns: ``cosim new``: the commented template or a copy with its bases. Boundaries: writes only the
files it names.
"""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

from .files import create_new
from .scenario import SCENARIO_DIR, ScenarioError, load

NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")

TEMPLATE = '''\
# {name}: a four-bar linkage scenario for the flexlink bench (written by `cosim new {name}`).
# Run it:      cosim run {path}            (add --engines tmm --revolutions 2 for a quick look)
# Check it:    python -c "from cosim.scenario import load; print(load('{path}').assumptions)"
#
# Every physical value carries its unit ("7 in", "70 GPa", "2700 kg/m^3", "300 rpm") and is
# converted to SI on load. A value you have from a source is written
#     key = {{ value = "7 in", source = "drawing 12-34" }}
# and one you had to assume
#     key = {{ value = "2 %", assumption = "why this value" }}
# so that every run lists what was assumed. The values below are an aluminium crank-rocker;
# replace each `assumption` with your rig's data. Full key list: docs/scenario-format.md.

[scenario]
name = "{name}"
description = "My four-bar rig (replace with a one-line description; `cosim list` shows it)"
sources = ["where the values come from (drawings, a thesis, measurements)"]
# rig = "fe_crank_rocker"    # records of this rig (scenarios/records or `cosim run --records DIR`)
#                            # at the drive speed are scored against every engine

[linkage]
type = "four-bar"            # or "slider-crank" / "linkage" / "structure" (docs/scenario-format.md)
ground = {{ value = "11 in", assumption = "distance between the crank and rocker pivots; replace" }}
branch = "open"              # assembly of the coupler and rocker: "open" or "crossed"

[materials.aluminium]
E = {{ value = "70 GPa", assumption = "handbook value for aluminium; replace with your material's modulus" }}
density = {{ value = "2700 kg/m^3", assumption = "handbook value for aluminium" }}

[sections.strip]             # a rectangular strip: width out of the plane, depth in the plane of motion
width = {{ value = "1 in", assumption = "replace with your links' section" }}
depth = {{ value = "0.125 in", assumption = "in-plane thickness: it sets the bending stiffness" }}

[links.crank]
length = {{ value = "7 in", assumption = "replace" }}
section = "strip"
material = "aluminium"
rigid = true                 # a crank far stiffer than the other links (its mass still counts)

[links.coupler]
length = {{ value = "10 in", assumption = "replace" }}
section = "strip"
material = "aluminium"
damping = {{ ratio = "2 %", frequency = "79 Hz", assumption = "modal damping at the first mode; typical of a bolted aluminium linkage" }}
# point_masses = [ {{ position = "0 in", mass = "30 g", label = "bearing at the crank pin" }} ]

[links.rocker]
length = {{ value = "12 in", assumption = "replace" }}
section = "strip"
material = "aluminium"
damping = {{ ratio = "2 %", frequency = "79 Hz", assumption = "as for the coupler" }}

[drive]
mode = "prescribed"          # constant crank speed; "motor" needs a [motor] table (see below)
speed = {{ value = "200 rpm", assumption = "replace with your test speed" }}
rotation = "ccw"             # seen with the ground line to the right of the crank pivot
start_angle = "0 deg"

# Strain gauges: strain is reported on the link's local +y face ("top") at `position` from the
# link's start joint (crank pivot -> pin, crank pin -> rocker pin, rocker pivot -> pin).
[gauges.coupler_mid]
link = "coupler"
position = "5 in"
face = "top"

[gauges.rocker_mid]
link = "rocker"
position = "6 in"
face = "top"

# Discretisation of each engine; a step is a time ("1e-4 s") or a crank angle ("0.5 deg").
[solver.tmm]
segments = 8
integrator = "generalized_alpha"
step = "0.5 deg"

[solver.exudyn]
elements = 16
step = "0.2 deg"

[solver.mujoco]
step = "0.2 deg"

[coupling]
macro_step = "2 deg"         # engines exchange data every macro step: a whole multiple of every step above

[output]
max_revolutions = 30         # runs until every engine is steady (last two revolutions within 0.5 %)
# revolutions = 4            # a fixed length instead
# engines = ["tmm", "mujoco"]

# A motor-driven rig (`cosim run {path} --drive motor`): a permanent-magnet DC motor written
# from its rating (constants the rating does not give are derived and listed as assumptions).
# [motor]
# rated_power = "0.5 hp"
# rated_speed = "1750 rpm"
# rated_voltage = "90 V"
# gear_ratio = 4
# flywheels = [ {{ diameter = "12 in", thickness = "2 in", density = "7850 kg/m^3" }} ]
# controller = {{ bandwidth = "2 Hz" }}
'''


def _check_name(name: str) -> None:
    if not NAME.match(name or ""):
        raise ScenarioError(f"scenario name {name!r}: use letters, digits, '_' and '-', starting with a letter "
                            "(it becomes the file name and the run folder's name)")


def _with_name(text: str, name: str, path: Path) -> str:
    """``text`` with ``[scenario] name`` set to ``name`` (replaced in place, comments kept)."""
    lines = text.splitlines(keepends=True)
    header = next((i for i, ln in enumerate(lines) if ln.strip() == "[scenario]"), None)
    if header is None:
        return text.rstrip("\n") + f'\n\n[scenario]\nname = "{name}"\n'
    for i in range(header + 1, len(lines)):
        stripped = lines[i].strip()
        if stripped.startswith("["):
            break
        if re.match(r"^name\s*=", stripped):
            lines[i] = f'name = "{name}"\n'
            return "".join(lines)
    lines.insert(header + 1, f'name = "{name}"\n')
    return "".join(lines)


def _bases(path: Path) -> list:
    """The chain of files ``path`` extends (relative to each file), nearest first."""
    out, seen = [], {path.resolve()}
    current = path
    while True:
        base = tomllib.loads(current.read_text(encoding="utf-8")).get("extends")
        if not isinstance(base, str):
            return out
        nxt = current.parent / base
        nxt = nxt if nxt.suffix else nxt.with_suffix(".toml")
        if nxt.resolve() in seen or not nxt.exists():
            return out                   # load() below reports the loop or the missing file
        seen.add(nxt.resolve())
        out.append(nxt)
        current = nxt


def new_scenario(name: str, like: str | None = None, out: Path | None = None) -> tuple:
    """Write ``<out>/<name>.toml`` (``out`` default: the current directory); returns
    ``(path, copied_base_files)``. Raises ScenarioError naming the file when it exists, or when
    ``like`` is not a scenario."""
    _check_name(name)
    folder = Path(out) if out is not None else Path.cwd()
    path = folder / f"{name}.toml"
    if path.exists() or path.is_symlink():
        raise ScenarioError(f"{path}: already exists{' (a symlink)' if path.is_symlink() else ''}; choose another "
                            "name or --out, or delete the file")
    copied = []
    if like is None:
        text = TEMPLATE.format(name=name, path=path)
    else:
        source = Path(like)
        source = source if source.suffix else SCENARIO_DIR / f"{like}.toml"
        load(source if source.exists() else like)            # names the available scenarios if not found
        text = f"# {name}: copied from {source} by `cosim new {name} --like {like}`.\n" + \
            _with_name(source.read_text(encoding="utf-8"), name, path)
        # The bases travel with the copy, at the same relative place, so `extends` still works.
        for base in _bases(source):
            try:
                rel = base.resolve().relative_to(source.parent.resolve())
            except ValueError:
                raise ScenarioError(f"{source}: extends {base}, outside its folder; copy it by hand") from None
            target = folder / rel
            if target.is_symlink():
                raise ScenarioError(f"{target}: is a symlink; the copy's base is never written through one (use "
                                    "another --out)")
            if target.exists():
                if target.read_bytes() != base.read_bytes():
                    raise ScenarioError(f"{target}: already exists and differs from {base}; the copy would extend "
                                        "the wrong base (use another --out)")
                continue
            target.parent.mkdir(parents=True, exist_ok=True)
            create_new(target, base.read_bytes())
            copied.append(target)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        create_new(path, text)
    except FileExistsError:                 # created since the check above
        raise ScenarioError(f"{path}: already exists; choose another name or --out, or delete the file") from None
    try:
        load(path)
    except ScenarioError:
        path.unlink()                    # never leave a file that does not load
        raise
    return path, copied
