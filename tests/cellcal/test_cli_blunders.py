"""Blunders on the command line: `simulate --blunders`, `calibrate --outliers`, the JSON keys,
params.json, and `diagnose` naming them."""

import json

import pytest

from cellcal.cli import main

FULL = "geometric,base,tool,compliance:3"


@pytest.fixture(scope="module")
def blunder_csv(tmp_path_factory):
    d = tmp_path_factory.mktemp("blunders")
    path, truth = d / "b.csv", d / "truth.json"
    assert main(["simulate", "--model", "ur10e", "--hidden", "compliance:3", "--seed", "4",
                 "--poses", "300", "--valid", "300", "--blunders", "0.03", "--out", str(path),
                 "--truth", str(truth)]) == 0
    doc = json.loads(truth.read_text())
    ids = {b["pose_id"] for b in doc["blunders"]}
    assert 4 <= len(ids) <= 18
    assert all(0.5 <= b["size_mm"] <= 5.0 for b in doc["blunders"])
    return path, ids


def _run_json(capsys, *argv):
    capsys.readouterr()
    rc = main([*argv, "--json"])
    return rc, json.loads(capsys.readouterr().out)


def test_simulate_blunders_leaves_the_clean_readings_alone(blunder_csv, tmp_path, capsys):
    path, ids = blunder_csv
    plain = tmp_path / "plain.csv"
    assert main(["simulate", "--model", "ur10e", "--hidden", "compliance:3", "--seed", "4",
                 "--poses", "300", "--valid", "300", "--out", str(plain)]) == 0
    a = [line for line in plain.read_text().splitlines() if not line.startswith("#")]
    b = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    differ = {x.split(",")[0] for x, y in zip(a, b, strict=True) if x != y}
    assert differ == ids
    with pytest.raises(SystemExit) as e:  # refused by the parser: a probability
        main(["simulate", "--model", "ur10e", "--out", str(plain), "--blunders", "2"])
    assert e.value.code == 2
    assert "--blunders: 2 is not a number 0 .. 1" in capsys.readouterr().err


def test_calibrate_json_lists_outliers_and_params(blunder_csv, tmp_path, capsys):
    path, ids = blunder_csv
    out = tmp_path / "params.json"
    rc, doc = _run_json(capsys, "calibrate", str(path), "--model", "ur10e", "--effects", FULL,
                        "--out", str(out))
    assert rc == 0
    named = {o["pose_id"] for o in doc["outliers"]}
    assert len(named & ids) >= 0.9 * len(ids) and len(named - ids) <= 6
    for o in doc["outliers"]:
        assert set(o) >= {"pose_id", "residual_mm", "along_beam"}
        assert o["excluded"] is True
        assert o["residual_mm"] > (0.3 if o["pose_id"] in ids else 0.06)
        assert o["along_beam"] in (True, False)  # simulated data: tracker frame
    assert doc["outlier_check"]["clean_cloud"] and doc["outlier_check"]["mode"] == "exclude"
    assert doc["calib"]["n"] == 300 - len(named)
    assert doc["valid"]["rms_mm"] < 1.10 * doc["noise_floor_mm"]
    p = doc["params"]
    assert p["compliance.j3.c"]["unit"] and p["geometric.j2.a"]["unit"] == "mm"
    assert p["base.x"]["std"] > 0 and p["geometric.j1.theta"]["std"] is None  # redundant
    saved = json.loads(out.read_text())
    assert [o["pose_id"] for o in saved["outliers"]] == [o["pose_id"] for o in doc["outliers"]]
    rows = {r["name"]: r for r in saved["parameters"]}
    assert all(rows[k]["value"] == v["value"] for k, v in p.items())
    # keep: every point fitted, nothing named, and the accuracy suffers
    rc, kept = _run_json(capsys, "calibrate", str(path), "--model", "ur10e", "--effects", FULL,
                         "--outliers", "keep")
    assert rc == 0 and kept["outliers"] == [] and kept["calib"]["n"] == 300
    assert kept["valid"]["rms_mm"] > 1.5 * doc["valid"]["rms_mm"]
    # flag: every point fitted, the same points named
    rc, flagged = _run_json(capsys, "calibrate", str(path), "--model", "ur10e", "--effects",
                            FULL, "--outliers", "flag")
    assert flagged["calib"]["n"] == 300
    assert {o["pose_id"] for o in flagged["outliers"]} == named
    assert not any(o["excluded"] for o in flagged["outliers"])
    assert flagged["valid"]["rms_mm"] == pytest.approx(kept["valid"]["rms_mm"])


def test_calibrate_text_names_the_blunders(blunder_csv, capsys):
    path, ids = blunder_csv
    capsys.readouterr()
    assert main(["calibrate", str(path), "--model", "ur10e", "--effects", FULL,
                 "--solver", "ridge"]) == 0
    text = capsys.readouterr().out
    assert "look like blunders" in text and "left out of the fit" in text
    assert "along" in text and "across" in text
    with pytest.raises(SystemExit) as e:
        main(["calibrate", str(path), "--model", "ur10e", "--outliers", "drop"])
    assert e.value.code == 2 and "--outliers" in capsys.readouterr().err


def test_diagnose_names_blunders_and_the_effect(blunder_csv, capsys):
    path, ids = blunder_csv
    rc, doc = _run_json(capsys, "diagnose", str(path), "--model", "ur10e")
    assert rc == 0
    assert doc["candidates"][0]["effect"] == "compliance:3"
    named = {o["pose_id"] for o in doc["outliers"]}
    assert len(named & ids) >= 0.9 * len(ids) and len(named - ids) <= 6
    assert "left out of the ranking" in doc["outlier_check"]["message"]
    capsys.readouterr()
    assert main(["diagnose", str(path), "--model", "ur10e"]) == 0
    text = capsys.readouterr().out
    assert "measurements look like blunders" in text and "left out of the ranking" in text
    assert "Compliance of joint 3 explains" in text


def test_calibrate_json_without_blunders_has_empty_outliers(tmp_path, capsys):
    path = tmp_path / "clean.csv"
    assert main(["simulate", "--model", "ur10e", "--seed", "8", "--poses", "150",
                 "--valid", "100", "--out", str(path)]) == 0
    rc, doc = _run_json(capsys, "calibrate", str(path), "--model", "ur10e")
    assert rc == 0 and doc["outliers"] == [] and doc["outlier_check"]["clean_cloud"]
    assert "params" in doc and doc["calib"]["n"] == 150
