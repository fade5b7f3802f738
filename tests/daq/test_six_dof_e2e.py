"""End to end, full pose: ``cellcal sim serve --six-dof`` (a simulated T-Mac on the tool,
its own process), ``cellcal capture poses --six-dof`` over emScon
(``ES_MM_6DStationary``), ``cellcal export`` (qw..qz, sigma_deg) and ``cellcal
calibrate`` (full pose by default): the orientations travel from the tracker's wire to
the fit, which reaches both noise floors on held-out poses."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from calibration import load_csv, load_model
from daq.store import RunStore

from .capture_helpers import ROOT, read_lines, sim_serve

CLI = [sys.executable, "-m", "cellcal"]


def _run(*argv: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *argv], cwd=ROOT, capture_output=True, timeout=timeout)


@pytest.mark.slow
def test_six_dof_capture_export_and_full_pose_calibration(tmp_path):
    db, csv = tmp_path / "cell.db", tmp_path / "six.csv"
    with sim_serve("--no-pty", "--no-rtde", "--seed", "5", "--six-dof") as serve:
        urls = read_lines(serve, 4, timeout=30)
        robot, emscon = urls[1], urls[3]
        out = _run("capture", "poses", "--model", "ur10e", "--tool-mm", "0,0,60",
                   "--no-floor", "--tracker-at", "2500,0,500", "--count", "80",
                   "--valid-fraction", "0.3", "--seed", "2", "--robot", robot,
                   "--tracker", emscon, "--db", str(db), "--six-dof", "--json")
    assert out.returncode == 0, out.stderr.decode()
    assert json.loads(out.stdout)["status"] == "completed"
    with RunStore(db) as store:
        s = store.samples(1)
        assert s.quat is not None and np.all(np.isfinite(s.quat))
        np.testing.assert_allclose(s.sigma_deg, 0.01, rtol=0.5)
    assert _run("export", "1", "--db", str(db), "--out", str(csv)).returncode == 0
    data = load_csv(csv, load_model("ur10e"))
    assert data.quat is not None and data.sigma_deg is not None
    out = _run("calibrate", str(csv), "--model", "ur10e", "--json")
    assert out.returncode == 0, out.stderr.decode()
    doc = json.loads(out.stdout)
    assert doc["effects"][-1] == "tool_rotation" and doc["orientation"]["fitted"]
    floor_deg = doc["orientation"]["noise_floor_deg"]
    assert doc["valid"]["rms_mm"] <= 1.1 * doc["noise_floor_mm"]
    assert doc["valid"]["orientation_rms_deg"] <= 1.1 * floor_deg
