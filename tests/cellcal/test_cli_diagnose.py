"""`cellcal diagnose` and the calibrate -> diagnose -> add -> calibrate loop."""

import json
import subprocess
import sys

import pytest

from cellcal.cli import main


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


HIDDEN = "harmonic20:2,compliance:3,backlash:2,harmonic2:4,table:5"


@pytest.fixture(scope="module")
def several_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("auto") / "capture.csv"
    assert main(["simulate", "--model", "ur10e", "--hidden", HIDDEN, "--seed", "4",
                 "--out", str(path)]) == 0
    return path


def test_diagnose_auto_as_in_the_readme(several_csv):
    # the README's commands, run as a user runs them
    params = several_csv.parent / "params.json"
    proc = subprocess.run(
        [sys.executable, "-m", "cellcal", "diagnose", several_csv.name, "--model", "ur10e",
         "--auto", "--out", params.name],
        cwd=several_csv.parent, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "step, effect added" in out and "held-out rms mm" in out
    for eff in HIDDEN.split(","):
        assert f" {eff} " in out  # every hidden effect is added, nothing else
    assert "a 20-per-turn periodic error of joint 2" in out
    assert "stopped   the residual is at the instrument's noise floor" in out
    assert "effects   geometric,base,tool," in out
    assert "wrote     params.json" in out and params.exists()


def test_diagnose_auto_json_and_its_params_file(several_csv, tmp_path, capsys):
    params = tmp_path / "auto.json"
    capsys.readouterr()
    assert main(["diagnose", str(several_csv), "--model", "ur10e", "--auto", "--json",
                 "--out", str(params)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc) == {"model", "start_effects", "steps", "effects", "stop_reason",
                        "params_file", "outliers"}
    assert doc["model"] == "ur10e" and doc["start_effects"] == ["geometric", "base", "tool"]
    assert sorted(s["effect"] for s in doc["steps"]) == sorted(HIDDEN.split(","))
    assert doc["effects"] == ["geometric", "base", "tool"] + [s["effect"] for s in doc["steps"]]
    assert doc["params_file"] == str(params) and doc["outliers"] == []
    floor = 0.015 * 3**0.5
    assert doc["steps"][-1]["heldout_rms_mm"] < 1.10 * floor
    # the params file is what calibrate writes: diagnose --params reads it back, at the floor
    assert main(["diagnose", str(several_csv), "--model", "ur10e", "--params", str(params),
                 "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["effects"] == doc["effects"] and again["at_noise_floor"]
    # and the effect list works as --effects
    assert main(["calibrate", str(several_csv), "--model", "ur10e", "--effects",
                 ",".join(doc["effects"]), "--json"]) == 0
    cal = json.loads(capsys.readouterr().out)
    assert cal["valid"]["rms_mm"] < 1.10 * floor


def test_diagnose_auto_bad_input(several_csv, capsys):
    base = ["diagnose", str(several_csv), "--model", "ur10e"]
    assert main(base + ["--out", "p.json"]) == 2
    assert "--out need(s) --auto" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # refused by the parser (an integer >= 1)
        main(base + ["--auto", "--max-steps", "0"])
    assert e.value.code == 2
    assert "--max-steps: 0 is not an integer >= 1" in capsys.readouterr().err
    assert main(base + ["--auto", "--out", str(several_csv)]) == 2
    assert "is an input of this command" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        main(base + ["--auto", "--budget-s", "-1"])
    assert e.value.code == 2
