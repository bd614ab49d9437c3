"""Scenario files on disk: where the shipped ones are, their names, and a file read with the bases
it extends (TOML merged, nothing validated: :func:`cosim.scenario.load` builds and checks it).

Owns: ``SCENARIO_DIR``, :func:`scenario_names`, :func:`read_with_bases` and the limits on what is
read. Boundaries: it imports no numerics and no unit registry, so ``cosim list`` stays fast; its
errors (:class:`ScenarioFileError`) become :class:`cosim.scenario_types.ScenarioError` in the loader.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from .files import SCENARIO_BYTES, FileRefused, read_text_bounded

SCENARIO_DIR = Path(__file__).resolve().parent.parent / "scenarios"


class ScenarioFileError(ValueError):
    """A scenario file cannot be read as one (missing, not TOML, a bad ``extends``); the message
    names the file and the key."""


#: The largest scenario file read (a scenario is a few kB; a wrong path must not be read whole).
MAX_FILE_BYTES = SCENARIO_BYTES
#: The longest chain of ``extends`` followed (a rig uses one or two bases).
MAX_EXTENDS_DEPTH = 16


def read_with_bases(path: Path, chain: tuple = (), root: Path | None = None) -> dict:
    """Parse a scenario file; ``extends = "base/name"`` (relative to the file, ``.toml`` optional)
    merges the file over its base (tables merge key by key, other values replace), so a rig is
    written once and each test speed only states what differs.

    Where a base may be: a ``.toml`` file named by a relative path, inside the folder of the
    scenario that was loaded or its parent (``extends = "../base/rig"`` from a folder of speed
    files), or a shipped base or scenario (under ``scenarios/``, also by its absolute path). Any
    other absolute path, or one that climbs higher, is refused; a file that is not a scenario is
    never echoed in a message."""
    if path.resolve() in chain:
        raise ScenarioFileError(f"scenario '{path}': key 'extends' loops back ({' -> '.join(str(p) for p in chain)})")
    if len(chain) >= MAX_EXTENDS_DEPTH:
        raise ScenarioFileError(f"scenario '{chain[0]}': key 'extends' chains more than {MAX_EXTENDS_DEPTH} files "
                            f"(at {path}); a rig needs a base or two")
    if root is None:
        root = path.resolve().parent.parent
    try:
        data = tomllib.loads(read_text_bounded(path, MAX_FILE_BYTES))
    except FileRefused as exc:
        raise ScenarioFileError(f"scenario '{path}': {exc}; not a scenario file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioFileError(f"scenario '{path}': not valid TOML: {exc}") from None
    except RecursionError:
        raise ScenarioFileError(f"scenario '{path}': tables or arrays nested too deeply to be a scenario") from None
    except UnicodeDecodeError:
        raise ScenarioFileError(f"scenario '{path}': not a UTF-8 text file (save it as UTF-8; UTF-16 and other "
                            "encodings are not read)") from None
    except OSError as exc:
        raise ScenarioFileError(f"scenario '{path}': cannot be read ({exc.strerror})") from None
    base = data.pop("extends", None)
    if base is None:
        return data
    if not isinstance(base, str) or not base.strip():
        raise ScenarioFileError(f"scenario '{path}': key 'extends' = {base!r}: must be the name of a base file")
    rel = Path(base)
    shipped_file = rel.is_absolute() and rel.resolve().is_relative_to(SCENARIO_DIR)    # a shipped scenario's path
    if (rel.is_absolute() and not shipped_file) or rel.suffix not in ("", ".toml"):
        raise ScenarioFileError(f"scenario '{path}': key 'extends' = {base!r}: must name a .toml scenario by a path "
                            "relative to this file (e.g. 'base/rig' or '../base/rig'), or a shipped base")
    base_path = (path.parent / rel).with_suffix(".toml")
    shipped = (SCENARIO_DIR / rel).with_suffix(".toml")
    if not base_path.exists() and shipped.exists() and ".." not in rel.parts:
        base_path = shipped
    resolved_base = base_path.resolve()
    if not (resolved_base.is_relative_to(root) or resolved_base.is_relative_to(SCENARIO_DIR)):
        raise ScenarioFileError(f"scenario '{path}': key 'extends' = {base!r}: leads outside {root} (a base must lie "
                            "in the scenario's folder or the one above it, or be a shipped base)")
    if not base_path.is_file():
        raise ScenarioFileError(f"scenario '{path}': key 'extends' = {base!r}: no file {base_path}")
    return _merge(read_with_bases(base_path, (*chain, path.resolve()), root), data)


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def scenario_names() -> list:
    """Names of the runnable scenario files in ``scenarios/`` (bases under ``scenarios/base`` excluded)."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))
