"""Who a device says it is (simulators name themselves), and measurements that must be new."""

from __future__ import annotations

import pytest

from drivers.errors import ProtocolError
from drivers.protocols import DeviceIdentity, Identified
from drivers.urls import open_robot, open_tracker
from sim_drivers.cell import SimCell
from sim_drivers.emscon_server import EmsconServer
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.model_truth import ModelTruth
from sim_drivers.robot_server import RobotLineServer
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.helpers import ScriptedPeer


@pytest.fixture(scope="module")
def cell():
    return SimCell(ModelTruth.from_spec("ur10e", None, 7), seed=7)


def test_every_simulated_server_names_itself_a_simulator(cell):
    with RobotLineServer(cell) as line, ModbusRobotServer(cell) as modbus, \
            TrackerServer(cell) as tracker, EmsconServer(cell) as emscon:
        for url in (line.url, modbus.url):
            with open_robot(url) as robot:
                robot.connect(2.0)
                assert isinstance(robot, Identified)
                ident = robot.identify()
                assert ident.simulator and ident.kinematics == "ur10e", (url, ident)
                assert ident.serial == "SIM-ur10e-7" and ident.n_joints == 6
        for url in (tracker.url, emscon.url):
            with open_tracker(url) as trk:
                trk.connect(2.0)
                ident = trk.identify()
                assert ident.kind == "tracker" and ident.simulator, (url, ident)
                assert ident.serial in ("SIMTRK-7", "390130")  # line protocol, emScon


def test_a_controller_that_does_not_say_so_is_real_hardware():
    script = [("HELLO", ["OK HELLO ACME-R7 SN77 4.2 joints=6"])]
    with ScriptedPeer(script) as peer:
        robot = open_robot(f"socket://127.0.0.1:{peer.port}")
        try:
            robot.connect(1.0)
            assert robot.identify() == DeviceIdentity("robot", "ACME-R7", "SN77", "4.2",
                                                      n_joints=6)
        finally:
            robot.close()
        peer.check()


def _meas(t: float, seq: int | None = None, x: float = 1.0) -> str:
    return (f"OK MEAS x={x} y=2 z=3 sx=0.01 sy=0.01 sz=0.01 n=10 t={t}"
            + ("" if seq is None else f" seq={seq}"))


def test_a_repeated_or_older_measurement_reply_is_refused():
    script = [
        ("HELLO", ["OK HELLO AT960 SN1 2.1"]),
        ("STATUS?", ["OK STATUS init=1 warm=1 beam=1"]),
        ("SET MODE STATIONARY time_ms=10", ["OK MODE STATIONARY time_ms=10"]),
        ("MEAS", [_meas(100.0, 5)]),
        ("MEAS", [_meas(100.0, 5)]),  # the same reply again
        ("MEAS", [_meas(99.0, 6, x=1.1)]),  # older
        ("MEAS", [_meas(101.0, 5, x=1.2)]),  # newer time, old sequence number
        ("MEAS", [_meas(102.0, 7, x=1.3)]),
    ]
    with ScriptedPeer(script) as peer:
        trk = open_tracker(f"tracker+tcp://127.0.0.1:{peer.port}")
        try:
            trk.connect(1.0)
            assert trk.measure(0.01, 1.0).timestamp == 100.0
            for _ in range(3):
                with pytest.raises(ProtocolError, match="stale measurement"):
                    trk.measure(0.01, 1.0)
            assert trk.measure(0.01, 1.0).xyz[0] == 1.3
        finally:
            trk.close()
        peer.check()


def test_the_simulated_tracker_numbers_its_replies(cell):
    with TrackerServer(cell) as srv, open_tracker(srv.url) as trk:
        trk.connect(2.0)
        ts = [trk.measure(0.001, 2.0).timestamp for _ in range(5)]
    assert ts == sorted(ts) and len(set(ts)) == 5  # strictly later, even within a millisecond
