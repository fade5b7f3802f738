"""The capture's context travels: a measurement CSV's ``# key: value`` header (model, the
controller's tool, run) sets the nominal model of calibrate, goes into params.json and
makes compensate's corrections the robot's error; without it, compensate says why its
corrections are large. Also: compensate's targets without joints, its consistent
summary, and ``runs RUN`` for people."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from calibration import ErrorModel, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from cellcal.cli import main
from tests.daq.capture_helpers import DATA
from tests.daq.test_store_upgrade import v2_db  # noqa: F401  (the fixture)

TOOL = (0.0, 0.0, 60.0)


@pytest.fixture(scope="module")
def capture_csv(tmp_path_factory):
    """A simulated UR10e whose controller's TCP is a 60 mm holder, as `export` writes it."""
    nominal = load_model("ur10e").with_changes(tool=TOOL)
    em = ErrorModel(nominal)
    rng = np.random.default_rng(3)
    x = realistic_truth(em, rng)
    data = simulate(em, x, random_joints(nominal, 240, rng), 0.015, rng,
                    is_valid=np.arange(240) >= 180)
    d = tmp_path_factory.mktemp("meta")
    with_meta, without = d / "capture.csv", d / "bare.csv"
    data.meta = {"run": "7", "store": "cell.db", "model": "ur10e", "tool_mm": "0, 0, 60",
                 "tracker_sigma_mm": "0.015"}
    data.to_csv(with_meta)
    data.meta = {}
    data.to_csv(without)
    targets = d / "targets.csv"
    targets.write_text("pose_id,x,y,z\nA,600,200,500\nB,800,0,600\nC,-500,-400,300\n")
    return with_meta, without, targets


def test_the_capture_tool_travels_into_params_and_compensate(capture_csv, tmp_path, capsys):
    csv, _, targets = capture_csv
    params = tmp_path / "params.json"
    assert main(["calibrate", str(csv), "--out", str(params)]) == 0  # model from the header
    out = capsys.readouterr().out
    assert "model     ur10e (dh), tool 0, 0, 60 mm (capture run 7)" in out
    doc = json.loads(params.read_text())
    assert doc["model_definition"]["tool"] == list(TOOL)
    assert doc["capture"]["run"] == 7 and doc["capture"]["tool_mm"] == list(TOOL)
    assert main(["diagnose", str(csv), "--top", "3"]) == 0
    assert "tool 0, 0, 60 mm (capture run 7)" in capsys.readouterr().out
    assert main(["compensate", str(targets), "--params", str(params), "--json"]) == 0
    comp = json.loads(capsys.readouterr().out)
    assert comp["n_reached"] == 3 and comp["notes"] == []  # targets without joints: reached
    assert comp["tool_mm"] == list(TOOL) and comp["capture"]["run"] == 7
    assert 0.1 < comp["correction_mm"]["mean"] < 5.0  # the robot's error, not the tool
    assert comp["reason"] == "all 3 targets reached"


def test_without_the_capture_tool_compensate_says_why_corrections_are_large(
        capture_csv, tmp_path, capsys):
    _, bare, targets = capture_csv
    params = tmp_path / "params.json"
    assert main(["calibrate", str(bare), "--model", "ur10e", "--out", str(params)]) == 0
    capsys.readouterr()
    assert main(["compensate", str(targets), "--params", str(params)]) == 0
    out = capsys.readouterr().out
    mean = float(re.search(r"correction of the Cartesian targets: mean ([\d.]+) mm", out)[1])
    assert 50 < mean < 70  # the SMR's ~60 mm holder, not the robot's error
    assert re.search(r"the calibrated tool \(.*\) is \d+ mm from the nominal tool", out)
    assert main(["calibrate", str(bare)]) == 2
    assert "give --model: " in capsys.readouterr().err


def test_compensate_summary_agrees_with_its_counts(capture_csv, tmp_path, capsys):
    csv, _, _ = capture_csv
    params = tmp_path / "params.json"
    assert main(["calibrate", str(csv), "--out", str(params)]) == 0
    far = tmp_path / "far.csv"
    far.write_text("x,y,z\n600,200,500\n5000,0,0\n")  # the second is out of reach
    capsys.readouterr()
    assert main(["compensate", str(far), "--params", str(params)]) == 1
    out = capsys.readouterr().out
    assert "targets   " in out and "reached 1," in out
    assert "solver    1 of 2 targets not reached" in out


def test_runs_shows_a_run_for_people(v2_db, capsys):  # noqa: F811
    assert main(["runs", "3", "--db", str(v2_db)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("run 3 (zero20): completed, 20/20 points stored")
    assert "tool 0, 0, 60 mm" in out and "from run 1: tracker_T_base" in out
    assert "summary" in out and "tip_spread_max_mm" in out
    assert "{" not in out and "None" not in out  # no Python reprs
    started = next(line for line in out.splitlines() if line.startswith("started"))
    assert len(started.split()[1]) == 10 and started.split()[1][4] == "-"  # ISO date
    assert main(["runs", "--db", str(v2_db)]) == 0
    assert "\n1    frame    completed" in capsys.readouterr().out


def test_zero_without_seed_is_the_same_every_time(capsys):
    csv = DATA / "schema_v2" / "postures3.csv"
    outs = []
    for _ in range(2):
        assert main(["zero", str(csv), "--model", "ur10e", "--json"]) in (0, 3)
        doc = json.loads(capsys.readouterr().out)
        outs.append((doc["offsets_deg"], doc["seed"]["offsets_deg"]))
    assert outs[0] == outs[1]
