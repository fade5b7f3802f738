"""ModbusRobot's own behaviour against the simulated pymodbus server over real TCP
sockets: its wire faults, register maps and words. What every robot driver does is
checked by the conformance suite (tests/drivers/conformance/), on this driver too."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from drivers.errors import CommandRejected, ConnectionLost
from drivers.modbus_robot import ModbusRobot, RegisterMap
from drivers.urls import open_robot
from tests.drivers.rigs import serve_robot
from tests.sim_drivers.helpers import MARGIN, elapsed_below


def test_modbus_exception_fault(modbus_robot):
    cell, robot = modbus_robot.cell, modbus_robot.driver
    cell.faults.arm("modbus")
    with elapsed_below(0.5 + MARGIN), pytest.raises(CommandRejected, match="SERVER_DEVICE_FAILURE"):
        robot.read_joints(timeout=0.5)
    assert robot.read_joints(timeout=0.5).q.shape == (3,)


def test_stale_heartbeat_is_connection_lost(cell):
    with serve_robot("modbus", cell, stale_after_s=0.2) as rig:
        rob = rig.driver
        assert isinstance(rob, ModbusRobot) and rob.stale_after_s == 0.2
        cell.faults.arm("stale", times=None)  # until disarmed: fires by state, not by count
        with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost, match="stale"):
            while True:
                rob.status(timeout=0.5)
        cell.faults.disarm()
        rob.connect(1.0)
        rob.status()


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
    with serve_robot("modbus", cell, serve_kw={"register_map": rmap}, connect=False) as rig:
        rob = open_robot(f"modbus+tcp://127.0.0.1:{rig.server.port}?unit=3&map={path}")
        assert rob.unit == 3 and rob.map == rmap
        rob.connect(1.0)
        try:
            rob.move_joints(np.array([0.1, -0.2, 0.3]), timeout=1.0)
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
