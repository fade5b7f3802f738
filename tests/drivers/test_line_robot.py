"""SerialRobot against the simulated line-protocol controller over real sockets and a pty."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    LimitError,
    ProtectiveStop,
    ProtocolError,
)
from drivers.line_robot import SerialRobot
from drivers.protocols import CommandedPosition, RobotDriver
from drivers.urls import open_robot
from sim_drivers.robot_server import RobotLineServer
from tests.sim_drivers.helpers import MARGIN, ScriptedPeer, elapsed_below, make_cell


@pytest.fixture
def cell():
    return make_cell(seed=5)


@pytest.fixture
def server(cell):
    with RobotLineServer(cell) as srv:
        yield srv


@pytest.fixture
def robot(server):
    rob = open_robot(server.url)
    rob.connect(timeout=2.0)
    yield rob
    rob.close()


def test_move_and_read_back(cell, robot):
    assert isinstance(robot, RobotDriver) and isinstance(robot, CommandedPosition)
    assert robot.n_joints == 3
    target = np.array([0.3, 0.2, -0.4])
    robot.move_joints(target, speed=0.5, wait=True, timeout=2.0)
    r = robot.read_joints()
    assert np.allclose(r.q, target, atol=1e-4)
    assert np.allclose(r.q, cell.robot_state().q, atol=1e-7)
    assert np.allclose(robot.read_tcp(), cell.truth.nominal_tcp(r.q), atol=1e-3)
    st = robot.status()
    assert st.connected and st.in_position and not st.moving and not st.protective_stop
    robot.move_linear(np.array([450.0, 50.0, 250.0]), speed=200.0)
    robot.wait_settled(timeout=1.0)
    assert np.allclose(robot.read_tcp(), [450.0, 50.0, 250.0], atol=0.05)
    robot.stop()


def test_wait_settled_follows_the_motion_time_model():
    cell = make_cell(time_scale=0.05, settle_s=1.0)
    with RobotLineServer(cell) as srv, open_robot(srv.url) as rob:
        rob.connect(1.0)
        rob.move_joints(np.array([0.5, 0.0, 0.0]), speed=0.1)  # 5 s + 1 s sim = 0.3 s wall
        assert rob.status().moving
        rob.wait_settled(timeout=2.0 + MARGIN)  # settles (no wall-clock bound: load varies)
        assert rob.status().in_position
        rob.move_joints(np.array([-0.5, 0.0, 0.0]), speed=0.1)  # 10 s + 1 s sim = 0.55 s wall
        with elapsed_below(0.1 + MARGIN), pytest.raises(CommandTimeout, match="wait_settled"):
            rob.wait_settled(timeout=0.1)
        rob.stop()
        rob.wait_settled(timeout=1.0)


def test_limit_and_bad_arguments(robot):
    with pytest.raises(LimitError, match="LIMIT"):
        robot.move_joints(np.array([4.0, 0.0, 0.0]))
    with pytest.raises(CommandRejected, match="UNREACHABLE"):
        robot.move_linear(np.array([5000.0, 0.0, 0.0]))
    with pytest.raises(CommandRejected):
        robot.move_joints(np.array([0.0, 0.0]))


def test_protective_stop_fault_then_reset(cell, robot):
    cell.faults.arm("pstop")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtectiveStop, match="PROTECTIVE_STOP"):
        robot.move_joints(np.array([0.1, 0.1, 0.1]), timeout=1.0)
    assert robot.status().protective_stop
    with pytest.raises(ProtectiveStop):
        robot.wait_settled(timeout=1.0)
    robot.clear_protective_stop()
    robot.move_joints(np.array([0.1, 0.1, 0.1]), wait=True, timeout=1.0)


def test_slow_reply_times_out_then_recovers(cell, robot):
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout, match="POS"):
        robot.read_joints(timeout=0.3)
    assert robot.read_joints(timeout=1.0).q.shape == (3,)


def test_dropped_query_is_retried_once(cell, robot):
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN):
        robot.read_joints(timeout=1.0)


def test_dropped_move_raises_then_connect_recovers(cell, robot):
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost, match="MOVEJ"):
        robot.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    with pytest.raises(ConnectionLost):  # moves are not retried silently
        robot.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    robot.connect(timeout=1.0)
    robot.move_joints(np.array([0.2, 0.0, 0.0]), wait=True, timeout=1.0)


def test_garbage_reply_is_protocol_error_then_recovers(cell, robot):
    cell.faults.arm("garbage")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtocolError, match="garbage"):
        robot.status(timeout=1.0)
    assert robot.status(timeout=1.0).connected


def test_over_pty(cell):
    with RobotLineServer(cell, transport="pty") as srv:
        rob = open_robot(srv.url + "?baud=57600")
        assert isinstance(rob, SerialRobot)
        rob.connect(1.0)
        try:
            rob.move_joints(np.array([-0.2, 0.3, 0.1]), wait=True, timeout=1.0)
            assert np.allclose(rob.read_joints().q, [-0.2, 0.3, 0.1], atol=1e-4)
            cell.faults.spec.delay_s = 0.4
            cell.faults.arm("slow")
            with elapsed_below(0.2 + MARGIN), pytest.raises(CommandTimeout):
                rob.read_tcp(timeout=0.2)
            assert rob.read_joints(timeout=1.0).q.shape == (3,)  # late OK TCP is skipped
        finally:
            rob.close()


def test_loop_url_is_an_echo_and_fails_cleanly():
    rob = SerialRobot("loop://", "loop://")
    with pytest.raises(ProtocolError, match="HELLO"):
        rob.connect(0.5)
    rob.close()


def test_transcript():
    script = [
        ("HELLO", ["OK HELLO UR5e 20235500 5.11 joints=6"]),
        ("POS?", ["OK POS 0 -90 90 0 90 180"]),
        (
            "MOVEJ 10.000000 -90.000000 90.000000 0.000000 90.000000 0.000000 30.000000",
            ["OK MOVEJ"],
        ),
        ("STATUS?", ["OK STATUS moving=1 inpos=0 steady=0 fault=0 pstop=0 estop=0 err=0 t=1.0"]),
        ("STATUS?", ["OK STATUS moving=0 inpos=1 steady=1 fault=0 pstop=0 estop=0 err=0 t=2.0"]),
        ("TCP?", ["OK TCP 400.5 -133.25 500"]),
        ("MOVEL 400.0000 0.0000 500.0000 50.0000", ["ERR 30 PROTECTIVE_STOP safety plane"]),
        ("RESET", ["OK RESET"]),
        ("STOP", ["OK STOP"]),
    ]
    with ScriptedPeer(script) as peer:
        rob = open_robot(f"socket://127.0.0.1:{peer.port}", poll_s=0.0)
        try:
            rob.connect(1.0)
            assert rob.n_joints == 6 and rob.model == "UR5e"
            q = rob.read_joints().q
            assert np.allclose(np.rad2deg(q), [0, -90, 90, 0, 90, 180])
            target = np.deg2rad([10, -90, 90, 0, 90, 0])
            rob.move_joints(target, speed=np.deg2rad(30), wait=True, timeout=1.0)
            assert np.allclose(rob.read_tcp(), [400.5, -133.25, 500.0])
            with pytest.raises(ProtectiveStop, match="safety plane"):
                rob.move_linear(np.array([400.0, 0.0, 500.0]), speed=50.0)
            rob.clear_protective_stop()
            rob.stop()
        finally:
            rob.close()
        peer.check()


def test_transcript_unexpected_line_fails_the_check():
    with ScriptedPeer([("HELLO", ["OK HELLO a b c joints=1"])]) as peer:
        rob = open_robot(f"socket://127.0.0.1:{peer.port}")
        rob.connect(1.0)
        with pytest.raises(CommandTimeout):
            rob.read_joints(timeout=0.1)
        rob.close()
        with pytest.raises(AssertionError, match="unexpected line 'POS\\?'"):
            peer.check()


def test_closed_driver_does_not_reconnect_by_itself(robot):
    robot.close()
    with pytest.raises(ConnectionLost, match="not connected"):
        robot.read_joints(timeout=0.5)
    robot.connect(1.0)
    robot.read_joints(timeout=0.5)
