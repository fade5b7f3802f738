"""The logging flags every command takes (-v, -vv, --log-level, --log-file, before or after
the command's name), the default (warnings only, one line each on stderr), and the log a
capture keeps beside its run."""

from __future__ import annotations

import json
import logging
import re

import pytest

import sim_drivers.inprocess as inproc
from cellcal.cli import main
from sim_drivers.model_truth import model_truth_factory
from tests.daq.capture_helpers import served_cell, toy_sim

LINE = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3} (DEBUG|INFO|WARNING|ERROR|CRITICAL) "
                  r"[\w.]+: ")


def _toy_capture(db, name: str, *extra: str) -> list[str]:
    return ["capture", "poses", "--model", "tests/daq/data/toyarm.yaml", "--count", "6",
            "--seed", "2", "--robot", toy_sim("robot", 31, name),
            "--tracker", toy_sim("tracker", 31, name), "--db", str(db),
            "--measure-s", "0.01", "--no-visibility", *extra]


@pytest.fixture(autouse=True)
def _fresh_cells():
    inproc.reset_cells()
    yield
    inproc.reset_cells()


@pytest.mark.parametrize("argv", [["-v", "models"], ["models", "-v"],
                                  ["models", "--log-level", "info"],
                                  ["--log-level", "DEBUG", "models", "--log-level", "info"]])
def test_verbose_before_or_after_the_command_logs_info_to_stderr(argv, capsys):
    root = list(logging.getLogger().handlers)
    assert main(argv) == 0
    err = capsys.readouterr().err.splitlines()
    assert err and all(LINE.match(line) for line in err), err
    assert err[0].endswith(f"INFO cellcal.cli: cellcal {' '.join(argv)}")
    assert err[-1].endswith("INFO cellcal.cli: cellcal models: exit 0")
    assert logging.getLogger().handlers == root  # nothing left behind
    assert logging.getLogger("daq").level == logging.NOTSET


def test_default_is_warnings_only(capsys):
    assert main(["models"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("argv", [["models", "--log-level", "LOUD"],
                                  ["--log-level", "verbose", "models"],
                                  ["models", "--log-level", ""]])
def test_a_bad_level_is_a_usage_error(argv, capsys):
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "argument --log-level:" in err and "is not a log level: choose one of DEBUG, " \
        "INFO, WARNING, ERROR, CRITICAL" in err


def test_log_file_is_appended_and_an_input_is_never_written(tmp_path, capsys):
    log = tmp_path / "cellcal.log"
    assert main(["models", "-v", "--log-file", str(log)]) == 0
    assert capsys.readouterr().err == ""  # with a log file, stderr keeps warnings only
    first = log.read_text().splitlines()
    assert len(first) == 2 and all(LINE.match(line) for line in first)
    assert main(["--log-file", str(log), "-v", "models"]) == 0
    assert log.read_text().splitlines()[:2] == first and len(log.read_text().splitlines()) == 4
    data = tmp_path / "data.csv"
    data.write_text("pose_id,x\np1,1\n")
    assert main(["models", "--log-file", str(data)]) == 2
    assert "--log-file" in capsys.readouterr().err and data.read_text() == "pose_id,x\np1,1\n"
    assert main(["models", "--log-file", str(tmp_path / "no" / "x.log")]) == 2
    assert "no such folder" in capsys.readouterr().err
    assert main(["models", "--log-file", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_a_capture_keeps_its_log_beside_its_run(tmp_path, capsys):
    db = tmp_path / "cell.db"
    assert main(_toy_capture(db, "runlog", "--json")) == 0
    out = json.loads(capsys.readouterr().out)
    path = tmp_path / "cell.db.run1.log"
    assert out["log"] == str(path) and path.is_file()
    lines = path.read_text().splitlines()
    assert all(LINE.match(line) for line in lines)
    assert "cellcal.logs: cellcal capture poses" in lines[0]  # the command line first
    text = "\n".join(lines)
    assert " INFO daq.service: run 1 stored: poses, 6 points" in text
    assert text.count("joint move to [") >= 6 and text.count(") stored: [") == 6
    assert lines[-1].endswith("INFO daq.executor: run 1 completed")
    assert " DEBUG " not in text  # INFO without -vv
    # a run paused by a protective stop, then resumed: one log, appended to
    cell = inproc.get_cell("runlog", 31)
    cell.faults.arm("pstop")
    assert main(_toy_capture(db, "runlog")) == 1
    second = tmp_path / "cell.db.run2.log"
    paused = second.read_text().splitlines()
    assert "INFO daq.executor: run 2 paused: protective stop at point 0: " in paused[-1]
    cell.clear_protective_stop()
    assert main(["resume", "2", "--db", str(db)]) == 0
    resumed = second.read_text().splitlines()
    assert resumed[:len(paused)] == paused
    assert any("INFO daq.service: run 2 resumed: poses, 0 of 6 points stored" in line
               for line in resumed[len(paused):])
    assert resumed[-1].endswith("INFO daq.executor: run 2 completed")
    capsys.readouterr()


def test_a_postgresql_store_s_run_logs_are_named_by_server_and_database(tmp_path,
                                                                       monkeypatch):
    from cellcal.logs import run_log_path

    assert run_log_path(tmp_path / "cell.db", 2) == tmp_path / "cell.db.run2.log"
    url = "postgresql://cal:s3cret@db.plant.example:5433/cells"
    monkeypatch.setenv("CELLCAL_RUN_LOG_DIR", str(tmp_path))
    assert run_log_path(url, 7) == tmp_path / "postgresql-db.plant.example-cells.run7.log"
    monkeypatch.delenv("CELLCAL_RUN_LOG_DIR")
    assert str(run_log_path(url, 7)) == "postgresql-db.plant.example-cells.run7.log"


def test_the_run_log_holds_the_wire_with_vv(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=3) as stack:
        line_robot = next(u for u in stack.urls if u.startswith("socket://"))
        tracker = next(u for u in stack.urls if u.startswith("tracker+tcp://"))
        assert main(["capture", "poses", "--model", "ur10e", "--tool-mm", "0,0,60",
                     "--no-floor", "--tracker-at", "2500,0,500", "--count", "3", "--seed", "4",
                     "--robot", line_robot, "--tracker", tracker, "--db", str(db),
                     "--measure-s", "0.01", "--log-file", str(tmp_path / "all.log"),
                     "-vv"]) == 0
    capsys.readouterr()
    run_log = (tmp_path / "cell.db.run1.log").read_text()
    assert f"DEBUG drivers.line_robot: robot {line_robot}: > MOVEJ " in run_log
    assert f"DEBUG drivers.line_tracker: tracker {tracker}: < OK MEAS x=" in run_log
    everything = (tmp_path / "all.log").read_text()  # --log-file: the whole command
    assert "INFO cellcal.cli: cellcal capture poses" in everything
    assert "> MOVEJ " in everything and "cellcal capture: exit 0" in everything
