"""Interoperation: the independent ABB Robot Web Services client ``abb-robot-client``
(Apache-2.0, PyPI, ``abb_robot_client.rws.RWS``: requests with HTTP digest
authentication, RWS 1.0 of IRC5/RobotWare 6) talks to the simulated controller over
loopback, for every resource the ABB driver uses (docs/abb.md lists them).

The client is used through its public methods; the resources it has no method for
(mastership, the controller's identity, the system, the robot type) through its own
request path (``RWS._do_get`` / ``RWS._do_post``: its session, its digest, its JSON).
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.abb import codec as C
from sim_drivers.abb_controller import OTHER_CLIENT
from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from sim_drivers.rws_server import RwsServer
from tests.sim_drivers.helpers import make_cell

rws = pytest.importorskip("abb_robot_client.rws")

MODULE = C.MODULE + "/"


@pytest.fixture
def served():
    cell = make_cell(seed=5)
    with RwsServer(cell) as srv:
        client = rws.RWS(srv.base_url)
        try:
            yield srv, cell, client
        finally:
            client.close()


def _request(client, q_deg, seconds=0.5, seq=None):
    """The module's request as the driver writes it, through the client's own calls."""
    target = rws.JointTarget(np.deg2rad(list(q_deg) + [0] * 3), np.deg2rad([9e9] * 6))
    client.set_rapid_variable_jointtarget(MODULE + C.VAR_JOINTS, target)
    client.set_rapid_variable_num(MODULE + C.VAR_TIME, seconds)
    client.set_rapid_variable(MODULE + C.VAR_ZONE, C.ZONE_FINE)
    client.set_rapid_variable_num(MODULE + C.VAR_KIND, C.KIND_JOINTS)
    seq = seq if seq is not None else int(client.get_rapid_variable_num(MODULE + C.VAR_ACK)) + 1
    client.set_rapid_variable_num(MODULE + C.VAR_SEQ, seq)
    return seq


def test_digest_login_and_the_panel(served):
    srv, cell, client = served
    assert client.get_controller_state() == "motoron"  # the first request authenticates
    assert {"-http-session-", "ABBCX"} <= set(client._session.cookies.keys())
    assert client.get_operation_mode() == "AUTO"
    state = client.get_execution_state()
    assert (state.ctrlexecstate, state.cycle) == ("running", "forever")
    assert client.get_speedratio() == 100.0
    tasks = client.get_tasks()
    assert tasks[C.TASK].motiontask and tasks[C.TASK].active
    cell.trigger_protective_stop()
    assert client.get_controller_state() == "guardstop"
    assert client.get_execution_state().ctrlexecstate == "stopped"  # a guard stop stops RAPID
    cell.clear_protective_stop()
    client.set_controller_state("motoroff")
    assert client.get_controller_state() == "motoroff"
    client.set_controller_state("motoron")
    assert client.get_controller_state() == "motoron"


def test_a_wrong_password_is_refused():
    with RwsServer(make_cell()) as srv:
        client = rws.RWS(srv.base_url, password="nope")
        with pytest.raises(rws.ABBException, match="Unauthorized"):
            client.get_controller_state()
        client.close()


def test_positions_are_the_cells(served):
    _srv, cell, client = served
    jt = client.get_jointtarget()
    np.testing.assert_allclose(np.deg2rad(jt.robax[:3]), cell.robot_state().q, atol=1e-7)
    assert np.all(jt.extax == 9e9)
    rt = client.get_robtarget(tool="tool0", wobj="wobj0")
    np.testing.assert_allclose(rt.trans, cell.robot_state().tcp, atol=1e-5)
    assert rt.rot.shape == (4,) and abs(np.linalg.norm(rt.rot) - 1) < 1e-9


def test_the_rapid_module_moves_the_robot_through_its_variables(served):
    _srv, cell, client = served
    assert client.get_rapid_variable(MODULE + C.VAR_ACK) == "0"
    seq = _request(client, [20.0, 10.0, -30.0])
    assert client.get_rapid_variable_num(MODULE + C.VAR_ACK) == seq  # served, in position
    assert client.get_rapid_variable_num(MODULE + C.VAR_ERR) == 0
    np.testing.assert_allclose(np.rad2deg(cell.robot_state().q), [20, 10, -30], atol=1e-3)
    np.testing.assert_allclose(client.get_jointtarget().robax[:3], [20, 10, -30], atol=1e-3)
    jt = client.get_rapid_variable_jointtarget(MODULE + C.VAR_JOINTS)  # its own parser
    np.testing.assert_allclose(np.rad2deg(jt.robax[:3]), [20, 10, -30], atol=1e-4)
    # outside the joint limits: refused by the module, nothing moves
    seq = _request(client, [200.0, 0.0, 0.0])
    assert client.get_rapid_variable_num(MODULE + C.VAR_ERR) == C.ERR_LIMIT
    assert client.get_rapid_variable(MODULE + C.VAR_MSG).startswith('"LIMIT')
    np.testing.assert_allclose(client.get_jointtarget().robax[:3], [20, 10, -30], atol=1e-3)
    with pytest.raises(rws.ABBException, match="bad num"):
        client.set_rapid_variable(MODULE + C.VAR_TIME, "[1,2]")
    with pytest.raises(rws.ABBException, match="not found"):
        client.get_rapid_variable(MODULE + "nothere")


def test_execution_stop_resetpp_start_and_the_event_log():
    cell = make_cell(seed=6, time_scale=0.05, settle_s=1.0)
    with RwsServer(cell) as srv:
        client = rws.RWS(srv.base_url)
        try:
            _request(client, [30.0, 0.0, 0.0], seconds=5.0)  # 0.3 s of wall time
            assert client.get_rapid_variable_num(MODULE + C.VAR_BUSY) == 1
            client.stop()
            assert client.get_execution_state().ctrlexecstate == "stopped"
            q = cell.robot_state().q
            assert not cell.robot_state().moving and abs(np.rad2deg(q[0]) - 30) > 1
            client.resetpp()
            client.start(cycle="forever")  # from main: the unserved request is forgotten
            assert client.get_execution_state().ctrlexecstate == "running"
            seq = client.get_rapid_variable_num(MODULE + C.VAR_SEQ)
            assert client.get_rapid_variable_num(MODULE + C.VAR_ACK) == seq
            cell.faults.arm("rapid")
            _request(client, [10.0, 0.0, 0.0], seconds=2.0)
            assert client.get_execution_state().ctrlexecstate == "stopped"
            log = client.read_event_log()
            assert log[0].msgtype == 3 and "RAPID error" in log[0].title
        finally:
            client.close()


def test_mastership_identity_system_and_robot_type():
    cell = SimCell(ModelTruth.from_spec("ur10e", None, 7), seed=7)
    with RwsServer(cell) as srv:
        a, b = rws.RWS(srv.base_url), rws.RWS(srv.base_url)
        try:
            a._do_post(C.MASTERSHIP_REQUEST)
            held = a._do_get(C.MASTERSHIP + "/rapid")
            assert C.field(held, "mastershipheldbyme") == "TRUE"
            with pytest.raises(rws.ABBException, match="mastership held"):
                b._do_post(C.MASTERSHIP_REQUEST)
            with pytest.raises(rws.ABBException, match="mastership held"):
                b.set_rapid_variable_num(MODULE + C.VAR_KIND, 1)
            a._do_post(C.MASTERSHIP_RELEASE)
            b._do_post(C.MASTERSHIP_REQUEST)  # free again
            b.close()  # logging out releases it
            assert srv.controller.master is None
            ident = a._do_get(C.IDENTITY)
            assert C.field(ident, "ctrl-id") == "SIM-ur10e-7"
            assert "Virtual" in C.field(ident, "ctrl-type")
            assert "cellcal sim" in C.field(a._do_get(C.SYSTEM), "rwversionname")
            assert C.field(a._do_get(C.ROBOTTYPE), "robot-type") == "ur10e"
            srv.controller.master = OTHER_CLIENT
            with pytest.raises(rws.ABBException, match="FlexPendant"):
                a.stop()
        finally:
            a.close()
