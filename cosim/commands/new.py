"""``cosim new``: a commented scenario file to start a rig of one's own.

Owns: the new command's use of its options. Boundaries: the template is :mod:`cosim.template`.
"""
from __future__ import annotations

from ..template import new_scenario


def main(args) -> int:
    """``cosim new NAME [--like SCENARIO] [--out DIR]``: writes NAME.toml (never over a file)."""
    path, bases = new_scenario(args.name, args.like, args.out)
    print(f"wrote {path}" + (f" and its base file(s) {', '.join(str(b) for b in bases)}" if bases else ""))
    print(f"run it with: cosim run {path}")
    return 0
