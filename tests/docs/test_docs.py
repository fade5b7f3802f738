"""The commands of README.md and docs/*.md, run as documented (see :mod:`tests.docs.harness`
for the conventions: blocks, sessions, the simulated cell, output shapes, markers).

Quick: every block is runnable or says why not, every ``cellcal`` command in a runnable
block parses (a renamed flag fails here at once), the README's first screen has what a
newcomer needs. Slow: every document's blocks run against the simulated cell and their
output is compared with the document.
"""

from __future__ import annotations

import contextlib
import io

import pytest

from cellcal.cli import build_parser

from .harness import DOCS, ROOT, Session, cellcal_argv, check_block, parse_blocks

RUNNABLE = [p for p in DOCS if any(not b.skip for b in parse_blocks(p))]


def _ids(paths):
    return [p.relative_to(ROOT).as_posix() for p in paths]


def test_docs_have_blocks_and_every_skip_says_why():
    blocks = [b for p in DOCS for b in parse_blocks(p)]
    assert len(blocks) >= 10
    for b in blocks:
        if "skip" in b.options:
            assert len(b.skip) > 10, f"{b.where}: skip needs a reason"
        assert b.commands, f"{b.where}: a shell block without commands"


@pytest.mark.parametrize("path", DOCS, ids=_ids(DOCS))
def test_documented_cellcal_commands_parse(path):
    parser = build_parser()
    for block in parse_blocks(path):
        if block.skip:
            continue
        for cmd in block.commands:
            for argv in cellcal_argv(cmd.text):
                if argv[:2] == ["sim", "serve"] or "--help" in argv:
                    continue
                with contextlib.redirect_stderr(io.StringIO()) as err:
                    try:
                        parser.parse_args(argv)
                    except SystemExit as e:
                        raise AssertionError(f"{block.path.name}:{cmd.line}: `cellcal "
                                             f"{' '.join(argv)}` does not parse:\n"
                                             f"{err.getvalue()}") from e


def test_readme_first_screen_is_for_a_newcomer():
    first = "\n".join((ROOT / "README.md").read_text().splitlines()[:30])
    assert "python3 -m venv .venv && . .venv/bin/activate && pip install -e .[dev]" in first
    assert "cellcal demo" in first and "pytest" in first
    assert first.startswith("# cellcal\n")


def test_docs_point_at_the_formats_in_the_repository():
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = path.read_text()
        if path.name != "formats.md":
            assert "FORMATS.md" not in text, f"{path.name} cites FORMATS.md: docs/formats.md"


@pytest.mark.slow
@pytest.mark.parametrize("path", RUNNABLE, ids=_ids(RUNNABLE))
def test_documented_commands_run_as_documented(path, tmp_path):
    with Session(tmp_path / "session") as session:
        for block in parse_blocks(path):
            if not block.skip:
                check_block(session, block)
