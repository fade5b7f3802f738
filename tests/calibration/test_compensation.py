"""Compensation closes the loop: calibrate a simulated robot, compensate targets with the
fitted parameters, command the true robot, compare with the desired positions."""

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, identify, load_model
from calibration.compensation.compensation import CalibratedFK, compensate
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.inverse import ChainFK, solve_ik

SIGMA = 0.015


@pytest.fixture(scope="module")
def calibrated():
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(7)
    x_true = realistic_truth(em, rng)
    data = simulate(em, x_true, random_joints(m, 500, rng), SIGMA, rng,
                    is_valid=np.arange(500) >= 250)
    fit = identify(em, data)
    return m, em, x_true, fit, rng


def _points(em, x, q):
    return em.evaluate(x, em.bind(Dataset(q=q, tracker_p_smr=np.zeros((len(q), 3)))), False)[0]


def test_compensated_targets_reach_the_true_robot(calibrated):
    m, em, x_true, fit, rng = calibrated
    base = em.effects[em.labels.index("base")]
    sl = em.slices[em.labels.index("base")]
    R_fit, t_fit = base.transform(fit.values[sl])
    n = 1000
    q_nom = random_joints(m, n, rng, max_abs_deg=170)
    tool_fit = fit.values[em.index("tool.x"):em.index("tool.x") + 3]
    # desired points: where a perfect robot would put the tool; in the tracker frame they
    # are what the tracker is to see, in the robot base frame (fitted) what we compensate
    target_base = ChainFK.from_model(m, tool_fit).point(q_nom)
    desired_tracker = target_base @ R_fit.T + t_fit
    c = compensate(em, fit.values, target_base, q_nom)
    assert c.success.all(), c.reason
    assert c.orientation_kept.mean() > 0.95
    assert c.residual_mm.max() < 1e-6
    true = _points(em, x_true, c.q)
    err = np.linalg.norm(true - desired_tracker, axis=1)
    rms_true = float(np.sqrt(np.mean(err**2)))
    measured = true + rng.normal(0, SIGMA, true.shape)
    rms_measured = float(np.sqrt(np.mean(np.sum((measured - desired_tracker) ** 2, axis=1))))
    uncompensated = np.linalg.norm(_points(em, x_true, q_nom) - desired_tracker, axis=1)
    valid = fit.valid["rms_mm"]
    # as measured, the compensated error is the model's prediction error (validation RMS)
    assert rms_measured < 1.1 * valid, (rms_measured, valid)
    # without the tracker's noise it is far smaller, and far below the uncompensated error
    assert rms_true < 0.3 * valid
    assert np.sqrt(np.mean(uncompensated**2)) > 20 * rms_true


def test_orientation_is_kept_and_cmd_targets_reproduce_q(calibrated):
    m, em, _, fit, rng = calibrated
    q_nom = random_joints(m, 50, rng, max_abs_deg=150)
    nominal = ChainFK.from_model(m)
    target = CalibratedFK(em, fit.values).point(q_nom) + rng.normal(0, 0.5, (50, 3))
    c = compensate(em, fit.values, target, q_nom)
    ok = c.orientation_kept
    R_cal = CalibratedFK(em, fit.values)(c.q)[1]
    np.testing.assert_allclose(R_cal[ok], nominal(q_nom)[1][ok], atol=1e-7)
    # the controller's own IK of the corrected Cartesian target gives back q
    back = solve_ik(nominal, q_nom, c.cmd_point, c.cmd_R)
    assert back.success.mean() > 0.9  # the rest sit near a singularity
    np.testing.assert_allclose(back.q[back.success], c.q[back.success], atol=1e-5)


def test_position_only_is_minimum_norm(calibrated):
    m, em, _, fit, rng = calibrated
    q_nom = random_joints(m, 20, rng, max_abs_deg=150)
    target = ChainFK.from_model(m).point(q_nom)
    c = compensate(em, fit.values, target, q_nom, keep_orientation=False)
    assert c.success.all()
    held = compensate(em, fit.values, target, q_nom)
    dq_free = np.linalg.norm(c.q - q_nom, axis=1)
    dq_held = np.linalg.norm(held.q - q_nom, axis=1)
    assert (dq_free <= dq_held + 1e-9).all()


def test_nominal_solution_from_a_start(calibrated):
    m, em, _, fit, rng = calibrated
    q_nom = random_joints(m, 10, rng, max_abs_deg=60)
    target = ChainFK.from_model(m).point(q_nom)
    c = compensate(em, fit.values, target, q_start=np.radians([0, -60, 60, -60, -60, 0]))
    assert c.success.all()


def test_cli_compensate_and_exports(calibrated, tmp_path, capsys):
    import json

    from calibration.exports.params_io import save_params
    from calibration.exports.ur_conf import read_calibration_conf
    from cellcal.cli import main

    m, em, _, fit, rng = calibrated
    params = tmp_path / "params.json"
    save_params(fit, params)
    q_nom = random_joints(m, 30, rng, max_abs_deg=150)
    target = ChainFK.from_model(m).point(q_nom)
    csv_in = tmp_path / "targets.csv"
    lines = ["pose_id,x,y,z," + ",".join(f"q{j + 1}" for j in range(6))]
    for i in range(30):
        lines.append(",".join([f"t{i}"] + [repr(float(v)) for v in target[i]]
                              + [repr(float(v)) for v in np.degrees(q_nom[i])]))
    csv_in.write_text("\n".join(lines) + "\n")
    out = tmp_path / "compensated.csv"
    rc = main(["compensate", str(csv_in), "--params", str(params), "--out", str(out), "--json",
               "--export-model", str(tmp_path / "cal.yaml"),
               "--export-ur", str(tmp_path / "calibration.conf")])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0 and doc["n_reached"] == 30 and doc["nominal_joints"] == "given"
    assert 0.1 < doc["correction_mm"]["mean"] < 10
    text = out.read_text().splitlines()
    assert text[0].startswith("pose_id,x,y,z,q1") and len(text) == 31
    direct = compensate(em, fit.values, target, q_nom)
    q_csv = np.array([[float(v) for v in row.split(",")[4:10]] for row in text[1:]])
    np.testing.assert_allclose(np.radians(q_csv), direct.q, atol=1e-6)
    assert read_calibration_conf(tmp_path / "calibration.conf")["delta_d"].shape == (6,)
    assert "cal.yaml" in doc["model_file"]
    # bad input: exit 2 with file, line and column
    csv_in.write_text("x,y,z\n1,2,abc\n")
    assert main(["compensate", str(csv_in), "--params", str(params)]) == 2
    assert "line 2, column z: not a number" in capsys.readouterr().err
    assert main(["compensate", str(csv_in), "--params", str(params), "--out", str(params)]) == 2


def test_refused_targets_leave_no_export_behind(calibrated, tmp_path, capsys):
    """Every input is checked before anything is written: targets whose joints contradict
    their point (exit 2) leave neither the compensated CSV nor the model exports."""
    from calibration.exports.params_io import save_params
    from cellcal.cli import main

    m, em, _, fit, _ = calibrated
    params = tmp_path / "params.json"
    save_params(fit, params)
    csv_in = tmp_path / "targets.csv"
    csv_in.write_text("pose_id,x,y,z,q1,q2,q3,q4,q5,q6\np1,600,200,500,10,-80,90,-100,-90,0\n")
    outputs = [tmp_path / n for n in ("out.csv", "cal.yaml", "calibration.conf")]
    rc = main(["compensate", str(csv_in), "--params", str(params), "--out", str(outputs[0]),
               "--export-model", str(outputs[1]), "--export-ur", str(outputs[2])])
    assert rc == 2 and "--joints-tolerance-mm" in capsys.readouterr().err
    assert not any(p.exists() for p in outputs)
