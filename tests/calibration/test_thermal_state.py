"""The thermal state of a calibration (issue 26): params.json records the time window, the
reference temperature and the warm state of a model with drift effects (a record with a
version of its own); a
reloaded model measures time against its calibration's window; compensate uses each
target's state or the calibration's warm state and says which; older files still load."""

import json

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.compensation.compensation import load_targets
from calibration.errors import ParamsError
from calibration.exports.params_io import fit_to_dict, read_params, save_params
from calibration.fit.identify import fit_at
from calibration.fit.simulate import random_joints, realistic_truth, simulate, warmup_temperatures
from calibration.fit.thermal_state import target_state
from cellcal.cli import main
from presentation.thermal_text import state_line

UR = load_model("ur10e")
EFFECTS = "geometric,base,tool,thermal_zero:2,time_growth"
N = 80


@pytest.fixture(scope="module")
def fitted():
    em = ErrorModel(UR, EFFECTS)
    rng = np.random.default_rng(4)
    t = 1000.0 + np.arange(N) * 30.0
    data = simulate(em, realistic_truth(em, rng), random_joints(UR, N, rng), 0.015, rng,
                    t_s=t, joint_temp=warmup_temperatures(t - 1000.0, 6))
    return identify(em, data), data


def test_params_record_the_window_and_the_warm_state(fitted):
    fit, data = fitted
    doc = fit_to_dict(fit)
    th = doc["thermal"]
    assert doc["version"] == 2 and th["version"] == 1
    assert th["time_window_s"] == [1000.0, 1000.0 + (N - 1) * 30.0]
    assert th["temp_ref_c"] == 20.0
    assert th["warm_state"]["t_s"] == th["time_window_s"][1]
    last = data.joint_temp[-8:]
    np.testing.assert_allclose(th["warm_state"]["joint_temp_c"], np.median(last, axis=0))
    geometric = identify(ErrorModel(UR), data)
    assert "thermal" not in fit_to_dict(geometric)


def test_a_reloaded_model_measures_time_against_its_calibration(fitted, tmp_path):
    fit, data = fitted
    p = tmp_path / "p.json"
    save_params(fit, p)
    later = data.subset(np.arange(N) >= N // 2)  # the second half of the capture alone
    loaded = read_params(p)
    again = fit_at(loaded.error_model, later, loaded.values, outliers="keep")
    np.testing.assert_allclose(again.residuals, later.tracker_p_smr - fit.predict(later),
                               atol=1e-6)
    # a file without the record (before it) still loads: time from the new data
    doc = json.loads(p.read_text())
    doc.pop("thermal")
    old = tmp_path / "v2.json"
    old.write_text(json.dumps(doc))
    o = read_params(old)
    assert o.thermal is None
    moved = fit_at(o.error_model, later, o.values, outliers="keep").residuals - (
        later.tracker_p_smr - fit.predict(later))
    assert np.abs(moved).max() > 1e-3


def test_compensation_uses_each_target_state_else_the_warm_state(fitted, tmp_path):
    fit, _ = fitted
    rec = fit_to_dict(fit)["thermal"]
    em = fit.error_model
    cols, state = target_state(em, rec, {}, 2)
    assert state["source"] == "calibration's warm state"
    np.testing.assert_allclose(cols["joint_temp"][1], rec["warm_state"]["joint_temp_c"])
    assert cols["t_s"].tolist() == [rec["warm_state"]["t_s"]] * 2
    assert "calibration's warm state (the end of its capture)" in state_line(state)
    assert "time 100% of the capture's window (drift held at its end value)" in state_line(
        state)
    given = {"joint_temp": np.full((2, 6), 21.0), "t_s": np.array([1000.0, 1000.0])}
    cols, state = target_state(em, rec, given, 2)
    assert state["source"] == "targets" and cols is not given
    assert state_line(state).startswith("joints 21.0 °C, time 0% of the capture's window: given")
    _, state = target_state(em, rec, {"t_s": np.array([1000.0, 2000.0])}, 2)
    assert state["source"] == "mixed" and state["from_calibration"] == ["joint_temp"]
    with pytest.raises(ParamsError, match="needs joint_temp1..N in the targets"):
        target_state(em, None, {}, 2)
    assert target_state(identify(ErrorModel(UR), fit.data).error_model, None, {}, 2)[1] is None


def test_targets_carry_joint_temperatures_and_time(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("x,y,z,t_s," + ",".join(f"joint_temp{j}" for j in range(1, 7)) + "\n"
                 "600,200,400,5," + ",".join(["30"] * 6) + "\n")
    t = load_targets(p, UR)
    assert t.columns["t_s"].tolist() == [5.0] and t.columns["joint_temp"].shape == (1, 6)
    p.write_text("x,y,z,joint_temp1\n600,200,400,30\n")
    with pytest.raises(ValueError, match="joint_temp"):
        load_targets(p, UR)


@pytest.mark.parametrize(("thermal", "message"), [
    ("warm", "thermal: not an object"),
    ({"time_window_s": [5, 1]}, "ends (1) before it starts (5)"),
    ({"time_window_s": [1]}, "give [t0, t1]"),
    ({"temp_ref_c": "x"}, "temp_ref_c: 'x' is not a finite number"),
    ({"warm_state": {"joint_temp_c": [30.0]}}, "give 6 temperatures"),
    ({"version": 2}, "version: 2 is newer than this cellcal reads (1)"),
])
def test_a_bad_thermal_record_is_refused_by_name(fitted, tmp_path, thermal, message):
    doc = json.loads(json.dumps(fit_to_dict(fitted[0]), default=float))
    doc["thermal"] = thermal
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ParamsError, match="bad.json: thermal") as err:
        read_params(p)
    assert message in str(err.value)


def test_compensate_says_which_state_it_used(fitted, tmp_path, capsys):
    save_params(fitted[0], tmp_path / "p.json")
    (tmp_path / "t.csv").write_text("pose_id,x,y,z\nt1,600,200,400\n")
    args = ["compensate", str(tmp_path / "t.csv"), "--params", str(tmp_path / "p.json")]
    assert main(args) == 0
    assert "thermal   joints " in capsys.readouterr().out
    assert main([*args, "--json"]) == 0
    state = json.loads(capsys.readouterr().out)["thermal_state"]
    assert state["from_calibration"] == ["joint_temp", "t_s"]
