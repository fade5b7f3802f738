"""Every robot driver keeps the RobotDriver contract (drivers/protocols.py) on the simulated
cell: the same calls, the same blocking, the same errors. One test, every driver
(:data:`tests.drivers.rigs.ROBOTS`); what only one driver does is in its own test file."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    LimitError,
    ProtectiveStop,
)
from drivers.protocols import (
    STOP_AFTER_TIMEOUT_S,
    CommandedPosition,
    DeviceIdentity,
    Identified,
    JointTemperatures,
    RobotDriver,
)
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from tests.drivers.rigs import ROBOTS, having, serve_robot
from tests.sim_drivers.helpers import MARGIN, elapsed_below, make_cell


def _wait_for(predicate, what: str, timeout: float = 5.0 + MARGIN) -> None:
    """Poll ``predicate`` until true (state the simulator shows a moment later)."""
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"never {what}"
        time.sleep(0.005)


def test_is_a_robot_driver_that_reads_the_controller(robot):
    rob, cell = robot.driver, robot.cell
    assert isinstance(rob, robot.kind.cls) and isinstance(rob, RobotDriver)
    assert isinstance(rob, CommandedPosition)
    assert rob.n_joints == 3
    reading = rob.read_joints()
    assert reading.q.shape == (3,)
    np.testing.assert_allclose(reading.q, cell.robot_state().q, atol=robot.tol["q"])
    assert abs(reading.timestamp - time.time()) < 30.0  # a wall-clock stamp, not a speed bound
    st = rob.status()
    assert st.connected and st.in_position and not st.moving and not st.protective_stop


def test_move_returns_arrived_and_settled(robot):
    rob, cell = robot.driver, robot.cell
    target = np.array([0.3, 0.2, -0.4])
    rob.move_joints(target, speed=0.5, timeout=5.0)
    r = rob.read_joints()  # right after the return: there, no wait
    np.testing.assert_allclose(r.q, target, atol=1e-4)  # cell repeatability 1e-5 rad
    np.testing.assert_allclose(r.q, cell.robot_state().q, atol=robot.tol["q"])
    np.testing.assert_allclose(rob.read_tcp(), cell.truth.nominal_tcp(r.q), atol=robot.tol["tcp"])
    st = rob.status()
    assert st.connected and st.in_position and not st.moving and not st.protective_stop
    assert st.error_code == 0
    rob.wait_settled(timeout=1.0)  # settled already: returns at once
    rob.move_linear(np.array([450.0, 50.0, 250.0]), speed=200.0, timeout=5.0)
    np.testing.assert_allclose(rob.read_tcp(), [450.0, 50.0, 250.0], atol=robot.tol["linear"])
    assert rob.status().in_position
    rob.stop()
    assert not rob.status().moving


def test_status_says_moving_while_a_move_blocks(robot_kind):
    cell = make_cell(time_scale=0.05, settle_s=1.0)
    with serve_robot(robot_kind, cell) as rig, rig.observer() as watcher:
        done: list[BaseException | None] = []

        def move():
            try:  # 5 s + 1 s simulated = 0.3 s wall
                rig.driver.move_joints(np.array([0.5, 0.0, 0.0]), speed=0.1, timeout=2.0 + MARGIN)
                done.append(None)
            except BaseException as e:  # noqa: BLE001 - handed to the test's thread
                done.append(e)

        mover = threading.Thread(target=move, name="conformance-move")
        mover.start()
        try:
            _wait_for(lambda: watcher.status().moving or done, "moving")
            assert not done, "the move returned while the robot moved"
        finally:
            mover.join(10.0 + MARGIN)
        assert done == [None]
        st = watcher.status()
        assert st.in_position and not st.moving
        np.testing.assert_allclose(rig.driver.read_joints().q, [0.5, 0.0, 0.0], atol=1e-4)


def test_a_move_out_of_time_is_stopped_and_raises_timeout(robot_kind):
    cell = make_cell(time_scale=0.05, settle_s=1.0)
    with serve_robot(robot_kind, cell) as rig:
        rob = rig.driver
        with elapsed_below(0.1 + STOP_AFTER_TIMEOUT_S + MARGIN), \
                pytest.raises(CommandTimeout, match=rig.words["move"]):
            rob.move_joints(np.array([-0.5, 0.0, 0.0]), speed=0.1, timeout=0.1)  # 0.55 s wall
        assert not rob.status().moving  # stopped short of the target
        assert abs(rob.read_joints().q[0] + 0.5) > 0.05
        rob.wait_settled(timeout=1.0 + MARGIN)
        rob.stop()


def test_limits_and_bad_targets_are_refused(robot):
    rob, words = robot.driver, robot.words
    with pytest.raises(LimitError, match=words["limit"]):
        rob.move_joints(np.array([4.0, 0.0, 0.0]))
    with pytest.raises(CommandRejected, match=words["unreachable"]):
        rob.move_linear(np.array([5000.0, 0.0, 0.0]))
    with pytest.raises(CommandRejected):
        rob.move_joints(np.array([0.0, 0.0]))
    rob.move_joints(np.array([0.1, 0.0, 0.0]), timeout=5.0)  # and the next move goes
    np.testing.assert_allclose(rob.read_joints().q, [0.1, 0.0, 0.0], atol=1e-4)


def test_protective_stop_during_a_move(robot):
    rob, cell = robot.driver, robot.cell
    cell.faults.arm("pstop")  # the move meets an obstacle
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtectiveStop, match=robot.words["pstop"]):
        rob.move_joints(np.array([0.1, 0.1, 0.1]), timeout=1.0)
    _wait_for(lambda: rob.status().protective_stop, "protective-stopped")
    with pytest.raises(ProtectiveStop):
        rob.wait_settled(timeout=1.0)
    with pytest.raises(ProtectiveStop):  # a new move is refused while the stop lasts
        rob.move_joints(np.array([0.2, 0.1, 0.1]), timeout=1.0)
    cell.clear_protective_stop()  # the operator clears it
    _wait_for(lambda: not rob.status().protective_stop, "cleared")
    rob.move_joints(np.array([0.1, 0.1, 0.1]), timeout=5.0)
    np.testing.assert_allclose(rob.read_joints().q, [0.1, 0.1, 0.1], atol=1e-4)


def test_clear_protective_stop_where_offered(robot):
    rob = robot.driver
    if not callable(getattr(rob, "clear_protective_stop", None)):
        pytest.skip(f"{robot.name}: cleared at the controller (the pendant) only")
    robot.cell.trigger_protective_stop()
    _wait_for(lambda: rob.status().protective_stop, "protective-stopped")
    rob.clear_protective_stop()
    assert not rob.status().protective_stop
    rob.move_joints(np.array([0.1, 0.1, 0.1]), timeout=5.0)


def test_closed_driver_does_not_reconnect_by_itself(robot):
    rob = robot.driver
    rob.close()
    rob.close()  # idempotent
    with pytest.raises(ConnectionLost, match="not connected"):
        rob.read_joints(timeout=0.5)
    with pytest.raises(ConnectionLost, match="not connected"):
        rob.move_joints(np.array([0.1, 0.0, 0.0]), timeout=1.0)
    rob.connect(5.0)
    rob.read_joints(timeout=0.5)


@pytest.mark.parametrize("robot_kind", having(ROBOTS, "drop"))
def test_a_dropped_read_is_retried_once(robot):
    robot.cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN):
        robot.driver.read_joints(timeout=1.0)


@pytest.mark.parametrize("robot_kind", having(ROBOTS, "drop"))
def test_a_dropped_move_raises_then_connect_recovers(robot):
    rob = robot.driver
    robot.cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost, match=robot.words["move"]):
        rob.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    with pytest.raises(ConnectionLost, match="not connected"):  # moves are not retried silently
        rob.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    rob.connect(1.0)
    rob.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)


@pytest.mark.parametrize("robot_kind", having(ROBOTS, "slow"))
def test_a_slow_reply_times_out_then_reads_recover(robot):
    rob, cell = robot.driver, robot.cell
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout, match=robot.words["read"]):
        rob.read_joints(timeout=0.3)
    assert rob.read_joints(timeout=1.0).q.shape == (3,)
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout):
        rob.status(timeout=0.3)
    assert rob.status(timeout=1.0).connected  # reconnects: reads are idempotent


def test_identify(robot):
    rob = robot.driver
    assert isinstance(rob, Identified)
    ident = rob.identify()
    assert isinstance(ident, DeviceIdentity) and ident.kind == "robot"
    assert ident.n_joints == rob.n_joints == 3
    assert ident.simulator == robot.kind.names_itself


@pytest.fixture(scope="module")
def warming():
    """A UR10e with a thermal model, warmed by five minutes of work and ten powered."""
    truth = ModelTruth.from_spec("ur10e", None, 2).with_thermal(2)
    cell = SimCell(truth, seed=2, thermal="cold")
    cell.command_move_joints(cell.robot_state().q + 0.5, 0.1)  # 5 s of work
    cell.advance(600.0)  # and ten minutes powered
    return cell


def test_joint_temperatures(robot_kind, warming):
    with serve_robot(robot_kind, warming) as rig:
        rob = rig.driver
        assert isinstance(rob, JointTemperatures)
        got = rob.joint_temperatures()
    assert len(got) == 6 and all(isinstance(v, float) for v in got)
    truth = warming.joint_temperatures()
    np.testing.assert_allclose(got, truth, atol=rig.tol["temp"])  # centidegrees on some wires
    assert np.all(truth > 20.5)  # it did warm up
