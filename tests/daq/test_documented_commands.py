"""The capture commands the README and docs/capture.md show, as written, on the honest
simulated cell (``cellcal sim serve --seed 4 --hidden backlash:2``: its tracker stands at
2500,0,500)."""

from __future__ import annotations

import json

import pytest

from daq.cli import main
from sim_drivers.model_truth import model_truth_factory
from sim_drivers.serve import ServeConfig, SimStack

from .capture_helpers import FREE_PORTS


@pytest.mark.slow
def test_readme_and_capture_doc_commands(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    cfg = ServeConfig(seed=4, hidden="backlash:2", ports=dict(FREE_PORTS), pty=False)
    with SimStack(cfg, truth_factory=model_truth_factory) as stack:
        R, T = stack.urls[0], stack.urls[2]
        cell = ["--robot", R, "--tracker", T, "--db", "cell.db"]
        # README: frame, poses, runs, export, calibrate, diagnose, zero20, zero
        assert main(["capture", "frame", "--model", "ur10e", "--tool-mm", "0,0,60",
                     "--tracker-at", "2500,0,500", *cell]) == 0
        assert main(["capture", "poses", "--model", "ur10e", "--tool-mm", "0,0,60", "--count",
                     "400", "--valid-fraction", "0.25", "--seed", "4", *cell]) == 0
        out = capsys.readouterr().out
        assert "run 2 (poses): completed, 400/400 points stored" in out
        assert main(["runs", "--db", "cell.db"]) == 0
        assert "beam breaks" in capsys.readouterr().out
        assert main(["export", "--db", "cell.db", "--out", "capture.csv"]) == 0
        assert main(["calibrate", "capture.csv", "--model", "ur10e", "--json"]) == 0
        fit = json.loads(capsys.readouterr().out)
        assert fit["calib"]["n"] == 300 and fit["valid"]["n"] == 100
        assert main(["diagnose", "capture.csv", "--model", "ur10e", "--json"]) == 0
        diag = json.loads(capsys.readouterr().out)
        assert diag["candidates"][0]["effect"] == "backlash:2"
        # docs/capture.md: the dry run with a figure, poses, resume of a completed run
        capsys.readouterr()
        poses = ["capture", "poses", "--count", "200", "--seed", "1", "--valid-fraction", "0.2",
                 "--model", "ur10e", "--tool-mm", "0,0,60", "--no-floor", *cell]
        assert main([*poses, "--dry-run", "--plot", "plan.png"]) == 0
        out = capsys.readouterr().out
        assert "200 of 200 points visible" not in out  # the spares are counted too
        assert "points visible" in out and "not visible" not in out
        assert (tmp_path / "plan.png").stat().st_size > 10000
        assert main(poses) == 0
        assert main(["resume", "--db", "cell.db"]) == 0
        assert "already completed" in capsys.readouterr().err
    # README and docs/capture.md: zero20 then zero (on a cell without the hidden backlash,
    # which the closed loop does not converge through), the frame run's tracker known
    # from the store, or given
    cfg = ServeConfig(seed=4, ports=dict(FREE_PORTS), pty=False)
    with SimStack(cfg, truth_factory=model_truth_factory) as stack:
        cell = ["--robot", stack.urls[1], "--tracker", stack.urls[2], "--db", "zero.db"]
        assert main(["capture", "zero20", "--target-xyz", "700,150,250", "--model", "ur10e",
                     "--tool-mm", "0,0,60", "--no-floor", "--tracker-at", "2500,0,500",
                     *cell]) == 0
        # the cell's robot has every realistic geometric error, not only zero offsets: the
        # zero-point fit may well call its data too poor (3)
        assert main(["zero", "--db", "zero.db", "--json"]) in (0, 3)
        assert main(["capture", "frame", "--model", "ur10e", "--tool-mm", "0,0,60",
                     "--tracker-at", "2500,0,500", *cell]) == 0
        assert main(["capture", "zero20", "--target-xyz", "700,150,250", "--model", "ur10e",
                     "--tool-mm", "0,0,60", "--no-floor", *cell]) == 0
        assert main(["zero", "--db", "zero.db", "--method", "both", "--out",
                     "ur10e-rezeroed.yaml", "--json"]) in (0, 3)
