"""The simulated 6-DoF target: the true orientation comes from the true chain, the
tracker measures it with ~0.01 deg noise, and it must face the tracker like an SMR."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.model.transforms import (
    matrices_to_rotvecs,
    matrix_to_quat,
    quat_angle,
    quat_to_matrix,
)
from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.six_dof import SixDofTarget
from tests.sim_drivers.helpers import make_cell


@pytest.fixture(scope="module")
def truth():
    return ModelTruth.from_spec("ur10e", None, 4)


def _cell(truth, **kw):
    return SimCell(truth, seed=4, tracker_initialised=True,
                   six_dof=SixDofTarget.on_tool((0.0, 0.0, 30.0), seed=4), **kw)


def test_the_true_flange_rotation_is_the_true_chain_that_moves_the_point(truth):
    """Moving the hidden tool point 10 mm along flange axis k moves the true point 10 mm
    along column k of tracker_R_flange: the rotation and the positions are one chain."""
    rng = np.random.default_rng(0)
    lo, hi = truth.limits[:, 0], truth.limits[:, 1]
    for _ in range(3):
        q = rng.uniform(lo / 4, hi / 4)
        ctx = _cell(truth).pose_context()
        R = truth.true_flange_rotation(q, ctx)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        p0 = truth.true_point(q, ctx)
        for k, axis in enumerate("xyz"):
            x = truth.x_true.copy()
            x[truth.error_model.index(f"tool.{axis}")] += 10.0
            moved = ModelTruth(truth.model, truth.error_model, x, smr_axis=truth.smr_axis)
            np.testing.assert_allclose(moved.true_point(q, ctx) - p0, 10.0 * R[:, k],
                                       atol=1e-9)


def test_the_target_frame_is_the_nominal_mounting_turned_by_a_hidden_error():
    t = SixDofTarget.on_tool((0.0, 90.0, 0.0), seed=2, hidden_deg=0.2)
    turn = np.degrees(np.linalg.norm(matrices_to_rotvecs(t.R) - [0, np.pi / 2, 0]))
    assert 0.01 < turn < 1.5
    assert t.nominal_rotvec_deg == (0.0, 90.0, 0.0)
    np.testing.assert_allclose(t.facing_axis, t.R[:, 2])
    with pytest.raises(ValueError, match="proper 3x3 rotation"):
        SixDofTarget(flange_R_target=np.diag([1.0, 1.0, -1.0]))


def test_orientation_noise_is_about_a_hundredth_of_a_degree(truth):
    cell = _cell(truth)
    true_q = matrix_to_quat(cell.true_orientation())
    err, std = [], []
    for _ in range(300):
        r = cell.tracker_measure_pose(0.05)
        err.append(matrices_to_rotvecs(quat_to_matrix(r.quat) @ cell.true_orientation().T))
        std.append(r.std_deg)
        assert r.target == "T-Mac TMC30-F" and r.probe_id == 1
    per_axis = np.degrees(np.std(err, axis=0))
    np.testing.assert_allclose(per_axis, 0.01, rtol=0.2)
    np.testing.assert_allclose(np.mean(std, axis=0), 0.01, rtol=0.05)
    # the robot stood still: the truth did not move
    assert quat_angle(true_q, matrix_to_quat(cell.true_orientation())) < 1e-12


def test_the_target_must_face_the_tracker_and_is_measured_in_face_1_only(truth):
    cell = _cell(truth)
    assert cell.beam.cell.smr.half_angle_deg == 45.0
    np.testing.assert_allclose(cell.beam.cell.smr.axis, cell.six_dof.facing_axis)
    assert cell.beam_blocked() is None
    q0 = cell.robot_state().q
    turned = None
    for dq in (2.0, -2.0, 2.6, -2.6):  # turn the wrist until the T-Mac looks away
        q = q0.copy()
        q[4] += dq
        cell.command_move_joints(q, 1.0)
        reason = cell.beam_blocked()
        if reason and "faces" in reason:
            turned = reason
            break
    assert turned, "no wrist turn made the target face away"
    with pytest.raises(CellRefused, match="BEAM_BROKEN: the SMR faces") as e:
        cell.tracker_measure_pose(0.1)
    assert "limit 45 deg" in e.value.detail
    cell.command_move_joints(q0, 1.0)
    cell.tracker_change_face()
    with pytest.raises(CellRefused, match="FACE2_6D"):
        cell.tracker_measure_pose(0.1)


def test_without_a_6dof_target_the_cell_refuses_and_measures_positions_as_before(truth):
    with pytest.raises(CellRefused, match="NO_6DOF_TARGET"):
        SimCell(truth, seed=4, tracker_initialised=True).tracker_measure_pose(0.1)
    toy = make_cell(tracker_initialised=True, six_dof=SixDofTarget())
    with pytest.raises(CellRefused, match="NO_6DOF_TARGET"):  # a truth without orientation
        toy.tracker_measure_pose(0.1)
    # the 6D noise has its own generator: a 6D measurement leaves the position stream alone
    a, b = make_cell(seed=5, tracker_initialised=True), make_cell(seed=5, tracker_initialised=True)
    assert np.array_equal(a.tracker_measure(0.1).xyz, b.tracker_measure(0.1).xyz)


def test_the_6d_range_is_limited(truth):
    cell = SimCell(truth, seed=4, tracker_initialised=True,
                   six_dof=SixDofTarget.on_tool(seed=4, max_range_mm=1000.0))
    with pytest.raises(CellRefused, match="NO_TARGET: 6-DoF target at .* beyond the 6D range"):
        cell.tracker_measure_pose(0.1)
