"""`cellcal diagnose` on data with orientations (a 6-DoF target): the orientation
residuals shown and ranked beside the positions', per joint and per flange axis, in the
text and in an ``orientation`` object of ``--json`` (the existing keys unchanged)."""

from __future__ import annotations

import json

import pytest

from calibration import load_model
from cellcal.cli import main
from tests.calibration.test_full_pose import _data


@pytest.fixture(scope="module")
def six_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("six") / "six.csv"
    _data(load_model("ur10e"), n=60, n_valid=20).to_csv(path)
    return path


def test_diagnose_json_ranks_the_orientation_residual(six_csv, capsys):
    argv = ["diagnose", str(six_csv), "--model", "ur10e", "--effects", "geometric,base,tool",
            "--json"]
    assert main(argv) == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("rms_mm", "candidates", "recommendation", "worst_poses"):
        assert key in doc
    o = doc["orientation"]
    assert o["fitted"] is False and o["joints"][0]["joint"] == 5
    shares = [j["share"] for j in o["joints"]]
    assert shares == sorted(shares, reverse=True)
    axes = [a["rms_deg"] for a in o["axes"]]
    assert axes == sorted(axes, reverse=True) and {a["axis"] for a in o["axes"]} == set("xyz")
    assert o["valid"]["orientation_rms_deg"] > o["noise_floor_deg"]


def test_diagnose_text_shows_the_orientation_section(six_csv, capsys):
    assert main(["diagnose", str(six_csv), "--model", "ur10e"]) == 0
    text = capsys.readouterr().out
    assert "about the flange's axes" in text and "along the joints' axes" in text


def test_no_orientation_object_without_orientations(tmp_path, capsys):
    path = tmp_path / "pos.csv"
    data = _data(load_model("ur10e"), n=40, n_valid=10)
    data.quat = data.sigma_deg = None
    data.to_csv(path)
    assert main(["diagnose", str(path), "--model", "ur10e", "--json"]) == 0
    assert "orientation" not in json.loads(capsys.readouterr().out)
