"""Who a device says it is, and measurements that must be new, at the wire (that every
simulator names itself and stamps its measurements strictly later: the conformance suite,
tests/drivers/conformance/)."""

from __future__ import annotations

import pytest

from drivers.errors import ProtocolError
from drivers.protocols import DeviceIdentity
from drivers.urls import open_robot, open_tracker
from tests.sim_drivers.helpers import ScriptedPeer


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
