"""Every error class of every layer carries its exit code, and the command line maps each
family by it, in one place, as docs/formats.md §6 documents."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import calibration.errors
import daq.cell_session
import daq.errors
import daq.executor
import daq.motion_guard
import daq.store.errors
import daq.store.leases
import drivers.errors
from cellcal.errors import UsageError

FAMILIES = [calibration.errors.CalibrationError, daq.errors.DaqError,
            daq.store.errors.StoreError, drivers.errors.DriverError, UsageError]


def _classes(base: type) -> list[type]:
    out = [base]
    for sub in base.__subclasses__():
        out += _classes(sub)
    return out


def test_every_error_class_of_every_layer_has_an_exit_code():
    seen = [c for base in FAMILIES for c in _classes(base)]
    assert len(seen) > 30  # the families were found whole (imports above)
    for c in seen:
        assert type(c.exit_code) is int and c.exit_code in (1, 2, 3), c


def test_the_exit_codes_are_documented_once_and_completely():
    text = (Path(__file__).parents[2] / "docs" / "formats.md").read_text(encoding="utf-8")
    section = text.split("## 6. Exit codes", 1)[1].split("\n## ", 1)[0]
    assert set(re.findall(r"^\| (\d+) \|", section, re.M)) == {"0", "1", "2", "3", "130"}
    assert "128 + N" in section  # capture's and resume's signals


def _drivers_error():
    return drivers.errors.ProtectiveStop("robot sim://", "moveJ", "protective stop")


def _models_raising(error, monkeypatch) -> int:
    """``cellcal models`` whose command raises ``error``: its exit code."""
    import cellcal.cli

    def fail(args):
        raise error

    parser = cellcal.cli.build_parser

    def with_fail():
        p = parser()
        for action in p._subparsers._group_actions:
            action.choices["models"].set_defaults(func=fail)
        return p

    monkeypatch.setattr(cellcal.cli, "build_parser", with_fail)
    return cellcal.cli.main(["models"])


@pytest.mark.parametrize("error, rc, said", [
    (UsageError("--floor-z-mm: not a number"), 2, "error"),
    (calibration.errors.DataError("a.csv:3: column q1: not a number"), 2, "error"),
    (calibration.errors.CellError("cell.yaml: tracker: missing"), 2, "error"),
    (calibration.errors.InsufficientData("3 poses for 24 parameters"), 3, "data too poor"),
    (calibration.errors.TooLarge("calibrate of 9 poses needs 2 GiB; 1 GiB is left"), 3,
     "error"),
    (daq.errors.RequestError("unknown run 7"), 2, "error"),
    (daq.errors.NotEnoughVisible("the tracker would not see 12 of 20 targets"), 3, "error"),
    (daq.errors.ConnectFailed("robot sim://: connect: refused"), 1, "error"),
    (daq.store.errors.StoreError("cell.db: newer schema"), 2, "error"),
    (daq.store.errors.StoreUnavailable("postgresql://x: gone"), 1, "error"),
    (_drivers_error(), 1, "error"),
    (KeyboardInterrupt(), 130, None),
])
def test_the_command_line_maps_each_family_by_its_exit_code(error, rc, said, monkeypatch,
                                                           capsys):
    assert _models_raising(error, monkeypatch) == rc
    err = capsys.readouterr().err
    expected = ("cellcal models: interrupted\n" if said is None
                else f"cellcal models: {said}: {' '.join(str(error).split())}\n")
    assert err == expected


def test_running_out_of_memory_is_exit_3_and_says_so(monkeypatch, capsys):
    assert _models_raising(MemoryError("Unable to allocate 168. GiB"), monkeypatch) == 3
    err = capsys.readouterr().err
    assert err.startswith("cellcal models: error: out of memory (Unable to allocate 168. GiB)")
    assert "internal error" not in err and err.count("\n") == 1
