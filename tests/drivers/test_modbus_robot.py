"""ModbusRobot against the simulated pymodbus server over real TCP sockets."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    LimitError,
    ProtectiveStop,
)
from drivers.modbus_robot import ModbusRobot, RegisterMap
from drivers.protocols import CommandedPosition, RobotDriver
from drivers.urls import open_robot
from sim_drivers.modbus_server import ModbusRobotServer
from tests.sim_drivers.helpers import MARGIN, elapsed_below, make_cell


@pytest.fixture
def cell():
    return make_cell(seed=7)


@pytest.fixture
def server(cell):
    with ModbusRobotServer(cell) as srv:
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
    q = robot.read_joints().q
    assert np.allclose(q, target, atol=1e-4)
    assert np.allclose(q, cell.robot_state().q, atol=1e-6)  # float32 on the wire
    assert np.allclose(robot.read_tcp(), cell.truth.nominal_tcp(q), atol=1e-3)
    st = robot.status()
    assert st.in_position and not st.moving and st.error_code == 0
    robot.move_linear(np.array([450.0, 50.0, 250.0]), speed=200.0, wait=True, timeout=2.0)
    assert np.allclose(robot.read_tcp(), [450.0, 50.0, 250.0], atol=0.01)
    robot.stop()


def test_wait_settled_with_real_motion_time():
    cell = make_cell(time_scale=0.05, settle_s=1.0)
    with ModbusRobotServer(cell) as srv, open_robot(srv.url) as rob:
        rob.connect(1.0)
        rob.move_joints(np.array([0.5, 0.0, 0.0]), speed=0.1)  # 0.3 s wall
        assert rob.status().moving
        rob.wait_settled(timeout=2.0)
        rob.move_joints(np.array([-0.5, 0.0, 0.0]), speed=0.1)
        with elapsed_below(0.1 + MARGIN), pytest.raises(CommandTimeout):
            rob.wait_settled(timeout=0.1)
        rob.stop()


def test_limit_and_unreachable_are_rejected(robot):
    with pytest.raises(LimitError, match="ILLEGAL_DATA_VALUE.*LIMIT"):
        robot.move_joints(np.array([4.0, 0.0, 0.0]))
    with pytest.raises(CommandRejected, match="error code 21"):
        robot.move_linear(np.array([5000.0, 0.0, 0.0]))
    robot.move_joints(np.array([0.1, 0.0, 0.0]), wait=True, timeout=1.0)


def test_modbus_exception_fault(cell, robot):
    cell.faults.arm("modbus")
    with elapsed_below(0.5 + MARGIN), pytest.raises(CommandRejected, match="SERVER_DEVICE_FAILURE"):
        robot.read_joints(timeout=0.5)
    assert robot.read_joints(timeout=0.5).q.shape == (3,)


def test_protective_stop_fault_then_clear(cell, robot):
    cell.faults.arm("pstop")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtectiveStop):
        robot.move_joints(np.array([0.2, 0.1, 0.0]), timeout=1.0)
    assert robot.status().protective_stop
    with pytest.raises(ProtectiveStop):
        robot.wait_settled(1.0)
    robot.clear_protective_stop()
    robot.move_joints(np.array([0.2, 0.1, 0.0]), wait=True, timeout=1.0)


def test_slow_response_times_out_then_recovers(cell, robot):
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout):
        robot.status(timeout=0.3)
    assert robot.status(timeout=1.0).connected  # reconnects: reads are idempotent


def test_dropped_read_is_retried_once(cell, robot):
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN):
        robot.read_joints(timeout=1.0)


def test_dropped_move_raises_then_connect_recovers(cell, robot):
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost, match="move_joints"):
        robot.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    with pytest.raises(ConnectionLost, match="not connected"):
        robot.move_joints(np.array([0.2, 0.0, 0.0]), timeout=1.0)
    robot.connect(1.0)
    robot.move_joints(np.array([0.2, 0.0, 0.0]), wait=True, timeout=1.0)


def test_stale_heartbeat_is_connection_lost(cell, server):
    rob = ModbusRobot(server.url, "127.0.0.1", server.port, stale_after_s=0.2)
    rob.connect(1.0)
    try:
        cell.faults.arm("stale", times=None)  # until disarmed: fires by state, not by count
        with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost, match="stale"):
            while True:
                rob.status(timeout=0.5)
        cell.faults.disarm()
        rob.connect(1.0)
        rob.status()
    finally:
        rob.close()


def test_server_gone(cell):
    srv = ModbusRobotServer(cell).start()
    rob = open_robot(srv.url)
    rob.connect(1.0)
    srv.stop()
    try:
        with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost):
            rob.status(timeout=1.0)
        with pytest.raises(ConnectionLost):
            rob.connect(0.5)
    finally:
        rob.close()


def test_custom_map_from_yaml(tmp_path, cell):
    spec = {
        "n_joints": 4,
        "word_order": "little",
        "command": 100,
        "command_seq": 110,
        "speed": 102,
        "target_joints": 120,
        "target_xyz": 130,
        "status": 200,
        "error_code": 201,
        "heartbeat": 202,
        "command_ack": 203,
        "joint_count": 204,
        "actual_joints": 210,
        "actual_tcp": 220,
        "bits": {"in_position": 8, "busy": 9},
    }
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(spec))
    rmap = RegisterMap.from_yaml(path)
    assert rmap.word_order == "little" and rmap.bits.in_position == 8
    with ModbusRobotServer(cell, register_map=rmap) as srv:
        rob = open_robot(f"modbus+tcp://127.0.0.1:{srv.port}?unit=3&map={path}")
        assert rob.unit == 3 and rob.map == rmap
        rob.connect(1.0)
        try:
            rob.move_joints(np.array([0.1, -0.2, 0.3]), wait=True, timeout=1.0)
            assert np.allclose(rob.read_joints().q, [0.1, -0.2, 0.3], atol=1e-4)
        finally:
            rob.close()


def test_register_map_validation(tmp_path):
    with pytest.raises(ValueError, match="overlaps"):
        RegisterMap(speed=0)
    with pytest.raises(ValueError, match="share a bit"):
        RegisterMap(bits={"busy": 0})
    with pytest.raises(ValueError, match="extra"):
        RegisterMap(nonsense=3)
    bad = tmp_path / "bad.yaml"
    bad.write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="mapping"):
        RegisterMap.from_yaml(bad)
    m = RegisterMap()
    assert np.allclose(m.unpack_floats(m.pack_floats([1.5, -2.25])), [1.5, -2.25])
    assert m.pack_floats([1.0]) == [0x3F80, 0x0000]
    assert m.size == 58


def test_closed_driver_does_not_reconnect_by_itself(robot):
    robot.close()
    with pytest.raises(ConnectionLost, match="not connected"):
        robot.read_joints(timeout=0.5)
    robot.connect(1.0)
    robot.read_joints(timeout=0.5)
