"""End to end: every capture routine through ``cellcal capture`` over emScon against
``cellcal sim serve`` (its own process), with the tracker's checks before each run and
the tracker's metadata stored with every point and exported.

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

from calibration import load_csv, load_model
from daq.store import RunStore

from .capture_helpers import ROOT, read_lines, sim_serve

CLI = [sys.executable, "-m", "cellcal"]
#: routine -> its flags, in the order they run into one store (frame first: the others
#: use its measurement frame); the routines pick starts the tracker sees (--tracker-at)
ROUTINES = {
    "frame": ["--line-length-mm", "400"],
    "steps": ["--count", "3"],
    "poses": ["--count", "12", "--seed", "1"],
    "iso9283": ["--cycles", "3"],
    "zero20": ["--target-xyz", "700,150,250"],
}


def _capture(routine: str, robot: str, tracker: str, db, *extra: str) -> dict:
    out = subprocess.run(
        [*CLI, "capture", routine, "--model", "ur10e", "--tool-mm", "0,0,60", "--no-floor",
         "--tracker-at", "2500,0,500",
         "--robot", robot, "--tracker", tracker, "--db", str(db), "--json", *extra],
        cwd=ROOT, capture_output=True, timeout=300)
    assert out.returncode == 0, f"{routine}: {out.stderr.decode()}"
    doc = json.loads(out.stdout)
    assert doc["status"] == "completed", doc
    return doc


@pytest.mark.slow
def test_every_routine_over_emscon_records_the_trackers_metadata(tmp_path):
    db = tmp_path / "cell.db"
    with sim_serve("--no-pty", "--no-rtde", "--seed", "4") as serve:
        urls = read_lines(serve, 4, timeout=30)
        robot, emscon = urls[1], urls[3]
        assert emscon.startswith("emscon://127.0.0.1:")
        docs = {name: _capture(name, robot, emscon, db, *flags)
                for name, flags in ROUTINES.items()}
    model = load_model("ur10e")
    with RunStore(db) as store:
        runs = store.runs()
        assert [r.routine for r in runs] == list(ROUTINES)
        for r in runs:
            check = r.context.tracker_check
            assert check.ready and check.air_source == "station", r.routine
            assert check.reflector == "RRR 1.5in" and check.face == 1
            f = check.two_face  # a compensated (simulated) tracker passes
            assert f is not None and f.diff_mm <= f.tol_mm + f.noise_mm
            assert docs[r.routine]["tracker_check"] == check.model_dump(mode="json")
            s = store.samples(r.id)
            assert len(s) == r.n_points == docs[r.routine]["samples"]
            assert s.reflector == ["RRR 1.5in"] * len(s) and np.all(s.face == 1)
            assert np.all(np.isfinite(s.cov_mm2))  # SingleMeasResult2
            np.testing.assert_allclose(np.diagonal(s.cov_mm2, axis1=1, axis2=2), s.std_mm**2)
            np.testing.assert_allclose(s.temp_c, 20.0, atol=0.1)  # the station's air
            np.testing.assert_array_equal(s.pressure_hpa, 1013.25)
            np.testing.assert_array_equal(s.humidity_pct, 45.0)
            if r.routine != "frame":
                assert r.context.frame_run == 1
    for run in range(1, len(ROUTINES) + 1):
        csv = tmp_path / f"run{run}.csv"
        out = subprocess.run([*CLI, "export", str(run), "--db", str(db), "--out", str(csv)],
                             cwd=ROOT, capture_output=True, timeout=60)
        assert out.returncode == 0, out.stderr.decode()
        data = load_csv(csv, model)
        assert data.reflector.tolist() == ["RRR 1.5in"] * data.n and np.all(data.face == 1)
        np.testing.assert_array_equal(data.pressure_hpa, 1013.25)
        np.testing.assert_array_equal(data.humidity_pct, 45.0)
        assert np.all(data.sigma_mm > 0) and np.all(np.abs(data.temp_c - 20.0) < 0.1)
    # each routine did its job over emScon (the served UR10e has realistic hidden errors:
    # its linear move is not quite straight)
    frame = docs["frame"]["frame"]
    assert frame["circle"]["rms_mm"] < 0.05 and frame["line"]["rms_mm"] < 0.2
    assert docs["zero20"]["summary"]["tip_spread_max_mm"] < 0.08
    iso = docs["iso9283"]["summary"]["iso9283"]
    assert all(iso[f"P{k}"]["n"] == 3 and iso[f"P{k}"]["RP_mm"] < 0.2 for k in range(1, 6))


@pytest.mark.slow
def test_capture_poses_over_emscon_matches_the_line_tracker(tmp_path):
    with sim_serve("--no-pty", "--no-rtde", "--seed", "4") as serve:
        urls = read_lines(serve, 4, timeout=30)
        robot, line_tracker, emscon = urls[1], urls[2], urls[3]
        runs = {}
        for name, tracker in (("emscon", emscon), ("line", line_tracker)):
            db = tmp_path / f"{name}.db"
            summary = _capture("poses", robot, tracker, db, "--count", "25", "--seed", "3")
            assert summary["samples"] == 25
            with RunStore(db) as store:
                runs[name] = store.samples(1)
                assert store.run(1).tracker_url == tracker
    e, line = runs["emscon"], runs["line"]
    assert np.array_equal(e.point_index, line.point_index)
    diff = np.linalg.norm(e.tracker_p_smr - line.tracker_p_smr, axis=1)
    # two noisy measurements of the same point (σ ≈ 12-20 µm per axis) + arrival noise
    assert np.max(diff) < 0.15, diff
    assert np.all(e.std_mm > 0) and np.all(e.n_averaged == 1)
    assert np.allclose(e.temp_c, 20.0, atol=0.1)
    # the line protocol says the face but neither reflector nor covariance
    assert np.all(line.face == 1) and line.reflector == [None] * 25
    assert np.all(np.isnan(line.cov_mm2))
    print(f"\nemScon vs line tracker, same 25 poses: max |Δ| {np.max(diff):.4f} mm, "
          f"mean {np.mean(diff):.4f} mm")


@pytest.mark.slow
def test_sim_serve_switches_make_the_checks_refuse(tmp_path):
    """``cellcal sim serve --no-weather-station --tracker-collimation-urad 40``: capture
    refuses (exit 2) without --meteo, then for the two faces; --meteo and a looser
    tolerance let the run go, and the air given is recorded with every point."""
    db = tmp_path / "cell.db"
    with sim_serve("--no-pty", "--no-rtde", "--no-weather-station",
                   "--tracker-collimation-urad", "40") as serve:
        urls = read_lines(serve, 4, timeout=30)
        base = [*CLI, "capture", "poses", "--count", "5", "--model", "ur10e", "--tool-mm",
                "0,0,60", "--no-floor", "--tracker-at", "2500,0,500", "--robot", urls[1],
                "--tracker", urls[3], "--db", str(db)]
        for extra, words in (([], "no weather station reports the air"),
                             (["--meteo", "20.5,1008,40"], "the tracker needs compensation")):
            out = subprocess.run([*base, *extra], cwd=ROOT, capture_output=True, timeout=120)
            assert out.returncode == 2 and words in out.stderr.decode(), out.stderr.decode()
        doc = _capture("poses", urls[1], urls[3], db, "--count", "5", "--meteo",
                       "20.5,1008,40", "--two-face-tol-mm", "0.5")
    f = doc["tracker_check"]["two_face"]
    assert 0.15 < f["diff_mm"] < 0.5  # 2 x 40 µrad at ~3.8 m ≈ 0.3 mm
    with RunStore(db) as store:
        assert [r.id for r in store.runs()] == [1]
        s = store.samples(1)
    np.testing.assert_array_equal(s.temp_c, 20.5)
    np.testing.assert_array_equal(s.pressure_hpa, 1008.0)
    np.testing.assert_array_equal(s.humidity_pct, 40.0)
