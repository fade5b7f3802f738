"""The simulated robot warms up (issue 26): joint temperatures driven by motion on the
cell's clock, the hidden thermal effects they feed, and nothing of it when it is off."""

import numpy as np
import pytest

import sim_drivers.inprocess as inprocess
from drivers.errors import CommandRejected
from drivers.protocols import JointTemperatures
from drivers.urls import open_robot
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.thermal import REST_HEAT, JointThermal, thermal_effects
from sim_drivers.truth import ToyArm


def test_a_joint_relaxes_to_its_working_rise_with_its_time_constant():
    th = JointThermal(2, "cold", ambient_c=20.0, rise_k=(10.0, 4.0), tau_s=(1000.0, 100.0))
    np.testing.assert_allclose(th.at(0.0), 20.0)
    th.moved(0.0, 1e6, [0.5, 0.5])  # working pace for a long time
    np.testing.assert_allclose(th.at(1000.0), 20.0 + np.array([10.0, 4.0]) * [
        1 - np.exp(-1.0), 1 - np.exp(-10.0)])
    np.testing.assert_allclose(th.at(1e5), [30.0, 24.0])
    th.stopped(1e5)  # then it rests: cools towards the holding heat
    np.testing.assert_allclose(th.at(1e5 + 1e5), 20.0 + np.array([10.0, 4.0]) * REST_HEAT)


def test_the_temperatures_integrate_exactly_whatever_the_queries():
    a = JointThermal(3, "cold", tau_s=(600.0,))
    b = JointThermal(3, "cold", tau_s=(600.0,))
    for k in range(20):
        t0 = 30.0 * k
        for th in (a, b):
            th.moved(t0, t0 + 12.0, [0.4, 0.2, 0.0])
        for t in np.linspace(t0, t0 + 30.0, 7):
            b.at(t)  # asking never changes the answer
    np.testing.assert_allclose(a.at(650.0), b.at(650.0), rtol=0, atol=1e-12)
    assert np.all(a.at(650.0)[:2] > 20.5) and a.at(650.0)[0] > a.at(650.0)[2]


def test_a_warm_start_and_bad_starts():
    th = JointThermal(6, "warm")
    assert np.all(th.at(0.0) > 23.0)
    with pytest.raises(ValueError, match="cold, warm"):
        JointThermal(6, "tepid")


def test_off_by_default_and_the_truth_unchanged():
    truth = ModelTruth.from_spec("ur10e", None, 3)
    cell = SimCell(truth, seed=3)
    # no thermal model: the joints report the air's temperature, constant (issue 36: a
    # real UR always reports them); a controller may report none
    assert cell.thermal is None and cell.joint_temperatures().tolist() == [20.0] * 6
    assert cell.pose_context().joint_temp.tolist() == [20.0] * 6
    assert cell.robot_state().joint_temp.tolist() == [20.0] * 6
    worked = SimCell(truth, seed=3)
    worked.command_move_joints(worked.robot_state().q + 0.3, 0.5)
    worked.advance(3600.0)
    assert worked.joint_temperatures().tolist() == [20.0] * 6  # an hour later: constant
    quiet = SimCell(truth, seed=3, joint_temps=False)
    assert quiet.joint_temperatures() is None and quiet.robot_state().joint_temp is None
    assert quiet.pose_context().joint_temp is None
    warming = truth.with_thermal(3)
    k = truth.error_model.n_params
    np.testing.assert_array_equal(warming.x_true[:k], truth.x_true)
    assert warming.error_model.labels[-7:] == thermal_effects(6)
    hot = SimCell(warming, seed=3, thermal="cold")
    np.testing.assert_allclose(hot.true_point(), cell.true_point(), atol=1e-9)  # at 20 °C


def test_a_cold_robot_drifts_a_tenth_of_a_mm_or_more_as_it_works():
    truth = ModelTruth.from_spec("ur10e", None, 5).with_thermal(5)
    cell = SimCell(truth, seed=5, thermal="cold", joint_noise_rad=0.0)
    home = cell.robot_state().q
    first = cell.true_point()
    rng = np.random.default_rng(0)
    while cell.now() < 3 * 3600:  # three simulated hours of work
        cell.command_move_joints(home + rng.uniform(-0.4, 0.4, 6), 0.5)
        cell.advance(4.0)  # measure somewhere
    cell.command_move_joints(home, 0.5)
    moved = np.linalg.norm(cell.true_point() - first)
    temps = cell.joint_temperatures()
    assert np.all(temps > 25.0) and np.all(temps < 40.0), temps
    assert 0.05 < moved < 0.6, moved


def test_sim_url_thermal_option():
    inprocess.reset_cells()
    try:
        robot = open_robot("sim://robot?model=ur10e&seed=8&thermal=cold")
        robot.connect()
        assert isinstance(robot, JointTemperatures)
        assert robot.joint_temperatures() == (20.0,) * 6
        plain = open_robot("sim://robot?model=ur10e&seed=9")
        plain.connect()
        assert plain.joint_temperatures() == (20.0,) * 6  # the air's, constant
        inprocess.get_cell("quiet", 9, "ur10e", joint_temps=False)
        quiet = open_robot("sim://robot?name=quiet&seed=9")
        quiet.connect()
        with pytest.raises(CommandRejected, match="no joint temperatures"):
            quiet.joint_temperatures()
        with pytest.raises(ValueError, match="thermal=hot: expected cold or warm"):
            open_robot("sim://robot?model=ur10e&seed=10&thermal=hot")
        with pytest.raises(ValueError, match="no thermal model"):
            inprocess.with_thermal(ToyArm(), 0)
    finally:
        inprocess.reset_cells()
