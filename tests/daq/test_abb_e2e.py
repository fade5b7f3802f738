"""The whole workflow on the simulated ABB: the robot (the built-in IRB 2600-12/1.65 with
realistic hidden errors, behind a simulated IRC5) moved over Robot Web Services through
the RAPID server module, the tracker over its line protocol, every step the command
line's:

``capture frame`` → ``capture poses`` → ``export`` → ``calibrate`` (its validation RMS
within 1.1x the noise floor of the data) → ``compensate --program`` of a RAPID module of
taught targets → ``validate`` of that module (the compensated waypoints land within 1.3x
the validation RMS, the module as written misses by the uncalibrated error) and of a
targets CSV → ``capture steps`` and ``capture zero20``.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

from calibration import load_csv
from calibration.model.kinematics import tool_points
from cellcal.cli import main
from cellcal.programs import rapid
from daq.store import RunStore

from .abb_program import MODEL, controller_model, irb2600_truth, taught_module
from .capture_helpers import served_cell

SEED = 6


def _cellcal(*args: str, rc: int = 0) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        got = main([str(a) for a in args])
    assert got == rc, f"cellcal {' '.join(map(str, args))}: exit {got}\n{out.getvalue()}"
    return out.getvalue()


def _taught(db, n=8) -> np.ndarray:
    """The joints of ``n`` validation poses of the capture (points the tracker saw) in the
    arm's usual configuration (in front of axis 1, the lower arm leaning forward, the upper
    arm level, axis 5 positive): a teach pendant's taught targets."""
    with RunStore(db) as store:
        s = store.samples(2)
    q = np.asarray(s.q)
    deg = np.degrees(q)
    usual = ((np.array(s.set_name) == "valid") & (np.abs(deg[:, 0]) < 90)
             & (deg[:, 1] > -30) & (np.abs(deg[:, 2]) < 60) & (deg[:, 4] > 15))
    return q[usual][:n]


def _targets_csv(q: np.ndarray, path) -> None:
    p = tool_points(controller_model(), q)
    lines = ["pose_id,x,y,z,q1,q2,q3,q4,q5,q6"] + [
        f"T{k}," + ",".join(f"{v:.6f}" for v in [*p[k], *np.degrees(q[k])])
        for k in range(len(q))]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow
def test_the_whole_workflow_on_the_simulated_abb(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with served_cell(irb2600_truth, seed=SEED, abb=True) as stack:
        robot = stack.servers[-1]
        assert robot.url.startswith("abb://") and stack.urls[2].startswith("tracker+tcp://")
        devices = ["--robot", robot.url, "--tracker", stack.urls[2], "--db", "cell.db"]
        common = ["--model", MODEL, "--tool-mm", "0,0,60", *devices]
        _cellcal("capture", "frame", "--tracker-at", "2500,0,500", *common)
        _cellcal("capture", "poses", "--count", "300", "--valid-fraction", "0.25", "--seed",
                 SEED, "--remeasure", "0", *common)
        _cellcal("export", "--db", "cell.db", "--out", "capture.csv")
        fit = json.loads(_cellcal("calibrate", "capture.csv", "--out", "params.json",
                                  "--json"))
        floor = load_csv(tmp_path / "capture.csv", controller_model()).noise_floor_mm()
        valid_rms = fit["valid"]["rms_mm"]

        q = _taught(tmp_path / "cell.db")
        module = taught_module(controller_model(), q)
        (tmp_path / "taught.mod").write_text(module)
        comp = json.loads(_cellcal("compensate", "--params", "params.json", "--program",
                                   "taught.mod", "--out", "compensated.mod", "--json"))
        program = json.loads(_cellcal("validate", "--params", "params.json", "--program",
                                      "taught.mod", "--cycles", "2", "--remeasure", "0",
                                      *devices, "--json"))
        _targets_csv(q, tmp_path / "targets.csv")
        csv = json.loads(_cellcal("validate", "targets.csv", "--params", "params.json",
                                  "--remeasure", "0", *devices, "--json"))

        steps = json.loads(_cellcal("capture", "steps", "--step-mm", "40", "--count", "8",
                                    "--tracker-at", "2500,0,500", *common, "--json"))
        zero = json.loads(_cellcal("capture", "zero20", "--target-xyz", "1000,200,800",
                                   "--no-floor", "--zero-average", "4", "--tracker-at",
                                   "2450,40,520", *common, "--json"))
        served = robot.controller.n_served
    v, w = program["validation"], csv["validation"]
    e_u, e_c = v["uncompensated"]["rms_mm"], v["compensated"]["rms_mm"]
    print(f"\nABB over RWS, {MODEL}: {served} moves served by the RAPID module; calibration: "
          f"validation RMS {valid_rms:.4f} mm, noise floor {floor:.4f} mm "
          f"({valid_rms / floor:.3f}x), uncalibrated {fit['uncalibrated']['valid']['rms_mm']:.3f}"
          f" mm; validate {program['waypoints']} RAPID targets x 2 cycles: as written "
          f"{e_u:.3f} mm, compensated {e_c:.4f} mm ({e_c / valid_rms:.2f}x the validation "
          f"RMS); the same as a targets CSV: {w['compensated']['rms_mm']:.4f} mm")
    assert fit["calib"]["n"] + fit["valid"]["n"] == 300
    assert valid_rms <= 1.1 * floor
    assert len(q) == 8 and comp["written"] and not comp["refused"]
    assert comp["n_compensated"] == comp["n_targets"] == 8
    # the module's other text unchanged: the compensated module parses to the same targets
    before = rapid.parse_program(module)
    after = rapid.parse_program((tmp_path / "compensated.mod").read_text())
    assert [t.line for t in after.targets] == [t.line for t in before.targets]
    assert program["status"] == "completed" and program["waypoints"] == 8
    assert e_c <= 1.3 * valid_rms, (e_c, valid_rms)
    assert 10 * valid_rms < e_u < 5.0  # the uncalibrated error
    assert csv["status"] == "completed"
    assert w["compensated"]["rms_mm"] <= 1.3 * valid_rms
    assert steps["status"] == zero["status"] == "completed"
