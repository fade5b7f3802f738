"""`cellcal calibrate` and `cellcal models` from the command line."""

import json
import subprocess
import sys

import numpy as np
import pytest

from calibration import ErrorModel, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from cellcal.cli import main


@pytest.fixture(scope="module")
def sim_csv(tmp_path_factory):
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(42)
    q = random_joints(m, 400, rng)
    x = realistic_truth(em, rng)
    x[em.index("tool.x")] = x[em.index("tool.y")] = 0.0  # SMR on the flange axis: 25 free
    data = simulate(em, x, q, 0.015, rng,
                    is_valid=np.arange(400) >= 250)
    path = tmp_path_factory.mktemp("cli") / "sim.csv"
    data.to_csv(path)
    return path


def test_calibrate_json_follows_formats(sim_csv, tmp_path, capsys):
    out = tmp_path / "params.json"
    rc = main(["calibrate", str(sim_csv), "--model", "ur10e", "--json", "--out", str(out)])
    assert rc == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("model", "effects", "solver", "n_params", "n_identifiable", "unidentifiable",
                "calib", "valid", "params_file", "solve_s"):
        assert key in doc
    assert doc["effects"] == ["geometric", "base", "tool"]
    assert doc["n_params"] == 35 and doc["n_identifiable"] == 25
    assert doc["calib"]["n"] == 250 and doc["valid"]["n"] == 150
    assert doc["valid"]["rms_mm"] < 1.1 * np.sqrt(3) * 0.015
    assert doc["params_file"] == str(out) and out.exists()


def test_calibrate_table_and_params_reuse(sim_csv, tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["calibrate", str(sim_csv), "--model", "ur10e", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "calibrated, valid" in text and "noise floor" in text
    assert "geometric.j1.theta: redundant with base" in text
    assert main(["calibrate", str(sim_csv), "--model", "ur10e", "--params", str(out),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["iterations"] <= 3  # starts at the solution


def test_bad_input_exits_2_with_a_message(sim_csv, tmp_path, capsys):
    assert main(["calibrate", str(sim_csv), "--model", "nosuchrobot"]) == 2
    assert "unknown model" in capsys.readouterr().err
    assert main(["calibrate", str(tmp_path / "none.csv"), "--model", "ur10e"]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["calibrate", str(sim_csv), "--model", "ur5", "--effects", "geometric,wobble"]) == 2
    assert "unknown effect family 'wobble'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # argparse: the choices are listed
        main(["calibrate", str(sim_csv), "--model", "ur10e", "--solver", "magic"])
    assert e.value.code == 2
    assert "invalid choice: 'magic' (choose from 'lm', 'ridge'" in capsys.readouterr().err


def test_console_script_runs_models():
    r = subprocess.run([sys.executable, "-m", "cellcal", "models"], capture_output=True, text=True,
                       check=True)
    assert "ur10e" in r.stdout and "rv16" in r.stdout
