"""What only the ABB driver does (the rest is the conformance suite's): the mastership it
holds, the controller's states and faults (motors off, a lost mastership, a RAPID error
during a move, manual mode), the URL, the server module's protocol and the wire log."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from drivers.abb import codec as C
from drivers.abb.driver import AbbRwsRobot
from drivers.errors import CommandRejected, ConnectionLost, NotReady
from drivers.urls import check_url, open_robot
from sim_drivers.abb_controller import OTHER_CLIENT
from tests.drivers.rigs import serve_robot
from tests.sim_drivers.helpers import MARGIN, elapsed_below

TARGET = np.array([0.2, 0.1, -0.3])


@pytest.fixture
def abb(cell):
    with serve_robot("abb", cell) as rig:
        yield rig


def test_the_url():
    r = open_robot("abb://Default%20User:robotics@10.0.0.7?joints=6&tool=tSMR&wobj=wobjCell")
    assert isinstance(r, AbbRwsRobot)
    assert (r._link.host, r._link.port, r._link.user, r._link.password) == (
        "10.0.0.7", 80, "Default User", "robotics")
    assert (r.n_joints, r.tool, r.wobj, r.task, r.module) == (6, "tSMR", "wobjCell", "T_ROB1",
                                                             "CellcalServer")
    r = open_robot("abb://ctrl:8080?joints=3&read_only=1")
    assert (r._link.port, r.n_joints, r.read_only) == (8080, 3, True)
    for bad in ("abb://h?joints=7", "abb://h?tool=a-b", "abb://h?speed=1", "abb://:80"):
        with pytest.raises(ValueError, match="bad URL"):
            check_url(bad, "robot")


def test_mastership_is_held_while_connected(abb):
    ctl = abb.server.controller
    assert ctl.master is not None  # taken on connect
    other = abb.open()
    with pytest.raises(NotReady, match="mastership held by another client"):
        other.connect(2.0)
    watcher = abb.open(read_only=True)  # reading needs no mastership
    watcher.connect(2.0)
    assert watcher.status().connected
    with pytest.raises(NotReady, match="read-only"):
        watcher.move_joints(TARGET)
    abb.driver.close()  # released on close
    assert ctl.master is None
    other.connect(2.0)
    other.move_joints(TARGET, timeout=5.0)
    other.close()
    watcher.close()


def test_motors_off_during_a_move_is_not_ready_until_switched_on(abb):
    rob, ctl = abb.driver, abb.server.controller
    abb.cell.faults.arm("motoroff")
    with elapsed_below(2.0 + MARGIN), pytest.raises(NotReady, match="motoroff during the move"):
        rob.move_joints(TARGET, timeout=2.0)
    st = rob.status()
    assert not st.moving and "motoroff" in st.message and "RAPID stopped" in st.message
    with pytest.raises(NotReady, match="switch the motors on"):
        rob.move_joints(TARGET, timeout=2.0)
    np.testing.assert_allclose(rob.read_joints().q, abb.cell.robot_state().q, atol=1e-7)
    ctl.motors(True)  # the operator
    rob.move_joints(TARGET, timeout=2.0)  # RAPID restarted from main
    np.testing.assert_allclose(rob.read_joints().q, TARGET, atol=1e-4)


def test_a_lost_mastership_is_not_ready_until_the_other_client_lets_go(abb):
    rob, ctl = abb.driver, abb.server.controller
    abb.cell.faults.arm("mastership")
    with pytest.raises(NotReady, match=f"MoveAbsJ.*mastership held.*{OTHER_CLIENT}"):
        rob.move_joints(TARGET, timeout=2.0)
    rob.close()
    with pytest.raises(NotReady, match="mastership held"):
        rob.connect(2.0)
    ctl.release_mastership()  # the pendant lets go
    rob.connect(2.0)
    rob.move_joints(TARGET, timeout=2.0)
    np.testing.assert_allclose(rob.read_joints().q, TARGET, atol=1e-4)


def test_a_rapid_error_during_a_move_is_rejected_with_the_event_log(abb):
    rob = abb.driver
    abb.cell.faults.arm("rapid")
    with pytest.raises(CommandRejected,
                       match="RAPID stopped during the move: event 41617 Execution error"):
        rob.move_joints(TARGET, timeout=2.0)
    assert not rob.status().moving
    rob.move_joints(TARGET, timeout=2.0)  # the next move restarts the module
    np.testing.assert_allclose(rob.read_joints().q, TARGET, atol=1e-4)


def test_without_restart_a_stopped_rapid_is_not_ready(cell):
    with serve_robot("abb", cell, restart_rapid=False) as rig:
        rig.server.controller.pendant_stop()
        with pytest.raises(NotReady, match="RAPID is stopped"):
            rig.driver.move_joints(TARGET, timeout=2.0)


def test_manual_mode_moves_nothing_but_reads(abb):
    abb.server.controller.opmode = "MANR"
    with pytest.raises(NotReady, match="operating mode MANR"):
        abb.driver.move_joints(TARGET, timeout=2.0)
    assert abb.driver.status().message == "controller motoron, MANR, RAPID running"
    assert abb.driver.read_joints().q.shape == (3,)


def test_a_wrong_password_or_a_missing_module_is_said_at_connect(abb):
    abb.driver.close()  # its mastership
    with pytest.raises(CommandRejected, match="authentication refused for user 'Default User'"):
        abb.open(password="wrong").connect(2.0)
    with pytest.raises(CommandRejected, match="RAPID module Elsewhere loaded in task T_ROB1"):
        abb.open(module="Elsewhere").connect(2.0)


def test_the_move_writes_the_module_protocol_and_the_wire_is_logged(abb, caplog):
    rob, ctl = abb.driver, abb.server.controller
    with caplog.at_level(logging.DEBUG, logger="drivers.abb.link"):
        rob.move_joints(TARGET, speed=0.25, timeout=2.0)
    robax, _ = C.parse_jointtarget(ctl.pers[C.VAR_JOINTS])
    np.testing.assert_allclose(robax, list(np.rad2deg(TARGET)) + [0, 0, 0], atol=1e-4)
    assert C.parse_num(ctl.pers[C.VAR_TIME]) == pytest.approx(0.3 / 0.25, rel=1e-4)
    assert ctl.pers[C.VAR_ZONE] == C.ZONE_FINE and ctl.pers[C.VAR_SEQ] == ctl.pers[C.VAR_ACK]
    wire = [r.getMessage() for r in caplog.records if r.levelno == logging.DEBUG]
    dev = f"robot {rob.url}: "
    sent = [m for m in wire if m.startswith(dev + "> POST /rw/rapid/symbol/")]
    names = [m.split("CellcalServer/")[1].split("?")[0] for m in sent]
    assert names == [C.VAR_JOINTS, C.VAR_TIME, C.VAR_ZONE, C.VAR_KIND, C.VAR_SEQ]  # seq last
    assert sent[-1].endswith(f"?action=set&json=1 value={ctl.pers[C.VAR_SEQ]}")  # the form
    assert sent[2].endswith(f"value={C.ZONE_FINE}")
    assert dev + "< 204 (no content)" in wire
    assert any(m.startswith(dev + "< 200 ms-jointtarget: rax_1=") for m in wire)
    assert any(m.startswith(dev + "< 200 pnl-ctrlstate: ctrlstate=motoron") for m in wire)


def test_a_closed_link_mid_move_leaves_the_session_and_its_mastership(abb):
    rob, ctl = abb.driver, abb.server.controller
    master = ctl.master
    abb.cell.faults.arm("drop")
    with pytest.raises(ConnectionLost, match="MoveAbsJ"):
        rob.move_joints(TARGET, timeout=2.0)
    assert ctl.master == master  # nobody else could take the robot meanwhile
    rob.connect(2.0)
    assert ctl.master == master
    rob.move_joints(TARGET, timeout=2.0)


def test_close_after_a_link_lost_mid_move_ends_its_session(abb):
    """The capture service's reconnection (close, then connect) after a dropped move: the
    old session's mastership is released, the new session takes it."""
    rob, ctl = abb.driver, abb.server.controller
    old = ctl.master
    abb.cell.faults.arm("drop")
    with pytest.raises(ConnectionLost, match="MoveAbsJ"):
        rob.move_joints(TARGET, timeout=2.0)
    rob.close()
    assert ctl.master is None and old not in abb.server.sessions
    rob.connect(2.0)
    assert ctl.master not in (None, old)
    rob.move_joints(TARGET, timeout=2.0)


def test_a_speed_override_below_100_percent_is_a_warning_at_connect(abb, caplog):
    abb.driver.close()
    abb.server.controller.speedratio = 25
    with caplog.at_level(logging.WARNING, logger="drivers.abb.driver"):
        abb.driver.connect(2.0)
    assert any("speed ratio 25 % at the controller: moves take 4x longer" in r.getMessage()
               for r in caplog.records)
