"""The RTDE simulator against the real ur-rtde receive client and a scripted client."""

from __future__ import annotations

import socket
import struct
import time

import numpy as np
import pytest

from sim_drivers import rtde_wire as w
from sim_drivers.cell import SimCell
from sim_drivers.rtde_server import PortUnavailable, RtdeSimServer, controller_fields
from sim_drivers.truth import ToyArm
from tests.sim_drivers.rtde_helpers import (
    RtdeTranscript,
    loopback_host,
    receive_client,
    setup_outputs,
)

Q0 = np.array([0.3, 0.5, -0.7])


def _wait_for(pred, timeout: float = 1.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.005)
    return pred()


def test_real_receive_client_reads_every_variable_from_the_cell():
    cell = SimCell(ToyArm(), seed=1, time_scale=0.0, q0=Q0)
    server = RtdeSimServer(cell, host=loopback_host())
    with server, receive_client(server.host) as rx:  # variables=[]: all of them
        assert server.requested_frequency == 500.0  # e-Series controller version
        q = np.array(rx.getActualQ())
        assert q.shape == (6,)
        np.testing.assert_allclose(q[:3], Q0, atol=1e-9)
        np.testing.assert_array_equal(q[3:], 0.0)  # ToyArm padded to 6 joints
        pose = np.array(rx.getActualTCPPose())
        np.testing.assert_allclose(pose[:3] * 1000.0, ToyArm().nominal_tcp(Q0), atol=1e-6)
        assert rx.getSafetyStatusBits() == 1  # bit 0: normal mode
        assert rx.getRobotMode() == 7 and rx.getSafetyMode() == 1
        assert rx.getRuntimeState() == 2 and rx.getRobotStatus() == 3
        assert not rx.isProtectiveStopped() and not rx.isEmergencyStopped()
        assert rx.getJointMode() == [253] * 6
        assert len(rx.getActualToolAccelerometer()) == 3
        assert rx.getOutputIntRegister(12) == 0 and rx.getOutputDoubleRegister(19) == 0.0
        t0 = rx.getTimestamp()
        assert _wait_for(lambda: rx.getTimestamp() > t0 + 0.02)

        cell.trigger_protective_stop()  # the pump carries it to the stream
        assert _wait_for(rx.isProtectiveStopped)
        bits = rx.getSafetyStatusBits()
        assert bits & (1 << 2) and not bits & 1
        assert rx.getSafetyMode() == 3 and rx.getRuntimeState() == 4
    assert not server.running


def test_requested_frequency_is_honoured():
    server = RtdeSimServer(host=loopback_host())
    with server, receive_client(server.host, 125.0, ["timestamp", "actual_q"]) as rx:
        assert server.requested_frequency == 125.0
        n0, t0 = server.packages_sent, rx.getTimestamp()
        time.sleep(0.4)
        rate = (server.packages_sent - n0) / 0.4
        assert 90 < rate < 140
        assert rx.getTimestamp() - t0 == pytest.approx(0.4, abs=0.1)


def _types(*names: str) -> bytes:
    return ",".join(w.OUTPUT_TYPES[n] for n in names).encode()


def test_handshake_transcript():
    outputs = ["timestamp", "actual_q", "safety_status_bits"]
    transcript = [
        (w.REQUEST_PROTOCOL_VERSION, b"\x00\x03", w.REQUEST_PROTOCOL_VERSION, b"\x00"),
        (w.REQUEST_PROTOCOL_VERSION, b"\x00\x02", w.REQUEST_PROTOCOL_VERSION, b"\x01"),
        (w.GET_URCONTROL_VERSION, b"", w.GET_URCONTROL_VERSION, struct.pack(">IIII", 5, 11, 1, 0)),
        (w.CONTROL_PACKAGE_SETUP_OUTPUTS, setup_outputs(50.0, ["timestamp", "bogus_variable"]),
         w.CONTROL_PACKAGE_SETUP_OUTPUTS, b"\x00DOUBLE,NOT_FOUND"),
        (w.CONTROL_PACKAGE_SETUP_OUTPUTS, setup_outputs(50.0, outputs),
         w.CONTROL_PACKAGE_SETUP_OUTPUTS, b"\x01" + _types(*outputs)),
        (w.CONTROL_PACKAGE_SETUP_INPUTS, b"input_int_register_0,speed_slider_fraction,",
         w.CONTROL_PACKAGE_SETUP_INPUTS, b"\x02INT32,DOUBLE"),
        (w.CONTROL_PACKAGE_START, b"", w.CONTROL_PACKAGE_START, b"\x01"),
        (w.DATA_PACKAGE, b"\x07" + struct.pack(">i", 1), w.TEXT_MESSAGE,
         lambda p: b"unknown input recipe 7" in p),
        (ord("X"), b"", w.TEXT_MESSAGE, lambda p: b"unknown RTDE package type" in p),
    ]
    with RtdeSimServer(host=loopback_host()) as server:
        server.publish(_state(q=[0.1, 0.2, 0.3]))
        script = RtdeTranscript(server.host, transcript)
        script.play()
        assert script.used == len(transcript)
        pause = [(w.CONTROL_PACKAGE_PAUSE, b"", w.CONTROL_PACKAGE_PAUSE, b"\x01")]
        RtdeTranscript(server.host, pause).play()
    assert script.data, "no data package after START"
    payload = script.data[-1]
    assert payload[0] == 1
    ts, q, bits = w.unpack_values(["DOUBLE", "VECTOR6D", "UINT32"], payload[1:])
    assert len(payload) == 1 + 8 + 48 + 4
    assert ts >= 0 and q[:3] == pytest.approx([0.1, 0.2, 0.3]) and bits == 1


def test_transcript_fails_when_an_expected_exchange_is_unused():
    transcript = [
        (w.REQUEST_PROTOCOL_VERSION, b"\x00\x02", w.REQUEST_PROTOCOL_VERSION, b"\x01"),
        # PAUSE gets an answer, but not the START reply this transcript expects
        (w.CONTROL_PACKAGE_PAUSE, b"", w.CONTROL_PACKAGE_START, b"\x01"),
    ]
    with RtdeSimServer(host=loopback_host()) as server:
        script = RtdeTranscript(server.host, transcript, timeout=0.3)
        with pytest.raises(AssertionError, match="exchange 1"):
            script.play()
        assert script.used == 1
        # a START before any recipe is refused
        RtdeTranscript(server.host, [(w.CONTROL_PACKAGE_START, b"", w.CONTROL_PACKAGE_START,
                                      b"\x00")]).play()


def test_falls_back_when_30004_is_taken():
    taken = loopback_host()
    other = loopback_host()
    blocker = socket.socket()
    try:
        blocker.bind((taken, w.RTDE_PORT))
        blocker.listen(1)
        with RtdeSimServer(host=taken, fallback_hosts=[other]) as server:
            assert server.host == other and server.url == f"ur://{other}"
        with pytest.raises(PortUnavailable, match="unavailable"):
            RtdeSimServer(host=taken, fallback_hosts=()).start()
    finally:
        blocker.close()


def test_stop_closes_clients_and_process():
    server = RtdeSimServer(host=loopback_host()).start()
    client = socket.create_connection((server.host, w.RTDE_PORT), timeout=1.0)
    try:
        assert _wait_for(lambda: server.clients == 1)
        server.stop()
        assert client.recv(10) == b""  # closed by the server
        assert not server.running
        server.stop()  # idempotent
    finally:
        client.close()


class _S:
    def __init__(self, **kw):
        self.q, self.qd, self.tcp = [0.0] * 3, [0.0] * 3, [0.0, 0.0, 0.0]
        self.protective_stop = self.emergency_stop = self.fault = False
        self.__dict__.update(kw)


def _state(**kw):
    return _S(**kw)


@pytest.mark.parametrize(
    ("flags", "bits", "mode", "runtime"),
    [
        ({}, 0b1, 1, 2),
        ({"protective_stop": True}, (1 << 2) | (1 << 10), 3, 4),
        ({"emergency_stop": True}, (1 << 6) | (1 << 7) | (1 << 10), 7, 1),
        ({"fault": True}, (1 << 9) | (1 << 10), 9, 1),
    ],
)
def test_controller_fields_follow_the_rtde_guide(flags, bits, mode, runtime):
    f = controller_fields(_state(tcp=[100.0, -20.0, 300.0], **flags))
    assert f["safety_status_bits"] == bits
    assert f["safety_mode"] == mode and f["runtime_state"] == runtime
    np.testing.assert_allclose(f["actual_TCP_pose"][:3], [0.1, -0.02, 0.3])
    assert controller_fields(_state(), program_running=False)["runtime_state"] == 1
