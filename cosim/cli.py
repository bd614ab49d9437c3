"""Command line of the bench: ``cosim``.

Only ``--version`` and ``list`` exist so far; ``run``, ``sweep`` and ``compare`` follow with
the scenario description and the engines.
"""
from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

from . import __version__

SCENARIO_DIR = Path(__file__).resolve().parent.parent / "scenarios"


def _first_doc_line(path: Path) -> str:
    try:
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    except (OSError, SyntaxError) as exc:
        return f"(unreadable: {exc})"
    return doc.strip().splitlines()[0] if doc.strip() else ""


def list_scenarios(directory: Path = SCENARIO_DIR) -> list[tuple[str, str]]:
    """(name, one-line description) of every runnable scenario script."""
    out = []
    for path in sorted(directory.glob("*.py")):
        if path.name.startswith("_"):
            continue
        out.append((path.stem, _first_doc_line(path)))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="cosim",
        description="Flexible-linkage co-simulation bench (transfer-matrix solver with exudyn and MuJoCo references).",
        epilog="Example: cosim list")
    parser.add_argument("--version", action="version", version=f"cosim {__version__}")
    sub = parser.add_subparsers(dest="command")
    sub.add_parser("list", help="show the scenarios and their one-line descriptions")
    args = parser.parse_args(argv)
    if args.command == "list":
        rows = list_scenarios()
        width = max((len(n) for n, _ in rows), default=0)
        for name, desc in rows:
            print(f"{name:<{width}}  {desc}")
        return 0
    parser.print_help()
    return 0


if __name__ == "__main__":
    sys.exit(main())
