"""Issue 34 at the command line: every output names the targets beyond the calibrated
envelope (calibrate's split statistics, compensate's outside_range column, --json and
stderr warning, compensate --program's report, validate's notes), --strict-range refuses
them (exit 3, nothing written), and diagnose --auto shows its range-blocked figure."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest

from calibration import ErrorModel, load_model
from calibration.fit.envelope import Envelope
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.kinematics import tool_points
from cellcal.cli import main
from cellcal.usecases.validate import waypoints_outside

ROOT = Path(__file__).resolve().parents[2]
TAUGHT = ROOT / "examples" / "taught.script"
MODEL = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))


def _q(rng, n, lo, hi):
    q = random_joints(MODEL, n, rng, max_abs_deg=170)
    q[:, 1] = np.radians(rng.uniform(lo, hi, n))
    return q


@pytest.fixture(scope="module")
def capture(tmp_path_factory) -> Path:
    """A ur10e capture: joint 2 calibrated over [-150, -90] deg, a quarter of the validation
    rows beyond it (to -80 deg)."""
    em = ErrorModel(MODEL, "geometric,base,tool,compliance:2")
    rng = np.random.default_rng(4)
    x = realistic_truth(em, rng)
    q = np.vstack([_q(rng, 150, -150, -90), _q(rng, 60, -150, -90), _q(rng, 20, -90, -80)])
    data = simulate(em, x, q, 0.015, rng, is_valid=np.arange(230) >= 150)
    path = tmp_path_factory.mktemp("env") / "capture.csv"
    data.to_csv(path)
    return path


@pytest.fixture(scope="module")
def params(capture) -> Path:
    path = capture.parent / "params.json"
    assert main(["calibrate", str(capture), "--model", "ur10e", "--effects",
                 "geometric,base,tool,compliance:2", "--out", str(path)]) == 0
    return path


def _run(capsys, *argv) -> tuple[int, str, str]:
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_calibrate_splits_the_validation_inside_and_outside_the_envelope(capture, params,
                                                                          capsys):
    rc, text, _ = _run(capsys, "calibrate", capture, "--model", "ur10e", "--json")
    assert rc == 0
    doc = json.loads(text)
    env = doc["envelope"]
    assert env["n_poses"] == 150 and env["joints_deg"][1][1] <= -90.0
    inside, outside = doc["valid_inside"], doc["valid_outside"]
    assert inside["n"] + outside["n"] == doc["valid"]["n"] == 80
    assert outside["n"] >= 20 and outside["by_quantity"]["q2"] >= 20
    rc, text, _ = _run(capsys, "calibrate", capture, "--model", "ur10e")
    assert "valid inside the envelope" in text and "valid outside the envelope" in text
    assert f"outside   {outside['n']} of 80 validation poses lie beyond the envelope" in text
    assert "envelope  q1 " in text
    # params.json records it
    recorded = json.loads(params.read_text())["envelope"]["joints_deg"]
    assert np.allclose(recorded, env["joints_deg"])


def _targets(path: Path, q_deg: np.ndarray) -> Path:
    """Targets at the nominal points of joints ``q_deg`` (the calibration's model: no
    capture tool line, the ur10e's own tool)."""
    p = tool_points(load_model("ur10e"), np.radians(q_deg))
    rows = ["pose_id,x,y,z," + ",".join(f"q{j}" for j in range(1, 7))]
    rows += [f"t{i},{','.join(f'{v:.6f}' for v in [*p[i], *q_deg[i]])}"
             for i in range(len(q_deg))]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_compensate_names_the_targets_beyond_the_envelope(params, tmp_path, capsys):
    q = np.array([[10.0, -120.0, 80.0, -40.0, 70.0, 20.0],
                  [10.0, -84.0, 80.0, -40.0, 70.0, 20.0],
                  [20.0, -110.0, 60.0, -50.0, 80.0, 10.0]])
    targets = _targets(tmp_path / "targets.csv", q)
    out = tmp_path / "comp.csv"
    rc, text, err = _run(capsys, "compensate", targets, "--params", params, "--out", out)
    assert rc == 0, err
    rows = list(csv.DictReader(io.StringIO(out.read_text())))
    assert [r["outside_range"] for r in rows] == ["", "q2", ""]
    assert "warning: 1 of 3 targets lie beyond the calibrated envelope (q2: 1)" in err
    assert "envelope  1 of 3 targets beyond the calibrated envelope: t1 (q2)" in text
    rc, text, err = _run(capsys, "compensate", targets, "--params", params, "--json")
    doc = json.loads(text)
    assert doc["n_outside_range"] == 1
    assert doc["outside_range"] == [{"pose_id": "t1", "outside_range": ["q2"]}]
    # --strict-range: refused, exit 3, nothing written
    refused = tmp_path / "refused.csv"
    rc, _, err = _run(capsys, "compensate", targets, "--params", params, "--out", refused,
                      "--strict-range", "--export-model", tmp_path / "m.yaml")
    assert rc == 3 and "data too poor" in err and "t1: q2" in err and "--strict-range" in err
    assert not refused.exists() and not (tmp_path / "m.yaml").exists()
    inside = _targets(tmp_path / "inside.csv", q[[0, 2]])
    rc, _, err = _run(capsys, "compensate", inside, "--params", params, "--strict-range")
    assert rc == 0 and "warning" not in err
    # a params.json from before the envelope: said so; --strict-range cannot check
    doc = json.loads(params.read_text())
    del doc["envelope"]
    old = tmp_path / "old.json"
    old.write_text(json.dumps(doc))
    rc, text, err = _run(capsys, "compensate", targets, "--params", old)
    assert rc == 0 and "records no calibrated envelope" in text and "warning" not in err
    rc, _, err = _run(capsys, "compensate", targets, "--params", old, "--strict-range")
    assert rc == 2 and "records no calibrated envelope" in err


def test_compensate_program_and_validate_name_the_targets_beyond_it(params, tmp_path,
                                                                    capsys):
    doc = json.loads(params.read_text())
    doc["envelope"]["joints_deg"][2] = [-140.0, -125.0]  # joint 3 of the program is beyond
    narrow = tmp_path / "narrow.json"
    narrow.write_text(json.dumps(doc))
    out = tmp_path / "out.script"
    rc, text, err = _run(capsys, "compensate", "--params", narrow, "--program", TAUGHT,
                         "--out", out)
    assert rc == 0 and out.exists()
    assert "beyond the calibrated envelope (" in text and "(q3" in text
    assert "warning:" in err and "lie beyond the calibrated envelope (q3:" in err
    rc, text, _ = _run(capsys, "compensate", "--params", narrow, "--program", TAUGHT,
                       "--out", tmp_path / "again.script", "--json")
    rep = json.loads(text)
    assert rep["n_outside_range"] >= 1
    assert all("q3" in t["outside_range"] for t in rep["targets"] if t["outside_range"])
    refused = tmp_path / "refused.script"
    rc, _, err = _run(capsys, "compensate", "--params", narrow, "--program", TAUGHT,
                      "--out", refused, "--strict-range")
    assert rc == 3 and "line " in err and not refused.exists()
    # validate's waypoints: any variant's joints beyond it
    env = Envelope.from_json(doc["envelope"], 6, "narrow.json")
    rows = [{"label": "L1", "joints_deg": {"compensated": [0, -120, -130, 0, 0, 0]}},
            {"label": "L2", "joints_deg": {"compensated": [0, -120, -100, 0, 0, 0]}}]
    assert waypoints_outside(env, rows, None) == [[], ["q3"]]


def test_diagnose_auto_shows_the_range_blocked_figure(capture, capsys):
    rc, text, _ = _run(capsys, "diagnose", capture, "--model", "ur10e", "--auto",
                       "--max-steps", "1")
    assert rc == 0
    assert "range-blocked rms mm" in text and "range-blocked: the tenth of the poses" in text
    rc, text, _ = _run(capsys, "diagnose", capture, "--model", "ur10e", "--auto",
                       "--max-steps", "1", "--json")
    doc = json.loads(text)
    assert all(s["range_blocked_rms_mm"] > 0 for s in doc["steps"])
