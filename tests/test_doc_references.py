"""Every document the source cites exists in the repository.

A comment, docstring or message that names a ``something.md`` file (``docs/formats.md``,
``README.md``, ``ARCHITECTURE.md``) names it by its path from the repository's root, and
the file is there: no ``FORMATS.md §1`` for a file that is ``docs/formats.md``, no design
document that stays outside the repository.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: what is searched: the packages, the benchmarks and examples, the build and CI files
SOURCES = ("calibration", "cellcal", "daq", "drivers", "presentation", "sim_drivers",
           "benchmarks", "examples", ".ci")
TOP_FILES = ("pyproject.toml",)
SUFFIXES = {".py", ".toml", ".yaml", ".yml", ".cfg", ".ini", ".sh", ""}

#: a path ending in .md: folders and a name, not part of a longer word or a glob
CITED = re.compile(r"(?<![\w.*/-])((?:\.\.?/)*(?:[\w-]+/)*[\w.-]*\w\.md)\b")


def source_files() -> list[Path]:
    files = [ROOT / name for name in TOP_FILES]
    for top in SOURCES:
        files += sorted(p for p in (ROOT / top).rglob("*")
                        if p.is_file() and p.suffix in SUFFIXES and "__pycache__" not in p.parts)
    return files


def citations(text: str) -> list[tuple[int, str]]:
    """(line number, cited path) of every ``.md`` path in ``text``."""
    return [(n, m.group(1)) for n, line in enumerate(text.splitlines(), 1)
            for m in CITED.finditer(line)]


def exists(cited: str) -> bool:
    path = (ROOT / cited).resolve()
    return path.is_relative_to(ROOT) and path.is_file()


def test_sources_are_found():
    names = {p.relative_to(ROOT).as_posix() for p in source_files()}
    assert {"pyproject.toml", "cellcal/cli.py", ".ci/run"} <= names


def test_the_pattern_finds_cited_paths():
    assert citations("see docs/formats.md §1 and README.md; (FORMATS.md §4)") == [
        (1, "docs/formats.md"), (1, "README.md"), (1, "FORMATS.md")]
    assert citations("# ../shared/data/README.md, docs/*.md, x.md5, foo.mdx") == [
        (1, "../shared/data/README.md")]
    assert not exists("FORMATS.md") and not exists("../shared/data/README.md")
    assert exists("docs/formats.md") and exists("ARCHITECTURE.md")


def test_cited_documents_exist():
    missing = []
    for path in source_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        missing += [f"{path.relative_to(ROOT)}:{n}: {cited}" for n, cited in citations(text)
                    if not exists(cited)]
    assert not missing, ("files cited that the repository does not have (give the path "
                         "from its root: docs/..., README.md, ARCHITECTURE.md):\n"
                         + "\n".join(missing))
