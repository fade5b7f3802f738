"""The drift example of docs/history.md runs as shown: its commands are taken from the page,
run in a shell (``cellcal`` is this interpreter's ``-m cellcal``), and print what the page
says they print; then the same again into a PostgreSQL database."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from .capture_helpers import ROOT

DOC = ROOT / "docs" / "history.md"
_NUMBER = re.compile(r"[-+]?\d+\.\d+")


def doc_session() -> list[tuple[str, str]]:
    """(command, expected output) of the page's tested console block."""
    text = DOC.read_text()
    block = text.split("<!-- doctest: skip=tested by tests/daq/test_history_doc.py", 1)[1]
    block = block.split("```console\n", 1)[1].split("```", 1)[0]
    session: list[tuple[str, list[str]]] = []
    for line in block.splitlines():
        if line.startswith("$ "):
            session.append((line[2:], []))
        else:
            session[-1][1].append(line)
    return [(cmd, "\n".join(out)) for cmd, out in session]


def same_output(actual: str, expected: str) -> None:
    """Equal up to runs of spaces and the last printed digit of decimal numbers (another
    BLAS may round the fits' last digits differently)."""
    a_lines, e_lines = actual.rstrip("\n").splitlines(), expected.splitlines()
    assert len(a_lines) == len(e_lines), actual
    for a, e in zip(a_lines, e_lines, strict=True):
        a, e = " ".join(a.split()), " ".join(e.split())
        assert _NUMBER.sub("#", a) == _NUMBER.sub("#", e), (a, e)
        for x, y in zip(_NUMBER.findall(a), _NUMBER.findall(e), strict=True):
            last = 10.0 ** -len(y.split(".")[1])
            assert abs(float(x) - float(y)) <= 2.5 * last, (a, e)


@pytest.mark.slow
def test_the_drift_example_prints_what_the_page_shows(store_address, tmp_path):
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    prelude = (f'cellcal() {{ "{sys.executable}" -m cellcal "$@"; }}\n'
               f'python() {{ "{sys.executable}" "$@"; }}\nset -o pipefail\n')
    session = doc_session()
    assert [c.split()[0] for c, _ in session] == ["python", "for", "cellcal"]
    for cmd, expected in session:
        if not store_address.endswith("cell.db"):  # the same into PostgreSQL
            cmd = cmd.replace("drift/plant.db", store_address)
        out = subprocess.run(["bash", "-c", prelude + cmd], cwd=tmp_path, capture_output=True,
                             text=True, timeout=600)
        assert out.returncode == 0, out.stderr
        same_output(out.stdout.replace(store_address, "drift/plant.db"), expected)
    assert (tmp_path / "drift" / "history.html").read_text().count("data:image/png") == 1
