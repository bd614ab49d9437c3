"""The documents keep their word (issue 36, "the front door"):

* the README stays a front door: at most 300 lines and no dated measurement (history goes to
  CHANGELOG.md);
* every code block of README.md and docs/*.md runs: ```python blocks are executed (from a
  temporary working directory in which a short run has written ``logs/<scenario>-<timestamp>``),
  ```toml blocks are parsed, every line of a ```bash block is checked: ``cosim`` commands parse
  with the command line's own parser, ``python -m`` modules and ``python`` scripts exist, ``make``
  targets are in the Makefile; ```text blocks are drawings and are not run;
* docs/benchmarks.md's tables are the ones bench_table.py prints from the latest results file;
* no document, test, scenario, script or module names a repository file that does not exist,
  and every relative link of a document resolves (the research notes the bench was built from are
  not in the repository: what it relies on of them is written in docs/validation.md).
"""
from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCUMENTS = [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
KINDS = ("python", "toml", "bash", "text")


def _blocks(kind: str):
    for doc in DOCUMENTS:
        for n, m in enumerate(FENCE.finditer(doc.read_text(encoding="utf-8"))):
            if m.group(1) == kind:
                yield pytest.param(doc, m.group(2), id=f"{doc.relative_to(ROOT).as_posix()}#{n}")


def test_the_readme_is_a_front_door():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 300
    assert not re.findall(r"\b20\d\d-\d\d-\d\d\b", text), "dated measurements belong in CHANGELOG.md"


def test_every_code_block_is_of_a_kind_the_tests_run():
    for doc in DOCUMENTS:
        for m in FENCE.finditer(doc.read_text(encoding="utf-8")):
            assert m.group(1) in KINDS, f"{doc.name}: a ```{m.group(1)} block; this test runs {KINDS}"


# -- python blocks ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A working directory with one short run in ``logs/crank_rocker_95rpm-<timestamp>`` (MuJoCo
    alone, one revolution: what the documents' ``load_run`` examples read)."""
    # Through the command line, the interface the documents show (stable where modules move).
    wd = tmp_path_factory.mktemp("docs")
    subprocess.run([sys.executable, "-m", "cosim", "-q", "run", "crank_rocker_95rpm", "--engines", "mujoco",
                    "--revolutions", "1", "--no-record", "--out", "logs/crank_rocker_95rpm-doc"],
                   cwd=wd, check=True, capture_output=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    summary = json.loads((wd / "logs" / "crank_rocker_95rpm-doc" / "summary.json").read_text())
    assert summary["status"] == "completed", summary
    return wd


@pytest.mark.parametrize("doc, code", list(_blocks("python")))
def test_python_blocks_run(doc, code, workdir, monkeypatch):
    import matplotlib
    matplotlib.use("Agg")
    monkeypatch.chdir(workdir)
    exec(compile(code.replace("<timestamp>", "doc"), f"{doc.name} block", "exec"), {"__name__": "__doc_block__"})


# -- toml blocks -----------------------------------------------------------------------------

@pytest.mark.parametrize("doc, code", list(_blocks("toml")))
def test_toml_blocks_parse(doc, code):
    tomllib.loads(code)


# -- bash blocks -----------------------------------------------------------------------------

def _commands(code: str):
    """The commands of a shell block: continuation lines joined, comments dropped."""
    for line in code.replace("\\\n", " ").splitlines():
        words = shlex.split(line, comments=True)
        if words:
            yield words


def _check_command(words: list[str]) -> None:
    from cosim.cli import build_parser
    prog, *args = words
    if prog in (".venv/bin/cosim", "cosim"):
        build_parser().parse_args(args)                     # exits (a failure here) on a bad option
    elif prog in (".venv/bin/python", "python", "python3"):
        if args[:2] == ["-m", "cosim"]:
            build_parser().parse_args(args[2:])
        elif args[:2] == ["-m", "pip"]:
            assert args[2] == "install" and all(a.startswith("-") or a.startswith(".[") for a in args[3:]), args
        elif args[0] == "-m":
            module = ROOT / args[1].replace(".", "/")
            assert module.with_suffix(".py").is_file() or (module / "__init__.py").is_file(), args[1]
        else:
            assert (ROOT / args[0]).is_file(), args[0]
    elif prog == "make":
        targets = re.findall(r"^([\w-]+):", (ROOT / "Makefile").read_text(), re.M)
        assert args and all(a in targets for a in args), (args, targets)
    elif prog in (".venv/bin/rerun", ".venv/bin/jupyter"):
        assert all((ROOT / a).exists() for a in args if "/" in a and "<" not in a), args
    else:
        raise AssertionError(f"a command this test does not know how to check: {' '.join(words)}")


@pytest.mark.parametrize("doc, code", list(_blocks("bash")))
def test_shell_blocks_are_commands_that_exist_and_parse(doc, code):
    for words in _commands(code):
        try:
            _check_command(words)
        except SystemExit as exc:                           # argparse's refusal
            raise AssertionError(f"{doc.name}: {' '.join(words)} does not parse") from exc


# -- generated documents ---------------------------------------------------------------------

def test_the_benchmark_document_shows_the_latest_results():
    from tests.benchmarks import bench_table
    assert (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8") == bench_table.document(), \
        "run: python -m tests.benchmarks.bench_table --doc"


def test_the_architecture_lists_every_compiled_reference_pair():
    """docs/architecture.md's table of compiled kernels and their numpy references names every
    pair of tests/test_architecture.py's PAIRS: its kernels and its equality test."""
    from tests.test_architecture import PAIRS
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    for compiled, _reference, test in PAIRS:
        kernels = re.findall(r"(compiled\.\w+)\.(\w+)", compiled)
        assert kernels and all(f"{module}.{name}" in text for module, name in kernels), compiled
        assert test.split("/")[-1] in text, test


def test_the_architecture_lists_every_module():
    """docs/architecture.md has a row for every module of tmm_core and cosim (a package's row,
    ``recording/``, covers its modules): the layout stays true as modules come and go."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    missing = []
    sections = (("tmm_core", "**`tmm_core/`", "**`cosim/`"), ("cosim", "**`cosim/`", "**Around the code**"))
    for package, start, end in sections:
        rows = [row.split("|")[1] for row in text[text.index(start):text.index(end)].splitlines()
                if row.startswith("| `")]
        named = {n for cell in rows for n in re.findall(r"`([\w/]+(?:\.py|/))`", cell)}
        for path in sorted((ROOT / package).rglob("*.py")):
            name = path.relative_to(ROOT / package).as_posix()
            if name not in named and not any(name.startswith(n) for n in named if n.endswith("/")):
                missing.append(f"{package}/{name}")
    assert not missing, missing


# -- files named -----------------------------------------------------------------------------

#: Where a named file is looked for: the repository's own top-level folders.
TOP = ("cosim", "tmm_core", "tests", "scenarios", "docs", "examples", "benchmarks")
PATH = re.compile(r"(?<![\w./-])((?:%s)/[\w./*-]*[\w*/])" % "|".join(TOP))
BARE = re.compile(r"(?<![\w./-])([\w-]+\.md)\b")
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
SOURCES = [*DOCUMENTS, *sorted(p for p in ROOT.glob("tests/**/*.py") if p.name != "test_docs.py"),
           *sorted(ROOT.glob("scenarios/**/*.toml")),
           *sorted(ROOT.glob("scenarios/*.py")), *sorted(ROOT.glob("cosim/**/*.py")),
           *sorted(ROOT.glob("tmm_core/**/*.py")), *sorted(ROOT.glob("examples/*.py")),
           ROOT / "Makefile", ROOT / "pyproject.toml"]


def _exists(name: str) -> bool:
    name = name.split("::")[0].rstrip(".")
    if any(c in name for c in "*"):
        return any(ROOT.glob(name))
    return (ROOT / name).exists()


def _named(path: Path):
    text = path.read_text(encoding="utf-8")
    for m in PATH.finditer(text):
        if text[m.end():m.end() + 1] in ("<", "{"):
            continue                                        # a placeholder: scenarios/<name>.toml
        yield m.group(1)
    for m in BARE.finditer(text):
        yield m.group(1)


def test_every_file_named_exists():
    md_names = {p.name for p in ROOT.rglob("*.md") if ".venv" not in p.parts}
    missing = []
    for path in SOURCES:
        for name in _named(path):
            if name.endswith(".md") and "/" not in name:
                ok = name in md_names
            else:
                ok = _exists(name)
            if not ok:
                missing.append(f"{path.relative_to(ROOT).as_posix()}: {name}")
    assert not missing, "named but not in the repository:\n" + "\n".join(sorted(set(missing)))


def test_no_citation_of_notes_outside_the_repository():
    """The bench was built from reading notes of its sources (``notes seed000 §7.2``); they are not
    in the repository, so nothing cites them: cite the source itself, or the section of
    docs/validation.md that states what is relied on."""
    cited = [f"{path.relative_to(ROOT).as_posix()}:{n + 1}"
             for path in SOURCES for n, line in enumerate(path.read_text(encoding="utf-8").splitlines())
             if re.search(r"\bseed ?00\d\b|reference_checks|engine_pitfalls", line)]
    assert not cited, cited


SECTION = re.compile(r"\b(README|docs/[a-z-]+)(?:\.md)?(?:'s)?,? (?:section )?(?:\"([^\"\n]+)\"|'([^'\n]+)')")


def test_every_section_named_in_the_code_exists():
    """``docs/validation.md, "Engines that agree"``: a section a module, test or scenario points to
    is a heading (or a bold paragraph's lead) of that document, so that moving a section breaks a
    test instead of a pointer."""
    def leads(doc: Path) -> list[str]:
        text = doc.read_text(encoding="utf-8")
        found = re.findall(r"^#+ (.+)$", text, re.M) + re.findall(r"^\*\*(.+?)\*\*", text, re.M)
        return [_plain(h) for h in found]
    stale = []
    for path in SOURCES:
        for m in SECTION.finditer(path.read_text(encoding="utf-8")):
            doc = ROOT / (m.group(1) + ".md")
            name = _plain(m.group(2) or m.group(3))
            if not doc.is_file() or not any(h.startswith(name) for h in leads(doc)):
                stale.append(f"{path.relative_to(ROOT).as_posix()}: {m.group(0)}")
    assert not stale, stale


def _plain(text: str) -> str:
    return re.sub(r"[\"'`.:]", "", text).strip().lower()


def test_every_relative_link_of_a_document_resolves():
    broken = []
    for doc in DOCUMENTS:
        for m in LINK.finditer(doc.read_text(encoding="utf-8")):
            target = m.group(1)
            if not re.match(r"^[a-z]+:", target) and not (doc.parent / target).exists():
                broken.append(f"{doc.name}: {target}")
    assert not broken, broken


def test_every_anchor_of_a_document_link_exists():
    """``[text](file.md#anchor)``: the anchor is a heading of that file (GitHub's slugs)."""
    def slugs(doc: Path) -> set[str]:
        heads = re.findall(r"^#+ (.+)$", FENCE.sub("", doc.read_text(encoding="utf-8")), re.M)
        return {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in heads}
    broken = []
    for doc in DOCUMENTS:
        for target, anchor in re.findall(r"\]\(([^)#\s]*)#([^)\s]+)\)", doc.read_text(encoding="utf-8")):
            file = doc if not target else doc.parent / target
            if file.suffix == ".md" and anchor not in slugs(file):
                broken.append(f"{doc.name}: {target}#{anchor}")
    assert not broken, broken
