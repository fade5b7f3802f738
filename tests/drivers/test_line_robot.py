"""SerialRobot's own behaviour over real sockets and a pty: its wire faults, transcripts
and words. What every robot driver does is checked by the conformance suite
(tests/drivers/conformance/), on this driver too."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import CommandTimeout, ProtectiveStop, ProtocolError
from drivers.line_robot import SerialRobot
from drivers.urls import open_robot
from tests.drivers.rigs import serve_robot
from tests.sim_drivers.helpers import MARGIN, ScriptedPeer, elapsed_below


def test_garbage_reply_is_protocol_error_then_recovers(line_robot):
    cell, robot = line_robot.cell, line_robot.driver
    cell.faults.arm("garbage")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtocolError, match="garbage"):
        robot.status(timeout=1.0)
    assert robot.status(timeout=1.0).connected


def test_over_pty(cell):
    with serve_robot("line-pty", cell) as rig:
        rob = rig.driver
        assert isinstance(rob, SerialRobot) and rig.server.url.startswith("serial:///dev/")
        rob.move_joints(np.array([-0.2, 0.3, 0.1]), timeout=1.0)
        assert np.allclose(rob.read_joints().q, [-0.2, 0.3, 0.1], atol=1e-4)
        cell.faults.spec.delay_s = 0.4
        cell.faults.arm("slow")
        with elapsed_below(0.2 + MARGIN), pytest.raises(CommandTimeout):
            rob.read_tcp(timeout=0.2)
        assert rob.read_joints(timeout=1.0).q.shape == (3,)  # late OK TCP is skipped


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
        ("STATUS?", ["OK STATUS moving=0 inpos=1 steady=1 fault=0 pstop=0 estop=0 err=0 t=3.0"]),
    ]
    with ScriptedPeer(script) as peer:
        rob = open_robot(f"socket://127.0.0.1:{peer.port}", poll_s=0.0)
        try:
            rob.connect(1.0)
            assert rob.n_joints == 6 and rob.model == "UR5e"
            q = rob.read_joints().q
            assert np.allclose(np.rad2deg(q), [0, -90, 90, 0, 90, 180])
            target = np.deg2rad([10, -90, 90, 0, 90, 0])
            rob.move_joints(target, speed=np.deg2rad(30), timeout=1.0)
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
