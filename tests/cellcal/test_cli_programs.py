"""``cellcal compensate --program`` and ``cellcal validate`` at the command line, in process:
the report and its exit codes (0, 1 with nothing written, 0 with --allow-partial, 2 with
the line), KRL's frames file, and a validation run on the in-process simulated cell (its
run stored, its summary the figures the command prints)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.exports.params_io import save_params
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from cellcal.cli import main
from daq.store import RunStore

ROOT = Path(__file__).resolve().parents[2]
TAUGHT = ROOT / "examples" / "taught.script"
KRL = ROOT / "tests" / "programs" / "corpus" / "taught.dat"


@pytest.fixture(scope="module")
def params(tmp_path_factory) -> Path:
    """A ur10e calibration with the SMR at 0, 0, 60 mm and a compliant joint 2."""
    model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
    em = ErrorModel(model, "geometric,base,tool,compliance:2")
    rng = np.random.default_rng(2)
    x = realistic_truth(em, rng)
    q = random_joints(model, 160, rng, max_abs_deg=170)
    fit = identify(em, simulate(em, x, q, 0.015, rng, is_valid=np.arange(160) >= 120))
    path = tmp_path_factory.mktemp("cal") / "params.json"
    save_params(fit, path)
    return path


def _run(capsys, *argv) -> tuple[int, str, str]:
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_compensate_program_writes_and_reports(params, tmp_path, capsys):
    out = tmp_path / "out.script"
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", TAUGHT,
                       "--out", out)
    assert rc == 0, text
    assert "8 targets found, 8 compensated" in text and f"wrote {out}" in text
    assert "the point the calibration measured" in text
    lines_in, lines_out = TAUGHT.read_text().splitlines(), out.read_text().splitlines()
    assert len(lines_in) == len(lines_out)
    changed = [k for k, (a, b) in enumerate(zip(lines_in, lines_out, strict=True)) if a != b]
    assert all("# cellcal: was " in lines_out[k] for k in changed) and len(changed) == 8
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", TAUGHT,
                       "--out", tmp_path / "again.script", "--json")
    doc = json.loads(text)
    assert rc == 0 and doc["written"] and doc["n_compensated"] == 8 and not doc["refused"]
    assert all(0.1 < t["correction_mm"] < 20 for t in doc["targets"])


def test_a_target_computed_at_run_time(params, tmp_path, capsys):
    prog = tmp_path / "p.script"
    prog.write_text(TAUGHT.read_text().replace("  movej(home)\nend",
                                               "  movel(get_actual_tcp_pose())\nend"))
    out = tmp_path / "out.script"
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", prog,
                       "--out", out)
    assert rc == 1 and not out.exists()
    assert "line 18: movel(get_actual_tcp_pose())" in text and "nothing written" in text
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", prog,
                       "--out", out, "--allow-partial")
    assert rc == 0 and out.exists() and "partly compensated" in text
    assert "get_actual_tcp_pose()" in out.read_text().splitlines()[17]


def test_a_program_that_does_not_parse_names_the_line(params, tmp_path, capsys):
    prog = tmp_path / "p.script"
    prog.write_text(TAUGHT.read_text().replace("a=1.4, v=1.05)", "a=1.4, v=1.05"))
    rc, _, err = _run(capsys, "compensate", "--params", params, "--program", prog,
                      "--out", tmp_path / "o.script")
    assert rc == 2 and "line 6" in err and "Traceback" not in err


def test_krl_points_with_their_tool(params, tmp_path, capsys):
    frames = tmp_path / "frames.yaml"
    frames.write_text("tools:\n  1: [0, 0, 60, 0, 0, 0]\n")
    out = tmp_path / "out.dat"
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", KRL,
                       "--out", out, "--json")
    doc = json.loads(text)
    assert rc == 1 and any("TOOL_DATA[1]" in r["reason"] for r in doc["refused"])
    rc, text, _ = _run(capsys, "compensate", "--params", params, "--program", KRL,
                       "--out", out, "--frames", frames, "--allow-partial", "--json")
    doc = json.loads(text)
    assert rc == 0 and doc["written"] and doc["n_compensated"] >= 5
    assert not any("TOOL_DATA" in r["reason"] for r in doc["refused"])


def test_validate_runs_the_waypoints_on_the_cell(params, tmp_path, capsys):
    db = tmp_path / "cell.db"
    devices = ["--robot", "sim://robot?model=ur10e&seed=3&tool=0,0,60",
               "--tracker", "sim://tracker?seed=3", "--db", db]
    rc, _, err = _run(capsys, "capture", "frame", "--model", "ur10e", "--tool-mm", "0,0,60",
                      "--tracker-at", "2500,0,500", *devices)
    assert rc == 0, err
    rc, text, err = _run(capsys, "validate", "--params", params, "--program", TAUGHT,
                         "--variants", "uncompensated,compensated", "--remeasure", "0",
                         *devices)
    assert rc == 0, err
    assert "run 2 (validate): completed, 16/16 points stored" in text
    assert "waypoint error, in the calibration's base frame:" in text
    with RunStore(db) as store:
        run = store.run(2)
        figures = run.summary.validation
        assert list(figures) == ["uncompensated", "compensated"]
        assert figures["compensated"].n == 8 and len(figures["compensated"].waypoints) == 8
        assert run.summary.validation_frame == "the calibration's base frame"
        assert run.routine == "validate"
    # a targets CSV (points and their nominal joints), dry-run: planned, nothing moves
    from calibration.model.kinematics import tool_points

    model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
    q = np.array([[0.6007, -1.9745, -2.2809, 1.2080, 0.9082, -1.6289]])
    p = tool_points(model, q)[0]
    csv = tmp_path / "targets.csv"
    csv.write_text("pose_id,x,y,z,q1,q2,q3,q4,q5,q6\nA," + ",".join(
        f"{v:.6f}" for v in [*p, *np.degrees(q[0])]) + "\n")
    rc, text, err = _run(capsys, "validate", csv, "--params", params, "--cycles", "3",
                         "--dry-run", *devices)
    assert rc == 0, err
    assert text.startswith("validate: 9 points") and "plan ok: 9 targets" in text


def _thermal(params: Path, path: Path) -> Path:
    """``params`` with thermal growth from the joint temperatures and the warm state it was
    fitted against (issue 36: a program has no joint temperatures to give)."""
    doc = json.loads(params.read_text())
    doc["effects"] = [*doc["effects"], "thermal_growth"]
    doc["parameters"].append({"name": "thermal_growth.k", "value": 1.5e-5, "std": 1e-6,
                              "unit": "1/K", "identifiable": True, "weak": None})
    doc["thermal"] = {"version": 1, "temp_ref_c": 20.0,
                      "warm_state": {"joint_temp_c": [26.0, 27.5, 27.0, 25.0, 24.5, 24.0]}}
    path.write_text(json.dumps(doc))
    return path


def test_a_program_is_compensated_at_the_calibrations_warm_state(params, tmp_path, capsys):
    warm = _thermal(params, tmp_path / "warm.json")
    rc, text, err = _run(capsys, "compensate", "--params", warm, "--program", TAUGHT,
                         "--out", tmp_path / "warm.script")
    assert rc == 0, err
    assert ("note: thermal: joints 24.0–27.5 °C: the calibration's warm state (the end of its "
            "capture)") in text
    rc, _, _ = _run(capsys, "compensate", "--params", params, "--program", TAUGHT, "--out",
                    tmp_path / "cold.script")
    # the arm grown by k · 5.7 K: the two programs differ by its growth, tenths of a mm
    moved = [a != b for a, b in zip((tmp_path / "warm.script").read_text().splitlines(),
                                    (tmp_path / "cold.script").read_text().splitlines(),
                                    strict=True)]
    assert rc == 0 and sum(moved) == 8
    db = tmp_path / "cell.db"
    devices = ["--robot", "sim://robot?model=ur10e&seed=4&tool=0,0,60",
               "--tracker", "sim://tracker?seed=4", "--db", db]
    assert _run(capsys, "capture", "frame", "--model", "ur10e", "--tool-mm", "0,0,60",
                "--tracker-at", "2500,0,500", *devices)[0] == 0
    rc, text, err = _run(capsys, "validate", "--params", warm, "--program", TAUGHT,
                         "--dry-run", *devices)
    assert rc == 0, err
    assert "thermal: compensated for joints 24.0–27.5 °C" in text + err
    from calibration.model.kinematics import tool_points  # a targets CSV: the same state

    q = np.array([[0.6007, -1.9745, -2.2809, 1.2080, 0.9082, -1.6289]])
    p = tool_points(load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0)), q)[0]
    csv = tmp_path / "targets.csv"
    csv.write_text("pose_id,x,y,z,q1,q2,q3,q4,q5,q6\nA," + ",".join(
        f"{v:.6f}" for v in [*p, *np.degrees(q[0])]) + "\n")
    rc, text, err = _run(capsys, "validate", csv, "--params", warm, "--dry-run", *devices)
    assert rc == 0, err
    assert "thermal: compensated for joints 24.0–27.5 °C" in err
