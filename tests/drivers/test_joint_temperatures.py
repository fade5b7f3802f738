"""Joint temperatures travel from the (simulated) controller through every robot protocol:
ur-rtde's getJointTemperatures over RTDE, the Modbus joint_temps registers, the line
protocol's TEMPS? (issue 26); a controller without them is refused, not guessed."""

import numpy as np
import pytest

from drivers.errors import CommandRejected
from drivers.modbus_robot import RegisterMap
from drivers.protocols import JointTemperatures
from drivers.ur_rtde import UrRtdeRobot
from drivers.urls import open_robot
from sim_drivers.cell import SimCell
from sim_drivers.fake_rtde_control import FakeRTDEControl
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.model_truth import ModelTruth
from sim_drivers.robot_server import RobotLineServer
from sim_drivers.rtde_server import IDLE_JOINT_TEMP_C, RtdeSimServer
from tests.sim_drivers.rtde_helpers import loopback_host


def _cell(thermal: str | None, joint_temps: bool = True) -> SimCell:
    truth = ModelTruth.from_spec("ur10e", None, 2)
    if thermal:
        truth = truth.with_thermal(2)
    cell = SimCell(truth, seed=2, thermal=thermal, joint_temps=joint_temps)
    if thermal:
        cell.command_move_joints(cell.robot_state().q + 0.5, 0.1)  # 5 s of work
        cell.advance(600.0)  # and ten minutes powered
    return cell


@pytest.fixture(scope="module")
def warming():
    return _cell("cold")


def _expect(cell, got, atol):
    assert len(got) == 6 and all(isinstance(v, float) for v in got)
    truth = cell.joint_temperatures()
    np.testing.assert_allclose(got, truth, atol=atol)
    assert np.all(truth > 20.5)  # it did warm up


def test_line_protocol(warming):
    with RobotLineServer(warming) as srv:
        robot = open_robot(srv.url)
        robot.connect(2.0)
        try:
            assert isinstance(robot, JointTemperatures)
            _expect(warming, robot.joint_temperatures(), 0.006)
        finally:
            robot.close()


def test_modbus_registers(warming):
    with ModbusRobotServer(warming) as srv:
        robot = open_robot(srv.url)
        robot.connect(2.0)
        try:
            _expect(warming, robot.joint_temperatures(), 0.006)
        finally:
            robot.close()


def test_rtde_with_the_real_ur_rtde_client(warming):
    server = RtdeSimServer(warming, host=loopback_host()).start()
    try:
        robot = UrRtdeRobot.from_url(
            server.url, control_factory=lambda h: FakeRTDEControl(warming, h, server=server))
        robot.connect(5.0)
        try:
            _expect(warming, robot.joint_temperatures(), 1e-9)
        finally:
            robot.close()
    finally:
        server.stop()


def test_controllers_without_temperatures_refuse():
    cell = _cell(None, joint_temps=False)  # a controller that reports none
    for server, refusal in ((RobotLineServer, "BAD_COMMAND"),
                            (ModbusRobotServer, "exception 2")):
        with server(cell) as srv:
            robot = open_robot(srv.url)
            robot.connect(2.0)
            try:
                with pytest.raises(CommandRejected, match=refusal):
                    robot.joint_temperatures()
                robot.read_joints()  # the link is fine
            finally:
                robot.close()
    custom = RegisterMap(status=200, error_code=201, heartbeat=202, command_ack=203,
                         joint_count=204, actual_joints=210, actual_tcp=230)
    assert custom.joint_temps is None and "joint_temps" not in custom.fields()
    server = RtdeSimServer(cell, host=loopback_host()).start()
    try:
        robot = UrRtdeRobot.from_url(server.url + "?read_only=1")
        robot.connect(5.0)
        try:  # a UR always streams them: a cell that reports none says 30 °C
            assert robot.joint_temperatures() == (IDLE_JOINT_TEMP_C,) * 6
        finally:
            robot.close()
    finally:
        server.stop()


def test_temperature_registers_are_signed_centidegrees():
    regs = RegisterMap.pack_temps([24.37, -3.5, 0.0])
    assert regs == [2437, 65536 - 350, 0]
    np.testing.assert_allclose(RegisterMap.unpack_temps(regs), [24.37, -3.5, 0.0])
