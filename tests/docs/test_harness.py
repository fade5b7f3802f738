"""The doc-test harness's own rules: blocks and markers, terminal text, output shapes."""

from __future__ import annotations

from pathlib import Path

from .harness import cellcal_argv, match_output, parse_blocks, shape, terminal_text


def test_blocks_commands_outputs_and_markers(tmp_path: Path):
    doc = tmp_path / "doc.md"
    doc.write_text(
        "text\n\n<!-- doctest: rel=0.1; lines=^rms -->\n```console\n$ cellcal a \\\n"
        "    --b 1\nrms 0.5 mm\n$ echo x\nx\n```\n\n"
        "<!-- doctest: skip=needs a robot at the cell -->\n```sh\n# comment\ncellcal c\n```\n"
        "```python\nprint(1)\n```\n")
    a, b = parse_blocks(doc)
    assert a.lang == "console" and a.options == {"rel": "0.1", "lines": "^rms"}
    assert [c.text for c in a.commands] == ["cellcal a \\\n    --b 1", "echo x"]
    assert a.commands[0].expected == ["rms 0.5 mm"] and a.commands[0].line == 5
    assert b.skip == "needs a robot at the cell" and [c.text for c in b.commands] == ["cellcal c"]


def test_terminal_text_overwrites_like_a_terminal():
    raw = b"run 1\r\n\r0/3 points\r3/3 points\r          \rdone 3\r\nlast"
    assert terminal_text(raw) == ["run 1", "done 3", "last"]


def test_shapes_mask_numbers_hashes_times_and_spacing():
    assert shape("plan 693833e1fba10e1f, 0.3 s") == shape("plan 0a1b2c3d4e5f6789, 12.75 s")
    assert shape("2026-11-22 04:25:46  0") == shape("2025-01-01 00:00:00     17")
    assert shape("rms 0.5 mm") != shape("rms 0.5 mm!")
    assert shape("j1  0.1") != shape("j1  undetermined")


def test_match_output_ellipsis_and_tolerance():
    doc = ["head 1", "...", "rms 0.50 mm in 3 s", "tail"]
    assert match_output(doc, ["head 2", "a", "b", "rms 0.9 mm in 9 s", "tail", ""])
    assert match_output(doc, ["head 2", "rms 0.5 mm in 3 s", "tail"])
    assert not match_output(doc, ["head 2", "rms 0.5 mm in 3 s"])
    # numbers compared on the lines asked for, durations never
    assert match_output(doc, ["head 1", "rms 0.52 mm in 30 s", "tail"], 0.1, "^rms")
    assert not match_output(doc, ["head 1", "rms 0.9 mm in 3 s", "tail"], 0.1, "^rms")


def test_inline_ellipsis_matches_any_text():
    doc = ["solver    lm: converged ([...]) after 4 iterations, 45.7 ms"]
    assert match_output(doc, ["solver    lm: converged (step below tolerance) after 7 "
                              "iterations, 3.1 ms"])
    assert not match_output(doc, ["solver    lm: NOT converged (x) after 7 iterations, 3 ms"])


def test_cellcal_argv_splits_shell_syntax():
    assert cellcal_argv("cellcal zero --db c.db --json > out.json") == [
        ["zero", "--db", "c.db", "--json"]]
    assert cellcal_argv("cellcal capture poses --robot $R && cellcal runs --db x | head") == [
        ["capture", "poses", "--robot", "VALUE"], ["runs", "--db", "x"]]
    assert cellcal_argv("cellcal sim serve --no-pty &") == [["sim", "serve", "--no-pty"]]
