"""SimCell mechanics: motion-time model, direction tracking, temperature, tracker model."""

from __future__ import annotations

import time

import numpy as np
import pytest

from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.truth import ToyArm
from tests.sim_drivers.helpers import make_cell


def test_move_is_instantaneous_and_advances_the_simulated_clock():
    cell = make_cell(settle_s=0.5)
    t0 = cell.now()
    cell.command_move_joints([0.2, 0.1, -0.3], speed=0.1)
    assert cell.now() - t0 == pytest.approx(0.3 / 0.1 + 0.5)
    st = cell.robot_state()
    assert not st.moving and st.in_position and st.steady
    assert np.allclose(st.q, [0.2, 0.1, -0.3], atol=1e-4)
    assert np.allclose(st.tcp, cell.truth.nominal_tcp(st.q))
    ctx = cell.pose_context()
    assert ctx.direction.tolist() == [1.0, 1.0, -1.0]
    cell.command_move_joints([0.1, 0.1, -0.3], speed=0.1)
    assert cell.pose_context().direction.tolist() == [-1.0, 1.0, -1.0]  # joints 2, 3 unchanged


def test_move_linear_uses_nominal_ik():
    cell = make_cell(joint_noise_rad=0.0)
    cell.command_move_linear([500.0, 100.0, 300.0], speed=100.0)
    assert np.allclose(cell.robot_state().tcp, [500.0, 100.0, 300.0], atol=1e-6)
    with pytest.raises(CellRefused, match="UNREACHABLE"):
        cell.command_move_linear([5000.0, 0.0, 0.0], speed=100.0)


def test_limits_and_protective_stop():
    cell = make_cell()
    with pytest.raises(CellRefused, match="LIMIT"):
        cell.command_move_joints([4.0, 0.0, 0.0], 1.0)
    cell.trigger_protective_stop()
    assert cell.robot_state().protective_stop
    with pytest.raises(CellRefused, match="PROTECTIVE_STOP"):
        cell.command_move_joints([0.1, 0.0, 0.0], 1.0)
    cell.clear_protective_stop()
    cell.command_move_joints([0.1, 0.0, 0.0], 1.0)


def test_time_scale_makes_motion_take_wall_time():
    cell = SimCell(ToyArm(), seed=0, time_scale=0.01, settle_s=1.0)
    cell.command_move_joints([0.5, 0.0, 0.0], speed=0.1)  # 5 s + 1 s simulated = 60 ms wall
    st = cell.robot_state()
    assert st.moving and not st.in_position
    assert 0 < st.q[0] < 0.5
    time.sleep(0.2)
    st = cell.robot_state()
    assert not st.moving and st.steady


def test_temperature_drift_reaches_the_truth():
    cell = make_cell(temp_drift_c_per_h=2.0)
    cell.advance(1800.0)
    assert cell.temperature() == pytest.approx(21.0)
    assert cell.pose_context().temp_c == pytest.approx(21.0)


def test_tracker_sigma_and_measurement():
    cell = make_cell()
    assert cell.tracker_sigma([0.0, 0.0, 2000.0]) == pytest.approx(0.5 * (0.015 + 0.012))
    with pytest.raises(CellRefused, match="NOT_INITIALISED"):
        cell.tracker_measure(0.1)
    cell.tracker_init()
    r = cell.tracker_measure(0.5)
    assert r.n == 500
    assert np.linalg.norm(r.xyz - cell.true_point()) < 0.1
    cell.beam_ok = False
    with pytest.raises(CellRefused, match="BEAM_BROKEN"):
        cell.tracker_measure(0.1)


def test_true_point_depends_on_reported_joints_through_truth():
    cell = SimCell(ToyArm(error=(0.001, 0.0, 0.0)), seed=0, joint_noise_rad=0.0)
    cell.command_move_joints([0.3, 0.2, 0.1], 1.0)
    q = cell.robot_state().q
    expected = ToyArm(error=(0.001, 0.0, 0.0)).true_point(q, None)
    assert np.allclose(cell.true_point(), expected)
