"""`cellcal diagnose` and the calibrate -> diagnose -> add -> calibrate loop."""

import json

import pytest

from daq.cli import main


@pytest.fixture(scope="module")
def hidden_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("diag") / "c3.csv"
    assert main(["simulate", "--model", "ur10e", "--hidden", "compliance:3", "--seed", "2",
                 "--out", str(path)]) == 0
    return path


def test_diagnose_json_and_the_loop(hidden_csv, tmp_path, capsys):
    capsys.readouterr()
    assert main(["diagnose", str(hidden_csv), "--model", "ur10e", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["model"] == "ur10e" and doc["effects"] == ["geometric", "base", "tool"]
    assert doc["noise_floor_mm"] == pytest.approx(0.015 * 3**0.5)
    best = doc["candidates"][0]
    assert best["effect"] == "compliance:3" and best["significant"] and best["joint"] == 3
    assert best["family"] == "compliance" and 0.5 < best["explained_fraction"] <= 1
    assert doc["next_effects"] == "geometric,base,tool,compliance:3"
    params = tmp_path / "p.json"
    assert main(["calibrate", str(hidden_csv), "--model", "ur10e", "--effects",
                 doc["next_effects"], "--json", "--out", str(params)]) == 0
    cal = json.loads(capsys.readouterr().out)
    assert cal["valid"]["rms_mm"] < 1.1 * doc["noise_floor_mm"]
    # diagnosing the improved model (from its params) finds nothing more
    assert main(["diagnose", str(hidden_csv), "--model", "ur10e", "--params", str(params),
                 "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["at_noise_floor"] and not any(c["significant"] for c in again["candidates"])


def test_diagnose_text(hidden_csv, capsys):
    capsys.readouterr()
    assert main(["diagnose", str(hidden_csv), "--model", "ur10e"]) == 0
    out = capsys.readouterr().out
    assert "Compliance of joint 3 explains" in out
    assert "next:     --effects geometric,base,tool,compliance:3" in out
    assert "worst poses:" in out


def test_diagnose_bad_input(hidden_csv, capsys):
    assert main(["diagnose", str(hidden_csv), "--model", "ur10e", "--effects", "x:1"]) == 2
    assert "unknown effect family" in capsys.readouterr().err
    assert main(["diagnose", str(hidden_csv), "--model", "ur10e", "--params", "nope.json"]) == 2
