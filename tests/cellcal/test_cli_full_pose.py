"""`cellcal calibrate` on data with orientations (a 6-DoF target): full pose by default,
the orientation keys of docs/formats.md §4, ``--position-only`` predicting orientations
and warning where positions are blind."""

from __future__ import annotations

import json

import pytest

from calibration import load_model
from cellcal.cli import main
from tests.calibration.test_full_pose import FLOOR_DEG, FLOOR_MM, _data

KEYS = ("orientation_rms_deg", "orientation_mean_deg", "orientation_max_deg")


@pytest.fixture(scope="module")
def six_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("six") / "six.csv"
    _data(load_model("ur10e"), n=70, n_valid=25).to_csv(path)
    return path


def _calibrate(capsys, *argv):
    rc = main(["calibrate", *map(str, argv), "--model", "ur10e", "--json"])
    out = capsys.readouterr()
    return rc, json.loads(out.out), out.err


def test_full_pose_by_default_reports_orientations(six_csv, capsys, tmp_path):
    rc, doc, err = _calibrate(capsys, six_csv, "--out", tmp_path / "p.json")
    assert rc == 0 and doc["effects"][-1] == "tool_rotation" and "full-pose" in err
    for part in ("calib", "valid"):
        assert all(k in doc[part] for k in KEYS)
    assert doc["valid"]["rms_mm"] <= 1.1 * FLOOR_MM
    assert doc["valid"]["orientation_rms_deg"] <= 1.1 * FLOOR_DEG
    assert doc["orientation"]["fitted"] is True
    assert "orientation_blindness" not in doc and "weakly determined" not in err
    assert "tool_rotation.rx" in doc["params"]


def test_position_only_predicts_orientations_and_warns(six_csv, capsys):
    rc, doc, err = _calibrate(capsys, six_csv, "--position-only")
    assert rc == 0 and "tool_rotation" not in doc["effects"]
    assert doc["valid"]["rms_mm"] <= 1.1 * FLOOR_MM
    assert doc["valid"]["orientation_rms_deg"] > 5 * FLOOR_DEG
    assert doc["orientation"]["fitted"] is False
    assert doc["orientation"]["joints"][0]["joint"] == 5
    blind = doc["orientation_blindness"]
    assert blind["blind"] and blind["hidden_deg"] > 2 * blind["sigma_deg"]
    assert "weakly determined" in err and "6-DoF target" in err


def test_the_text_shows_the_orientation_table(six_csv, capsys):
    assert main(["calibrate", str(six_csv), "--model", "ur10e", "--position-only"]) == 0
    text = capsys.readouterr().out
    assert "orientations predicted by this position-only calibration" in text
    assert "along the joints' axes" in text and "joint 5" in text


def test_ridge_on_orientation_data_is_refused_naming_the_solver(six_csv, capsys):
    rc = main(["calibrate", str(six_csv), "--model", "ur10e", "--solver", "ridge"])
    assert rc == 2 and "ridge" in capsys.readouterr().err
    assert main(["calibrate", str(six_csv), "--model", "ur10e", "--solver", "ridge",
                 "--position-only"]) == 0
