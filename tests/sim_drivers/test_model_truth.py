"""The simulated cell's true robot built from the calibration core."""

import numpy as np

from calibration import ErrorModel, identify
from calibration.data.dataset import Dataset
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.truth import PoseContext


def test_hidden_effect_is_in_the_truth_and_calibration_recovers_the_base():
    truth = ModelTruth.from_spec("ur10e", "compliance:3", seed=4)
    assert truth.error_model.labels[-1] == "compliance:3"
    rng = np.random.default_rng(0)
    lim = np.radians([[-170, 170], [-170, -10], [20, 160], [-170, 170], [-170, 170], [-170, 170]])
    q = rng.uniform(lim[:, 0], lim[:, 1], (150, 6))
    xyz = np.array([truth.true_point(qi, PoseContext()) for qi in q])
    data = Dataset(q=q, tracker_p_smr=xyz + rng.normal(0, 0.01, xyz.shape))
    fit = identify(ErrorModel(truth.model, "geometric,base,tool,compliance:3"), data)
    assert fit.calib["rms_mm"] < 0.03
    k = fit.error_model.index("base.x")
    np.testing.assert_allclose(fit.values[k : k + 3], truth.tracker_T_base[:3, 3], atol=0.5)


def test_cell_moves_linear_with_the_nominal_model():
    truth = ModelTruth.from_spec("ur10e", None, seed=1)
    cell = SimCell(truth, seed=1)
    q0 = np.radians([0, -90, 90, -90, -90, 0])
    cell.command_move_joints(q0, 1.0)
    start = truth.nominal_tcp(cell.robot_state().q)
    cell.command_move_linear(start + [50.0, 0, 0], 100.0)
    tcp = truth.nominal_tcp(cell.robot_state().q)
    np.testing.assert_allclose(tcp - start, [50, 0, 0], atol=0.05)  # joint noise ~1e-5 rad
