"""Real laser-tracker data of a UR5 (Jacobi, MIT licence): calibration and diagnosis."""

import numpy as np

from calibration import ErrorModel, identify
from calibration.diagnosis import diagnose
from calibration.kinematics import tool_points
from tests.calibration.jacobi_ur5 import GRID, RANDOM, load, ur5_with_smr


def test_geometric_calibration_and_diagnosis_on_real_ur5_data():
    model = ur5_with_smr()
    grid, target = load(GRID)
    test, test_target = load(RANDOM, valid=True)
    # the data's targets are the nominal model's own predictions (to its 0.1 mm rounding)
    assert np.abs(tool_points(model, grid.q) - target).max() < 0.1
    before = np.linalg.norm(test.tracker_p_smr - test_target, axis=1)
    assert abs(before.mean() - 2.57) < 0.02  # as published: 2.57 mm uncalibrated
    data = grid.concat(test)
    fit = identify(ErrorModel(model), data)
    assert fit.converged
    assert fit.valid["n"] == 20
    # better than the published hybrid model + neural network (0.155 mm mean)
    assert fit.valid["mean_mm"] < 0.12
    diag = diagnose(fit, data)
    assert diag.noise_floor_mm is None  # the data state no tracker uncertainty
    best = diag.best
    assert best is not None and best.confirmed and best.joint in (1, 2)
    assert best.heldout_after_mm < best.heldout_before_mm
