"""End to end: ``cellcal capture poses`` over emScon against ``cellcal sim serve``.

The same poses captured through the emScon tracker and through the line-protocol
tracker of the same simulated cell land on the same points (the capture code is
unchanged: the tracker is just another URL).
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from daq.store import RunStore

from .capture_helpers import ROOT, read_lines, sim_serve


@pytest.mark.slow
def test_capture_poses_over_emscon_matches_the_line_tracker(tmp_path):
    cli = [sys.executable, "-m", "daq"]
    with sim_serve("--no-pty", "--no-rtde", "--seed", "4") as serve:
        urls = read_lines(serve, 4, timeout=30)
        robot, line_tracker, emscon = urls[1], urls[2], urls[3]
        assert emscon.startswith("emscon://127.0.0.1:")
        runs = {}
        for name, tracker in (("emscon", emscon), ("line", line_tracker)):
            db = tmp_path / f"{name}.db"
            out = subprocess.run(
                [*cli, "capture", "poses", "--count", "25", "--seed", "3", "--model", "ur10e",
                 "--tool-mm", "0,0,60", "--no-floor", "--robot", robot, "--tracker", tracker,
                 "--db", str(db), "--json"],
                cwd=ROOT, capture_output=True, timeout=240)
            assert out.returncode == 0, out.stderr.decode()
            summary = json.loads(out.stdout)
            assert summary["status"] == "completed" and summary["samples"] == 25
            with RunStore(db) as store:
                runs[name] = store.samples(1)
                assert store.run(1).tracker_url == tracker
    e, line = runs["emscon"], runs["line"]
    assert np.array_equal(e.point_index, line.point_index)
    diff = np.linalg.norm(e.tracker_p_smr - line.tracker_p_smr, axis=1)
    # two noisy measurements of the same point (σ ≈ 12 µm per axis) + arrival noise
    assert np.max(diff) < 0.15, diff
    assert np.all(e.std_mm > 0) and np.all(e.n_averaged == 1)
    assert np.allclose(e.temp_c, 20.0, atol=0.1)
    print(f"\nemScon vs line tracker, same 25 poses: max |Δ| {np.max(diff):.4f} mm, "
          f"mean {np.mean(diff):.4f} mm")
