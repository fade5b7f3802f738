"""``cellcal compensate --program`` on ABB RAPID modules, in process: a module with targets
of every kind compensates to the same targets as ``cellcal compensate`` on a targets CSV
of the same points and taught joints (0.01 mm), the report and its exit codes, a module
written by a compensation refused as input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.compensation.pose_compensation import NominalTcpFK
from calibration.exports.params_io import save_params
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.transforms import matrix_to_quat, quat_angle, rotvec_to_matrix
from cellcal.cli import main
from cellcal.programs import rapid
from cellcal.programs.poses import rapid_to_T

ROOT = Path(__file__).resolve().parents[2]
CORPUS = ROOT / "tests" / "programs" / "corpus"
CELL, REFUSED = CORPUS / "cell.mod", CORPUS / "refused.mod"

#: the joints (deg) each pose target of cell.mod was taught at, in the order moved to
TAUGHT_DEG = {
    "robtarget pApproach": (10, 5, -10, 20, 60, -30),
    "robtarget pPick": (-25, 30, -5, -40, 55, 40),
    "robtarget pPlace": (-40, 25, 0, 30, 70, -60),
    "robtarget pPath{1}": (20, 10, 5, 10, 70, 15),
    "robtarget pPath{2}": (28, 15, 0, 15, 65, 10),
    "robtarget pPath{3}": (35, 20, -8, 25, 62, 5),
    "robtarget pLower": (50, 40, -30, -60, -45, 120),
    "MoveC@33": (5, 20, -20, 0, 80, 0),
    "MoveC@34": (15, 25, -25, 5, 75, -5),
    "MoveL@36": (-10, 35, -35, -15, 50, 100),
}


@pytest.fixture(scope="module")
def params(tmp_path_factory) -> Path:
    """An IRB 2600 calibration with the SMR at 0, 0, 60 mm (cell.mod's tSmr)."""
    model = load_model("irb2600_12_165").with_changes(tool=(0.0, 0.0, 60.0))
    em = ErrorModel(model, "geometric,base,tool,harmonic:2")
    rng = np.random.default_rng(3)
    x = realistic_truth(em, rng)
    q = random_joints(model, 200, rng, max_abs_deg=170)
    fit = identify(em, simulate(em, x, q, 0.015, rng, is_valid=np.arange(200) >= 150))
    path = tmp_path_factory.mktemp("abb") / "params.json"
    save_params(fit, path)
    return path


def _run(capsys, *argv) -> tuple[int, str]:
    rc = main([str(a) for a in argv])
    return rc, capsys.readouterr().out


def _key(t) -> str:
    return t.context if t.context.split()[0] in ("robtarget", "jointtarget") \
        else f"{t.context}@{t.line}"


def _base_T(t) -> np.ndarray:
    """The target's pose in the robot's base frame (its work object's frame applied)."""
    B = np.eye(4) if t.extra["base"] is None else rapid_to_T(t.extra["base"])
    return B @ rapid_to_T(t.values)


def _targets_csv(program, path: Path) -> None:
    """The module's targets as a targets CSV: the TCP point in the base frame and the
    joints each was taught at (a joint target's own)."""
    fk = NominalTcpFK(load_model("irb2600_12_165"), np.array([0.0, 0.0, 60.0]))
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["pose_id", "x", "y", "z", *(f"q{j}" for j in range(1, 7)), "payload_kg"])
        for t in program.targets:
            q = t.values if t.kind == "joints" else TAUGHT_DEG[_key(t)]
            taught = fk.chain(np.radians([q]))
            xyz = taught.base_p_tcp[0] if t.kind == "joints" else _base_T(t)[:3, 3]
            # the corpus is what it says: the taught joints reach the written target
            assert np.linalg.norm(taught.base_p_tcp[0] - xyz) < 0.01
            w.writerow([f"L{t.line}.{t.index}", *xyz, *q, t.payload_kg])


def test_module_compensates_as_the_targets_csv(params, tmp_path, capsys):
    out, comp = tmp_path / "cell.mod", tmp_path / "comp.csv"
    rc, text = _run(capsys, "compensate", "--params", params, "--program", CELL, "--out", out)
    assert rc == 0, text
    assert "rapid, 12 targets found, 12 compensated" in text
    assert "the TCP (0, 0, 60 mm) is the point the calibration measured" in text
    before = rapid.parse_program(CELL.read_text())
    after = rapid.parse_program(out.read_text())
    _targets_csv(before, tmp_path / "targets.csv")
    rc, text = _run(capsys, "compensate", tmp_path / "targets.csv", "--params", params,
                    "--out", comp)
    assert rc == 0, text
    with comp.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(after.targets) == 12
    worst_mm = worst_deg = 0.0
    for t, row in zip(after.targets, rows, strict=True):
        q_csv = np.array([float(row[f"q{j}"]) for j in range(1, 7)])
        cmd = np.array([float(row[k]) for k in ("cmd_x", "cmd_y", "cmd_z")])
        if t.kind == "joints":
            np.testing.assert_allclose(t.values, q_csv, atol=1e-5)
            fk = NominalTcpFK(load_model("irb2600_12_165"), np.array([0.0, 0.0, 60.0]))
            got = fk.chain(np.radians([t.values])).base_p_tcp[0]
        else:
            T = _base_T(t)
            got = T[:3, 3]
            rv = np.radians([float(row[k]) for k in ("cmd_rx", "cmd_ry", "cmd_rz")])
            R_csv = rotvec_to_matrix(rv)
            worst_deg = max(worst_deg, float(np.degrees(quat_angle(
                matrix_to_quat(T[:3, :3]), matrix_to_quat(R_csv)))))
        worst_mm = max(worst_mm, float(np.linalg.norm(got - cmd)))
    assert worst_mm < 0.01 and worst_deg < 1e-3, (worst_mm, worst_deg)
    # the rest of the module is the same, byte for byte, and its quaternions are unit
    assert all(abs(np.linalg.norm(t.values[3:]) - 1) < 1e-6 for t in after.targets
               if t.kind == "pose")
    lines_in, lines_out = CELL.read_text().splitlines(), out.read_text().splitlines()
    changed = [k for k, (a, b) in enumerate(zip(lines_in, lines_out, strict=True)) if a != b]
    assert all("! cellcal: was " in lines_out[k] or not lines_out[k].rstrip().endswith(";")
               for k in changed)
    # compensated already: refused as input
    rc = main(["compensate", "--params", str(params), "--program", str(out), "--out",
               str(tmp_path / "twice.mod")])
    assert rc == 2 and "compensated already" in capsys.readouterr().err


def test_refused_targets_exit_1_and_nothing_is_written(params, tmp_path, capsys):
    out = tmp_path / "refused.mod"
    rc, text = _run(capsys, "compensate", "--params", params, "--program", REFUSED,
                    "--out", out)
    assert rc == 1 and not out.exists() and "nothing written" in text
    assert "line 18: MoveL pB, v100, fine, tFixed: tooldata tFixed: a stationary tool" in text
    rc, text = _run(capsys, "compensate", "--params", params, "--program", REFUSED,
                    "--out", out, "--allow-partial", "--json")
    doc = json.loads(text)
    assert rc == 0 and doc["written"] and out.exists()
    assert [r["line"] for r in doc["refused"]] == [15, 17, 18, 19, 20, 21, 22, 26, 27, 31]
    assert any("GripLoad" in n for n in doc["notes"])
    same = out.read_text().splitlines()
    assert same[14] == REFUSED.read_text().splitlines()[14]  # the Offs() move as it was


def test_language_flag_reads_any_suffix_as_rapid(params, tmp_path, capsys):
    src = tmp_path / "cell.txt"
    src.write_bytes(CELL.read_bytes())
    rc, text = _run(capsys, "compensate", "--params", params, "--program", src,
                    "--language", "rapid", "--out", tmp_path / "out.txt")
    assert rc == 0 and "rapid, 12 targets found" in text
