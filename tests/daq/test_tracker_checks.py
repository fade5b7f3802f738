"""The tracker's checks before a run (daq.tracker_checks) through ``cellcal capture`` and
``cellcal resume``, against the simulated cell over emScon and the line protocol: each
refusal exits 2 naming the check and what to do, and stores nothing; what passes is
recorded with the run and with every point."""

from __future__ import annotations

import json

import numpy as np
import pytest

from calibration import load_csv, load_model
from cellcal.cli import main
from daq.store import RunStore
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import served_cell

METEO = (21.5, 998.0, 38.0)


def _capture(stack, db, tracker: str = "emscon", *extra, count: int = 4) -> int:
    url = {"line": stack.urls[2], "emscon": stack.urls[3]}[tracker]
    return main(["capture", "poses", "--count", str(count), "--seed", "1", "--model", "ur10e",
                 "--tool-mm", "0,0,60", "--no-floor", "--tracker-at", "2500,0,500",
                 "--robot", stack.urls[1], "--tracker", url, "--db", str(db), "--json", *extra])


def _runs(db) -> list:
    with RunStore(db) as store:
        return store.runs()


@pytest.mark.parametrize("tracker", ["emscon", "line"])
def test_no_weather_station_needs_meteo_which_every_point_records(tmp_path, capsys, tracker):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2, weather_station=False) as stack:
        assert _capture(stack, db, tracker) == 2
        err = capsys.readouterr().err
        assert "is not ready: no weather station reports the air" in err
        assert "--meteo T,P,H" in err and "nothing was stored" in err
        assert _runs(db) == []
        assert _capture(stack, db, tracker, "--meteo", ",".join(map(str, METEO))) == 0
        assert stack.cell.manual_environment == METEO  # the tracker corrects with them
    out = json.loads(capsys.readouterr().out)
    assert out["status"] == "completed"
    check = out["tracker_check"]
    assert check["air_source"] == "manual" and check["ready"] is True
    assert (check["temp_c"], check["pressure_hpa"], check["humidity_pct"]) == METEO
    with RunStore(db) as store:
        s = store.samples(1)
        assert store.run(1).context.tracker.meteo == METEO
    for got, want in zip((s.temp_c, s.pressure_hpa, s.humidity_pct), METEO, strict=True):
        np.testing.assert_array_equal(got, want)
    csv = tmp_path / "data.csv"
    assert main(["export", "--db", str(db), "--out", str(csv)]) == 0
    data = load_csv(csv, load_model("ur10e"))
    np.testing.assert_array_equal(data.pressure_hpa, METEO[1])
    np.testing.assert_array_equal(data.humidity_pct, METEO[2])
    assert data.face.tolist() == [1] * 4  # both protocols say the face


@pytest.mark.parametrize("tracker", ["emscon", "line"])
def test_meteo_is_refused_while_a_weather_station_reports(tmp_path, capsys, tracker):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2) as stack:
        assert _capture(stack, db, tracker, "--meteo", "21,1000,40") == 2
        assert stack.cell.manual_environment != (21.0, 1000.0, 40.0)
    err = capsys.readouterr().err
    assert "--meteo: the weather station of tracker" in err and "drop --meteo" in err
    assert _runs(db) == []


def test_meteo_out_of_range_is_bad_input(tmp_path, capsys):
    assert _capture_args_only(tmp_path, "--meteo", "21,10130,40") == 2
    assert "--meteo: 10130 hPa is outside [500, 1200]" in capsys.readouterr().err


def _capture_args_only(tmp_path, *extra) -> int:
    return main(["capture", "poses", "--count", "2", "--model", "ur10e", "--robot",
                 "sim://robot", "--tracker", "sim://tracker", "--db", str(tmp_path / "c.db"),
                 *extra])


def test_a_tracker_still_warming_up_refuses_the_run(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2, warmup_s=3600.0) as stack:
        assert _capture(stack, db) == 2
        assert stack.cell.n_measurements == 0
    err = capsys.readouterr().err
    assert "is not ready: still warming up: wait until the laser is stable" in err
    assert "ES_LPS_LaserHeatingUp" in err
    assert _runs(db) == []


def test_reflector_by_name_is_selected_and_recorded(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2) as stack:
        assert _capture(stack, db, "emscon", "--reflector", "rrr 0.5IN") == 0
        assert stack.cell.tracker_reflector.name == "RRR 0.5in"
        capsys.readouterr()
        assert _capture(stack, db, "emscon", "--reflector", "RRR 2in") == 2
        err = capsys.readouterr().err
        assert "knows no reflector 'RRR 2in'; it knows 'RRR 1.5in', 'RRR 0.5in'" in err
        assert _capture(stack, db, "line", "--reflector", "RRR 0.5in") == 2
        assert "cannot select a reflector" in capsys.readouterr().err
    with RunStore(db) as store:
        assert len(store.runs()) == 1
        s = store.samples(1)
        assert store.run(1).context.tracker_check.reflector == "RRR 0.5in"
    assert s.reflector == ["RRR 0.5in"] * 4
    assert np.all(np.isfinite(s.cov_mm2))  # emScon's SingleMeasResult2: the covariance
    np.testing.assert_allclose(np.diagonal(s.cov_mm2, axis1=1, axis2=2), s.std_mm**2)


@pytest.mark.parametrize("tracker", ["emscon", "line"])
def test_two_face_check_refuses_a_tracker_that_needs_compensation(tmp_path, capsys, tracker):
    db = tmp_path / "cell.db"
    c = 80e-6  # rad: turns the point by +c in face 1, -c in face 2
    with served_cell(model_truth_factory, seed=2, tracker_collimation_rad=c) as stack:
        p = stack.cell.true_point()
        assert _capture(stack, db, tracker) == 2
        assert stack.cell.tracker_face == 1  # turned back to the face it was in
        err = capsys.readouterr().err
        assert "two-face check" in err and "the tracker needs compensation" in err
        assert _runs(db) == []
        diff = float(err.split("measured the same point ")[1].split(" mm")[0])
        # the truth: the two faces put the point 2c apart about the vertical axis
        assert diff == pytest.approx(2 * np.sin(c) * np.hypot(p[0], p[1]), abs=0.06)
        # a looser tolerance, or no check, lets the run go
        assert _capture(stack, db, tracker, "--two-face-tol-mm", "1.0") == 0
        out = json.loads(capsys.readouterr().out)
        assert out["tracker_check"]["two_face"]["tol_mm"] == 1.0
        assert _capture(stack, db, tracker, "--no-two-face-check") == 0
        assert json.loads(capsys.readouterr().out)["tracker_check"]["two_face"] is None


def test_a_compensated_tracker_passes_the_two_face_check(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2) as stack:
        for _ in range(3):
            p = stack.cell.true_point()  # where the robot stands: the point checked
            assert _capture(stack, db, count=2) == 0
            f = json.loads(capsys.readouterr().out)["tracker_check"]["two_face"]
            assert f["diff_mm"] <= f["tol_mm"] + f["noise_mm"]
            assert f["distance_mm"] == pytest.approx(np.linalg.norm(p), abs=0.1)
        assert stack.cell.tracker_face == 1
    with RunStore(db) as store:
        assert all(store.samples(r.id).face.tolist() == [1, 1] for r in store.runs())


def test_resume_checks_the_tracker_again_with_the_runs_setup(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2, weather_station=False) as stack:
        stack.faults.arm("pstop")  # the first move: the run pauses
        assert _capture(stack, db, "emscon", "--meteo", "20,1010,50") == 1
        stack.cell.clear_protective_stop()
        stack.cell.set_tracker_environment(25.0, 1013.0, 45.0)  # someone changed it
        capsys.readouterr()
        assert main(["resume", "--db", str(db), "--json", "--meteo", "20,1010"]) == 2
        assert "--meteo: expected 3 numbers" in capsys.readouterr().err
        # the run's --meteo is given to the tracker again
        assert main(["resume", "--db", str(db), "--json"]) == 0
        assert stack.cell.manual_environment == (20.0, 1010.0, 50.0)
    assert json.loads(capsys.readouterr().out)["status"] == "completed"
    with RunStore(db) as store:
        s = store.samples(1)
        kinds = [k for _, _, k, _ in store.interruptions(1)]
    np.testing.assert_array_equal(s.pressure_hpa, 1010.0)
    assert kinds[0] == "protective_stop" and kinds[-1] == "resume"


def test_resume_refuses_a_tracker_that_is_not_ready(tmp_path, capsys):
    db = tmp_path / "cell.db"
    with served_cell(model_truth_factory, seed=2) as stack:
        stack.faults.arm("pstop")
        assert _capture(stack, db) == 1
        stack.cell.clear_protective_stop()
        stack.cell.warmup_s = stack.cell.now() + 3600.0  # power-cycled: warming up again
        capsys.readouterr()
        assert main(["resume", "--db", str(db), "--json"]) == 2
        assert "still warming up" in capsys.readouterr().err
        stack.cell.warmup_s = 0.0
        assert main(["resume", "--db", str(db), "--json"]) == 0
    with RunStore(db) as store:
        kinds = [k for _, _, k, _ in store.interruptions(1)]
        assert store.run(1).status == "completed" and store.n_samples(1) == 4
    assert "not_ready" in kinds
