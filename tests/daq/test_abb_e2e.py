"""The whole workflow on the simulated ABB: the robot (a UR10e arm with realistic hidden
errors, behind a simulated IRC5) moved over Robot Web Services through the RAPID server
module, the tracker over its line protocol, every step the command line's:

``capture frame`` → ``capture poses`` → ``export`` → ``calibrate`` (its validation RMS
within 1.1x the noise floor of the data) → ``validate`` of taught targets (a targets CSV:
the compensated waypoints land within 1.3x the validation RMS, the uncompensated ones
miss by the uncalibrated error) → ``capture steps`` and ``capture zero20``.
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
from daq.store import RunStore
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import served_cell, ur10e_controller_model

SEED = 6


def _cellcal(*args: str, rc: int = 0) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        got = main([str(a) for a in args])
    assert got == rc, f"cellcal {' '.join(map(str, args))}: exit {got}\n{out.getvalue()}"
    return out.getvalue()


def _taught_targets(db, path, n=16) -> None:
    """A targets CSV of ``n`` validation poses of the capture (points the tracker saw):
    their nominal joints and where the nominal model puts the SMR."""
    model = ur10e_controller_model()
    with RunStore(db) as store:
        s = store.samples(2)
    rows = [i for i, name in enumerate(s.set_name) if name == "valid"][:n]
    q = np.asarray(s.q)[rows]
    p = tool_points(model, q)
    lines = ["pose_id,x,y,z,q1,q2,q3,q4,q5,q6"] + [
        f"T{k}," + ",".join(f"{v:.6f}" for v in [*p[k], *np.degrees(q[k])])
        for k in range(len(rows))]
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.slow
def test_the_whole_workflow_on_the_simulated_abb(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with served_cell(model_truth_factory, seed=SEED, abb=True) as stack:
        robot = stack.servers[-1]
        assert robot.url.startswith("abb://") and stack.urls[2].startswith("tracker+tcp://")
        devices = ["--robot", robot.url, "--tracker", stack.urls[2], "--db", "cell.db"]
        common = ["--model", "ur10e", "--tool-mm", "0,0,60", *devices]
        _cellcal("capture", "frame", "--tracker-at", "2500,0,500", *common)
        _cellcal("capture", "poses", "--count", "300", "--valid-fraction", "0.25", "--seed",
                 SEED, "--remeasure", "0", "--measure-s", "0.05", *common)
        _cellcal("export", "--db", "cell.db", "--out", "capture.csv")
        fit = json.loads(_cellcal("calibrate", "capture.csv", "--out", "params.json",
                                  "--json"))
        floor = load_csv(tmp_path / "capture.csv", ur10e_controller_model()).noise_floor_mm()
        valid_rms = fit["valid"]["rms_mm"]

        _taught_targets(tmp_path / "cell.db", tmp_path / "targets.csv")
        out = json.loads(_cellcal("validate", "targets.csv", "--params", "params.json",
                                  "--cycles", "2", "--remeasure", "0", *devices, "--json"))
        v = out["validation"]
        e_u, e_c = v["uncompensated"]["rms_mm"], v["compensated"]["rms_mm"]

        steps = json.loads(_cellcal("capture", "steps", "--step-mm", "40", "--count", "8",
                                    "--tracker-at", "2500,0,500", *common, "--json"))
        zero = json.loads(_cellcal("capture", "zero20", "--target-xyz", "600,200,500",
                                   "--no-floor", "--zero-average", "4", "--tracker-at",
                                   "2450,40,520", *common, "--json"))
        served = robot.controller.n_served
    print(f"\nABB over RWS: {served} moves served by the RAPID module; calibration: "
          f"validation RMS {valid_rms:.4f} mm, noise floor {floor:.4f} mm "
          f"({valid_rms / floor:.3f}x), uncalibrated {fit['uncalibrated']['valid']['rms_mm']:.3f}"
          f" mm; validate {out['waypoints']} targets x 2 cycles: uncompensated {e_u:.3f} mm, "
          f"compensated {e_c:.4f} mm ({e_c / valid_rms:.2f}x the validation RMS)")
    assert fit["calib"]["n"] + fit["valid"]["n"] == 300
    assert valid_rms <= 1.1 * floor
    assert out["status"] == "completed" and out["waypoints"] == 16
    assert e_c <= 1.3 * valid_rms, (e_c, valid_rms)
    assert 10 * valid_rms < e_u < 5.0  # the uncalibrated error, the tool's 60 mm included
    assert steps["status"] == zero["status"] == "completed"
