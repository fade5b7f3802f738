"""Each driver logs its wire traffic decoded at DEBUG (requests with their arguments, replies
with their fields) and its connection at INFO, against the served simulators over real
sockets; nothing of it is formatted when DEBUG is off."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from drivers.errors import DriverError
from drivers.urls import open_robot, open_tracker
from sim_drivers.emscon_server import EmsconServer
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.robot_server import RobotLineServer
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.helpers import make_cell


def _lines(caplog, logger: str, level: int = logging.DEBUG) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == logger and r.levelno == level]


def test_line_robot_logs_each_request_and_reply(caplog):
    caplog.set_level(logging.DEBUG, logger="drivers")
    with RobotLineServer(make_cell(seed=5)) as server:
        robot = open_robot(server.url)
        robot.connect(timeout=2.0)
        try:
            robot.move_joints(np.deg2rad([10.0, 20.0, -30.0]), speed=0.5, timeout=2.0)
            robot.wait_settled(timeout=2.0)
            robot.read_joints()
            with pytest.raises(DriverError):
                robot.move_joints(np.deg2rad([500.0, 0.0, 0.0]), speed=0.5, timeout=2.0)
        finally:
            robot.close()
    wire = _lines(caplog, "drivers.line_robot")
    dev = f"robot {server.url}"
    assert f"{dev}: > HELLO" in wire
    assert any(w.startswith(f"{dev}: < OK HELLO ") and "joints=3" in w for w in wire)
    moves = [w for w in wire if w.startswith(f"{dev}: > MOVEJ ")]
    assert moves[0].split()[-4:-1] == ["10.000000", "20.000000", "-30.000000"]
    assert f"{dev}: < OK MOVEJ" in wire
    assert any(w.startswith(f"{dev}: > POS?") for w in wire)
    assert any(w.startswith(f"{dev}: < OK POS ") for w in wire)
    assert any(w.startswith(f"{dev}: < OK STATUS ") and "inpos=" in w for w in wire)
    info = _lines(caplog, "drivers.line_robot", logging.INFO)
    assert any("link open" in w for w in info) and any("link closed" in w for w in info)
    assert any("controller" in w and "3 joints" in w for w in info)
    assert any("MOVEJ refused: ERR" in w for w in info)  # the error reply, decoded


def test_line_tracker_logs_each_measurement(caplog):
    caplog.set_level(logging.DEBUG, logger="drivers.line_tracker")
    with TrackerServer(make_cell(seed=5)) as server:
        tracker = open_tracker(server.url)
        tracker.connect(timeout=2.0)
        try:
            m = tracker.measure(duration_s=0.01, timeout=2.0)
        finally:
            tracker.close()
    wire = _lines(caplog, "drivers.line_tracker")
    dev = f"tracker {server.url}"
    assert f"{dev}: > SET MODE STATIONARY time_ms=10" in wire
    assert f"{dev}: > MEAS" in wire
    reply = next(w for w in wire if w.startswith(f"{dev}: < OK MEAS "))
    fields = dict(t.split("=", 1) for t in reply.split()[4:] if "=" in t)
    assert float(fields["x"]) == pytest.approx(m.xyz[0], abs=1e-3)
    assert {"y", "z", "sx", "sy", "sz", "n", "t"} <= set(fields)


def test_modbus_robot_logs_registers_by_field(caplog):
    caplog.set_level(logging.DEBUG, logger="drivers.modbus_robot")
    with ModbusRobotServer(make_cell(seed=7)) as server:
        robot = open_robot(server.url)
        robot.connect(timeout=2.0)
        try:
            robot.move_joints(np.array([0.1, 0.2, -0.3]), speed=0.5, timeout=2.0)
            robot.wait_settled(timeout=2.0)
        finally:
            robot.close()
    wire = _lines(caplog, "drivers.modbus_robot")
    assert any("> move_joints: write target_joints=[0.1, 0.2, -0.3" in w for w in wire)
    assert any("> move_joints: write command=1 MOVE_JOINTS, command_seq=" in w for w in wire)
    assert any("< move_joints: command" in w and "acknowledged, error code 0" in w
               for w in wire)
    assert any("< status: status 0x" in w and "heartbeat" in w and "q [" in w for w in wire)
    assert any("connected to" in w for w in _lines(caplog, "drivers.modbus_robot",
                                                     logging.INFO))


def test_emscon_logs_every_packet_with_its_names(caplog):
    caplog.set_level(logging.DEBUG, logger="drivers.leica")
    with EmsconServer(make_cell(seed=3)) as server:
        tracker = open_tracker(server.url)
        tracker.connect(timeout=2.0)
        try:
            tracker.measure(duration_s=0.01, timeout=2.0)
        finally:
            tracker.close()
    wire = _lines(caplog, "drivers.leica.link")
    assert any("> SetUnitsCT(command=ES_C_SetUnits, lenUnitType=" in w for w in wire)
    assert any("< SetUnitsRT(command=ES_C_SetUnits, status=ES_RS_AllOK)" in w for w in wire)
    assert any("> StartMeasurementCT(command=ES_C_StartMeasurement" in w for w in wire)
    result = [w for w in wire if "< SingleMeasResult" in w]
    assert result and "status=ES_RS_AllOK" in result[0] and "dVal1=" in result[0]
    assert any("settings put" in w for w in _lines(caplog, "drivers.leica.driver",
                                                    logging.INFO))


def test_nothing_is_formatted_when_debug_is_off(caplog, monkeypatch):
    """The wire's records are not even made at INFO (lazy %-arguments, guarded decoding)."""
    from drivers import modbus_robot

    caplog.set_level(logging.INFO, logger="drivers")
    made = []
    monkeypatch.setattr(modbus_robot.ModbusRobot, "_decode",
                        lambda self, *a: made.append(a) or "")
    with ModbusRobotServer(make_cell(seed=7)) as server:
        robot = open_robot(server.url)
        robot.connect(timeout=2.0)
        try:
            robot.move_joints(np.array([0.1, 0.2, -0.3]), speed=0.5, timeout=2.0)
        finally:
            robot.close()
    assert made == []
    assert not [r for r in caplog.records if r.levelno < logging.INFO]
