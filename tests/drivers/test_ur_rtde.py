"""UrRtdeRobot end to end: real ur-rtde receive client on the RTDE simulator + FakeRTDEControl.

What every robot driver does is checked by the conformance suite
(tests/drivers/conformance/), on this driver too; here: the wire's units, ur-rtde's quirks.
"""

from __future__ import annotations

import contextlib
import time

import numpy as np
import pytest

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    LimitError,
    NotReady,
    ProtectiveStop,
)
from drivers.protocols import CommandedPosition, RobotDriver
from drivers.ur_rtde import UrRtdeRobot
from sim_drivers.fake_rtde_control import FakeRTDEControl
from sim_drivers.rtde_server import RtdeSimServer
from sim_drivers.truth import ToyArm
from tests.drivers.rigs import serve_robot
from tests.sim_drivers.helpers import make_cell
from tests.sim_drivers.rtde_helpers import loopback_host

Q0 = np.array([0.2, 0.4, -0.6])


@contextlib.contextmanager
def ur_rig(control_cls=FakeRTDEControl, **driver_kw):
    """A ToyArm cell at ``Q0`` served over RTDE, ``control_cls`` on its control side, the
    driver connected; ``calls(rig, name)`` the control interface's calls of ``name``."""
    with serve_robot("ur-rtde", make_cell(seed=3, q0=Q0), serve_kw={"control_cls": control_cls},
                     **driver_kw) as rig:
        yield rig


def calls(rig, name: str) -> list[tuple]:
    return [c for c in rig.server.controls[-1].calls if c[0] == name]


@pytest.fixture
def rig():
    with ur_rig() as r:
        yield r


def test_move_settle_read_with_unit_conversion(rig):
    robot = rig.driver
    assert isinstance(robot, RobotDriver) and isinstance(robot, CommandedPosition)
    np.testing.assert_allclose(robot.read_joints().q, Q0, atol=1e-9)

    target = np.array([0.5, 0.3, -0.9])
    robot.move_joints(target, speed=0.8, timeout=5.0)  # returns settled
    reading = robot.read_joints()
    assert reading.q.shape == (3,)
    np.testing.assert_allclose(reading.q, target, atol=1e-4)  # cell repeatability 1e-5 rad
    assert abs(reading.timestamp - time.time()) < 30.0  # a wall-clock stamp, not a speed bound
    # the controller's TCP comes back in mm (the wire carries metres)
    tcp = robot.read_tcp()
    np.testing.assert_allclose(tcp, ToyArm().nominal_tcp(reading.q), atol=1e-6)
    assert np.linalg.norm(tcp) > 100.0
    name, q_wire, speed, _acc, asynchronous = calls(rig, "moveJ")[-1]
    assert len(q_wire) == 6 and q_wire[:3] == pytest.approx(target) and q_wire[3:] == [0, 0, 0]
    assert speed == 0.8 and asynchronous is True
    st = robot.status()
    assert st.connected and st.in_position and not st.moving and st.error_code == 0


def test_move_linear_sends_metres_and_arrives_in_mm(rig):
    robot = rig.driver
    start = robot.read_tcp()
    goal = start + np.array([-30.0, 20.0, 10.0])
    robot.move_linear(goal, speed=150.0, timeout=5.0)
    np.testing.assert_allclose(robot.read_tcp(), goal, atol=0.05)
    _, pose, speed, _acc, _async = calls(rig, "moveL")[-1]
    np.testing.assert_allclose(pose[:3], goal / 1000.0)
    assert speed == pytest.approx(0.15)


class _CollidingControl(FakeRTDEControl):
    """moveJ meets an obstacle: the cell protective-stops as the command starts."""

    def moveJ(self, q, speed=1.05, acceleration=1.4, asynchronous=False):  # noqa: N802
        self.cell.trigger_protective_stop()
        return super().moveJ(q, speed, acceleration, asynchronous)


def test_moveJ_false_on_protective_stop_raises_and_recovers_after_clear():  # noqa: N802
    with ur_rig(control_cls=_CollidingControl) as rig:
        robot = rig.driver
        with pytest.raises(ProtectiveStop, match="protective stop") as err:
            robot.move_joints(Q0 + 0.1, timeout=5.0)
        assert err.value.command == "moveJ" and rig.server.host in str(err.value)
        assert calls(rig, "moveJ"), "the refusal must come from moveJ's False"
        st = robot.status()
        assert st.protective_stop and st.error_code == 3
        # a new move is refused before anything is sent
        n = len(calls(rig, "moveJ"))
        with pytest.raises(ProtectiveStop):
            robot.move_joints(Q0, timeout=2.0)
        assert len(calls(rig, "moveJ")) == n

        rig.cell.clear_protective_stop()  # the operator clears it on the pendant
        rig.server.controls[-1].__class__ = FakeRTDEControl  # and the obstacle is gone
        deadline = time.monotonic() + 1.0
        while robot.status().protective_stop and time.monotonic() < deadline:
            pass  # until the stream shows it
        robot.move_joints(Q0 + 0.1, timeout=5.0)  # script re-uploaded, then the move
        assert calls(rig, "reuploadScript")
        np.testing.assert_allclose(robot.read_joints().q, Q0 + 0.1, atol=1e-4)
        assert not robot.status().protective_stop


def test_moveJ_false_with_dead_script_is_rejected(rig):  # noqa: N802
    # outside the ToyArm's limits: the controller refuses and its script stops
    with pytest.raises(CommandRejected, match="control script stopped"):
        rig.driver.move_joints(np.array([4.0, 0.0, 0.0]), timeout=2.0)
    assert not rig.server.controls[-1].isProgramRunning()
    rig.driver.move_joints(Q0 - 0.1, timeout=5.0)  # recovers by re-uploading
    np.testing.assert_allclose(rig.driver.read_joints().q, Q0 - 0.1, atol=1e-4)


class _DeafControl(FakeRTDEControl):
    """Accepts moveJ but never moves (a stalled controller)."""

    def moveJ(self, q, speed=1.05, acceleration=1.4, asynchronous=False):  # noqa: N802
        self.calls.append(("moveJ", list(q), speed, acceleration, asynchronous))
        return True


#: slack on top of a timeout that tells a hang from an answer (not a speed bound: a
#: loaded 2-core machine must not break it)
HANG_S = 30.0  # a hang is forever: the slack is for a loaded machine


def test_limits_and_timeouts():
    with ur_rig(control_cls=_DeafControl, limits=[[-1.0, 1.0]] * 3) as rig:
        with pytest.raises(LimitError, match="joint\\(s\\) \\[2\\]"):
            rig.driver.move_joints(np.array([0.0, 1.5, 0.0]))
        assert not calls(rig, "moveJ")
        with pytest.raises(CommandRejected):
            rig.driver.move_joints(np.array([0.0, 0.0]))
        t0 = time.monotonic()
        with pytest.raises(CommandTimeout, match="moveJ"):
            rig.driver.move_joints(np.array([0.1, 0.1, 0.1]), timeout=0.3)
        assert time.monotonic() - t0 < 0.3 + HANG_S
        assert calls(rig, "stopJ"), "a timed-out move must be stopped"


def test_killed_server_raises_connection_lost_within_the_timeout(rig):
    rig.driver.read_joints()
    rig.server.kill()
    t0 = time.monotonic()
    with pytest.raises(ConnectionLost, match="getActualQ"):
        # a sample the receive thread took in just before the kill may still be read
        # (on a loaded machine it lags): the link's loss shows on the read after it
        for _ in range(3):
            rig.driver.read_joints(timeout=1.0)
    assert time.monotonic() - t0 < 3 * 1.0 + HANG_S
    with pytest.raises(ConnectionLost):
        rig.driver.status(timeout=0.5)


def test_frozen_controller_timestamp_is_stale_data(rig):
    rig.driver.read_joints()
    rig.server.freeze()
    time.sleep(0.05)
    rig.driver.read_joints()  # the last sample before the freeze is still news
    t0 = time.monotonic()
    with pytest.raises(ConnectionLost, match="stale"):
        rig.driver.read_joints(timeout=0.6)
    assert time.monotonic() - t0 < 0.6 + HANG_S
    rig.server.freeze(False)
    np.testing.assert_allclose(rig.driver.read_joints(timeout=1.0).q, Q0, atol=1e-9)


class _Idle:
    def __init__(self, **kw):
        self.q, self.qd, self.tcp = [0.1] * 6, [0.0] * 6, [400.0, 0.0, 500.0]
        self.protective_stop = self.emergency_stop = self.fault = False
        self.__dict__.update(kw)


def test_read_only_url_reads_a_running_server():
    with RtdeSimServer(host=loopback_host()) as server:
        server.publish(_Idle())
        robot = UrRtdeRobot.from_url(f"{server.url}?read_only=1")
        robot.connect(timeout=5.0)
        try:
            np.testing.assert_allclose(robot.read_joints().q, [0.1] * 6)
            np.testing.assert_allclose(robot.read_tcp(), [400.0, 0.0, 500.0])
            with pytest.raises(NotReady, match="read-only"):
                robot.move_joints(np.zeros(6))
            server.publish(_Idle(emergency_stop=True))
            deadline = time.monotonic() + 1.0
            while not robot.status().emergency_stop and time.monotonic() < deadline:
                time.sleep(0.01)
            st = robot.status()
            assert st.emergency_stop and st.error_code == 7 and "emergency" in st.message
            with pytest.raises(ProtectiveStop, match="emergency stop"):
                robot.wait_settled(timeout=1.0)
        finally:
            robot.close()


def test_connect_to_nothing_fails_fast():
    robot = UrRtdeRobot.from_url(f"ur://{loopback_host()}")
    t0 = time.monotonic()
    with pytest.raises(ConnectionLost, match="connect"):
        robot.connect(timeout=1.0)
    assert time.monotonic() - t0 < 1.0 + HANG_S
    with pytest.raises(ConnectionLost, match="not connected"):
        robot.read_joints()


def test_from_url():
    r = UrRtdeRobot.from_url("ur://10.0.0.5?frequency=125&joints=3&stale=0.5&read_only=true")
    assert (r.host, r.frequency, r.n_joints, r.stale_after, r.read_only) == (
        "10.0.0.5", 125.0, 3, 0.5, True)
    assert UrRtdeRobot.from_url("ur://robot", n_joints=2).n_joints == 2
    for bad in ("ur://", "modbus+tcp://h:502", "ur://h:1234", "ur://h?joints=x"):
        with pytest.raises(ValueError):
            UrRtdeRobot.from_url(bad)


@pytest.mark.hardware
def test_read_only_with_device(robot_url):
    """Opt-in (``--robot-url ur://<controller>``): reads only, never moves."""
    robot = UrRtdeRobot.from_url(robot_url, read_only=True)
    robot.connect(timeout=5.0)
    try:
        assert robot.read_joints().q.shape == (6,)
        assert robot.read_tcp().shape == (3,)
        assert robot.status().connected
    finally:
        robot.close()
