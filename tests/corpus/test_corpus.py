"""Every CLI command over the corpus of bad inputs (tests/corpus/cases.py): no traceback,
the documented exit code, a message naming the problem, every input file unchanged.

The quick part runs in-process (``cellcal.cli.main``); cases that need a real process (stdout
without a reader, /dev/zero and FIFOs as inputs, a store only readable by an unprivileged
user, `sim serve`) are marked slow. ``python -m tests.corpus.tally`` prints the same
corpus as a table per command.
"""

from __future__ import annotations

import pytest

from .cases import build_cases, judge, run_case
from .workspace import build, copy_workspace

CASES = build_cases()


@pytest.fixture(scope="session")
def corpus_workspace(tmp_path_factory):
    return build(tmp_path_factory.mktemp("corpus") / "workspace")


def _param(case):
    marks = [pytest.mark.slow] if case.slow else []
    return pytest.param(case, id=case.id, marks=marks)


@pytest.mark.parametrize("case", [_param(c) for c in CASES])
def test_corpus_case(case, corpus_workspace, tmp_path):
    ws = copy_workspace(corpus_workspace, tmp_path / "ws")
    outcome, before = run_case(case, ws)
    problems = judge(case, outcome, before, ws)
    assert not problems, f"{case.id} {case.argv}:\n" + "\n".join(problems) + \
        f"\n--- stderr ---\n{outcome.err[-2000:]}"


def test_corpus_covers_every_command():
    from cellcal.cli import COMMANDS

    names = {m.rsplit(".", 1)[-1] for m in COMMANDS}
    aliases = {"export_run": "export", "sim_serve": "sim", "simulate_dataset": "simulate"}
    covered = {c.command for c in CASES}
    assert {aliases.get(n, n) for n in names} <= covered


class _ClosedPipe:
    """stdout whose reader went away (`cellcal runs --json | head`)."""

    def write(self, text):
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self):
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self):
        raise ValueError("no file")


def test_a_closed_stdout_ends_quietly(corpus_workspace, monkeypatch, capsys):
    from cellcal.cli import main

    monkeypatch.chdir(corpus_workspace)
    monkeypatch.setattr("sys.stdout", _ClosedPipe())
    assert main(["runs", "--db", "cell.db", "--json"]) == 0
    assert main(["models"]) == 0
    assert capsys.readouterr().err == ""


def test_an_unexpected_error_is_one_line_not_a_traceback(monkeypatch, capsys):
    from cellcal.cli import main

    def boom(args):
        raise RuntimeError("something nobody foresaw")

    monkeypatch.delenv("CELLCAL_TRACEBACK", raising=False)
    import cellcal.cli

    parser = cellcal.cli.build_parser  # the sub-command binds run at registration
    monkeypatch.setattr(cellcal.cli, "build_parser", lambda: _with_func(parser(), boom))
    assert main(["models"]) == 1
    err = capsys.readouterr().err
    assert "internal error: RuntimeError: something nobody foresaw" in err
    assert "Traceback" not in err and err.count("\n") == 1


def _with_func(parser, func):
    for action in parser._subparsers._group_actions:
        action.choices["models"].set_defaults(func=func)
    return parser
