"""Full pose: orientations of a 6-DoF target in the data, the model and the fit.

The orientation Jacobians against finite differences; the measurement CSV's orientation
columns through Dataset and back; identification with positions and orientations each
weighted by its own uncertainty; the issue's acceptance on simulated data with hidden
wrist errors: position-only reaches the position floor but misses the orientation by
far more than sigma (and says so), full pose reaches both floors.
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration import load_csv, load_model
from calibration.data.dataset import Dataset
from calibration.diagnosis.orientation_blindness import orientation_blindness
from calibration.errors import InputError
from calibration.fit.error_model import ErrorModel
from calibration.fit.identify import identify
from calibration.fit.orientation_residuals import OrientationRows, rotation_residuals
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.model.transforms import matrices_to_rotvecs, rotvecs_to_matrices

SIGMA_MM, SIGMA_DEG = 0.01, 0.01
#: the floors of 3-D errors: sqrt(3) sigma
FLOOR_MM, FLOOR_DEG = np.sqrt(3) * SIGMA_MM, np.sqrt(3) * SIGMA_DEG
FULL = "geometric,base,tool,tool_rotation"
POSITION = "geometric,base,tool"


@pytest.fixture(scope="module")
def ur10e():
    return load_model("ur10e")


def _truth(model, seed=3, wrist_deg=0.08):
    """Hidden errors of real size, the wrist's angles larger; an SMR 60 mm out on the
    flange axis with a 6-DoF target turned on it."""
    em = ErrorModel(model, FULL)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    for k, name in enumerate(em.names):
        if name.split(".")[1] in ("j5", "j6") and name.endswith(("alpha", "theta")):
            x[k] = rng.normal(0, np.radians(wrist_deg))
    x[em.slices[2]] = [0.4, -0.3, 60.0]
    x[em.slices[3]] = np.radians([1.0, -2.0, 30.0])
    return em, x, rng


def _data(model, n=90, n_valid=30, seed=3, sigma_deg=SIGMA_DEG):
    em, x, rng = _truth(model, seed)
    q = random_joints(model, n, rng)
    return simulate(em, x, q, SIGMA_MM, rng, sigma_deg=sigma_deg,
                    is_valid=np.arange(n) >= n - n_valid)


def _numeric_W(em, x, bound, h=1e-6):
    W = np.zeros((bound.data.n, 3, em.n_params))
    for k in range(em.n_params):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        Rp = em.evaluate_pose(xp, bound, False)[2]
        Rm = em.evaluate_pose(xm, bound, False)[2]
        W[:, :, k] = matrices_to_rotvecs(Rp @ np.swapaxes(Rm, 1, 2)) / (2 * h)
    return W


@pytest.mark.parametrize("model_name,effects", [
    ("ur10e", FULL + ",compliance:2,scale:6,thermal,tracker_scale"),
    ("rv16", FULL + ",harmonic:4,coupling:5"),
])
def test_the_orientation_jacobian_matches_finite_differences(model_name, effects):
    model = load_model(model_name)
    em = ErrorModel(model, effects)
    rng = np.random.default_rng(1)
    x = realistic_truth(em, rng)
    q = random_joints(model, 6, rng)
    bound = em.bind(Dataset(q=q, tracker_p_smr=np.zeros((6, 3)), temp_c=np.full(6, 25.0)))
    P, J, R, W = em.evaluate_pose(x, bound)
    np.testing.assert_allclose(W, _numeric_W(em, x, bound), atol=1e-7 * np.abs(W).max())
    P2, J2 = em.evaluate(x, bound)  # the positions exactly as evaluate gives them
    assert np.array_equal(P, P2) and np.array_equal(J, J2)


def test_the_residual_jacobian_is_exact_away_from_zero(ur10e):
    em = ErrorModel(ur10e, FULL)
    rng = np.random.default_rng(2)
    x = realistic_truth(em, rng)
    bound = em.bind(Dataset(q=random_joints(ur10e, 5, rng), tracker_p_smr=np.zeros((5, 3))))
    R0 = em.evaluate_pose(x, bound, False)[2]
    turn = rotvecs_to_matrices(rng.normal(0, 0.3, (5, 3)))  # residuals of ~20 deg
    rows = OrientationRows(turn @ R0, 0.01, np.full(5, 1e-4))
    _, _, R, W = em.evaluate_pose(x, bound)
    r, Jr = rows.residual_and_jacobian(R, W)
    h = 1e-6
    for k in (0, 10, em.n_params - 1):
        xp, xm = x.copy(), x.copy()
        xp[k] += h
        xm[k] -= h
        fd = (rows.residual(em.evaluate_pose(xp, bound, False)[2])
              - rows.residual(em.evaluate_pose(xm, bound, False)[2])) / (2 * h)
        np.testing.assert_allclose(Jr[:, :, k], fd, atol=1e-6 * np.abs(Jr).max())


def test_orientation_columns_round_trip_through_the_csv(ur10e, tmp_path):
    data = _data(ur10e, n=8, n_valid=0)
    data.tool_id = np.array(["A", "B"] * 4, dtype=object)
    data.to_csv(tmp_path / "m.csv")
    back = load_csv(tmp_path / "m.csv", ur10e)
    assert np.array_equal(back.quat, data.quat / np.linalg.norm(data.quat, axis=1)[:, None])
    np.testing.assert_allclose(back.quat, data.quat, rtol=0, atol=1e-15)
    assert np.array_equal(back.sigma_deg, data.sigma_deg)
    assert list(back.tool_id) == list(data.tool_id)
    sub = back.subset([1, 3]).concat(back.subset([0]))
    assert list(sub.tool_id) == ["B", "B", "A"] and sub.quat.shape == (3, 4)


@pytest.fixture(scope="module")
def fits(ur10e):
    data = _data(ur10e)
    return data, identify(ErrorModel(ur10e, POSITION), data), identify(
        ErrorModel(ur10e, FULL), data)


def test_position_only_reaches_the_floor_but_misses_the_orientation(fits):
    data, pos, _ = fits
    assert pos.orientation_fitted is False
    assert pos.valid["rms_mm"] <= 1.1 * FLOOR_MM
    assert pos.valid["orientation_rms_deg"] > 5 * FLOOR_DEG
    assert pos.calib["orientation_rms_deg"] > 5 * FLOOR_DEG


def test_full_pose_reaches_both_floors_on_held_out_poses(fits):
    _, _, full = fits
    assert full.converged and full.orientation_fitted
    assert full.valid["rms_mm"] <= 1.1 * FLOOR_MM
    assert full.valid["orientation_rms_deg"] <= 1.1 * FLOOR_DEG
    assert full.calib["orientation_rms_deg"] <= 1.1 * FLOOR_DEG


def test_the_blindness_warning_fires_on_the_position_only_fit(fits):
    data, pos, full = fits
    b = orientation_blindness(pos)
    assert b.blind and b.hidden_deg > 2 * SIGMA_DEG > b.with_orientation_deg
    assert any(".j5." in p or ".j6." in p for p in b.parameters)
    assert "6-DoF target" in b.note() and "tool_id" in b.note()
    assert orientation_blindness(full) is None


def test_orientations_shrink_the_wrist_uncertainties(fits):
    _, pos, full = fits
    for name in ("geometric.j5.alpha", "geometric.j5.theta"):
        k = full.error_model.index(name)
        kp = pos.error_model.index(name)
        assert pos.free[kp] and full.free[k]
        assert full.std[k] < 0.5 * pos.std[kp]
    assert full.free[full.error_model.index("tool_rotation.rx")]


def test_unknown_orientation_uncertainty_is_estimated(ur10e):
    data = _data(ur10e, n=60, n_valid=20, seed=4)
    data.sigma_deg = None
    fit = identify(ErrorModel(ur10e, FULL), data)
    assert fit.valid["orientation_rms_deg"] <= 1.1 * FLOOR_DEG
    assert fit.valid["rms_mm"] <= 1.1 * FLOOR_MM


def test_tool_rotation_without_orientations_is_unidentifiable(ur10e):
    data = _data(ur10e, n=40, n_valid=0, sigma_deg=None)
    fit = identify(ErrorModel(ur10e, FULL), data)
    assert fit.orientation_fitted is None and fit.orientation_residuals is None
    assert "tool_rotation.rx" in fit.identifiability.fixed
    assert "orientation_rms_deg" not in fit.calib


def test_ridge_refuses_a_full_pose_problem(ur10e):
    with pytest.raises(InputError, match="ridge.*positions only"):
        identify(ErrorModel(ur10e, FULL), _data(ur10e, n=20, n_valid=0), "ridge")


def test_rotation_residual_is_the_turn_from_predicted_to_measured():
    rng = np.random.default_rng(0)
    R = rotvecs_to_matrices(rng.normal(size=(4, 3)))
    r = rng.normal(0, 0.01, (4, 3))
    np.testing.assert_allclose(rotation_residuals(rotvecs_to_matrices(r) @ R, R), r,
                               atol=1e-12)


def _nest_data(model, nests, n=72, seed=6):
    """Positions of SMR nests (no orientations): each row one nest, cycling."""
    from calibration.effects import NestedTool

    em = ErrorModel(model, POSITION)
    em = ErrorModel(model, [em.effects[0], em.effects[1],
                            NestedTool(model, list(nests))])
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    x[em.slices[2]] = np.concatenate(list(nests.values()))
    ids = np.array([list(nests)[i % len(nests)] for i in range(n)], dtype=object)
    data = simulate(em, x, random_joints(model, n, rng), SIGMA_MM, rng, tool_id=ids,
                    is_valid=np.arange(n) >= n - 18)
    return em, x, data


def test_smr_nests_are_each_identified_and_see_the_orientation(ur10e, tmp_path):
    from calibration.exports.params_io import read_params, save_params
    from calibration.fit.full_pose import for_data

    nests = {"A": [0.0, 0.0, 60.0], "B": [80.0, 0.0, 40.0], "C": [0.0, 80.0, 40.0]}
    _, _, data = _nest_data(ur10e, nests)
    em, notes = for_data(ErrorModel(ur10e, POSITION), data)
    assert "tool.B.x" in em.names and any("3 targets" in n for n in notes)
    fit = identify(em, data)
    assert fit.valid["rms_mm"] <= 1.1 * FLOOR_MM
    got = {k: np.array([fit.param(f"tool.{k}.{c}")[0] for c in "xyz"]) for k in nests}
    for a, b in (("A", "B"), ("A", "C"), ("B", "C")):  # the flange's own errors move all
        true = np.linalg.norm(np.subtract(nests[a], nests[b]))
        assert abs(np.linalg.norm(got[a] - got[b]) - true) < 0.05
    single = identify(ErrorModel(ur10e, POSITION), data.subset(data.tool_id == "A"))
    assert orientation_blindness(fit).hidden_deg < 0.5 * orientation_blindness(single).hidden_deg
    save_params(fit, tmp_path / "p.json")
    back = read_params(tmp_path / "p.json", model=ur10e)
    assert back.error_model.names == em.names and np.allclose(back.values, fit.values)


def test_for_data_adds_tool_rotation_for_orientations_unless_position_only(ur10e):
    from calibration.fit.full_pose import for_data

    data = _data(ur10e, n=10, n_valid=0)
    em, notes = for_data(ErrorModel(ur10e, POSITION), data)
    assert em.labels[-1] == "tool_rotation" and "full-pose" in notes[0]
    em2, notes2 = for_data(ErrorModel(ur10e, FULL), data, position_only=True)
    assert "tool_rotation" not in em2.labels and not notes2
    plain = ErrorModel(ur10e, POSITION)
    assert for_data(plain, _data(ur10e, n=10, n_valid=0, sigma_deg=None)) == (plain, [])
