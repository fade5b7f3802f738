"""LineTracker's own behaviour against the simulated tracker server over real TCP sockets
and a pty: its events, wire faults, transcripts and words. What every tracker driver does
is checked by the conformance suite (tests/drivers/conformance/), on this driver too."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import (
    BeamBroken,
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    NotReady,
    ProtocolError,
)
from drivers.urls import open_tracker
from tests.drivers.rigs import serve_tracker
from tests.sim_drivers.helpers import MARGIN, ScriptedPeer, elapsed_below, make_cell


def test_measure_noise_is_reproducible_and_matches_sigma():
    out = []
    for _ in range(2):
        cell = make_cell(seed=11)
        with serve_tracker("line-tcp", cell) as rig:
            out.append(np.array([rig.driver.measure(0.01, 2.0).xyz for _ in range(60)]))
    assert np.allclose(out[0], out[1], atol=1e-4)  # 5 decimals on the wire
    sigma = cell.tracker_sigma(cell.true_point())
    assert np.std(out[0], axis=0) == pytest.approx([sigma] * 3, rel=0.4)


def test_events_are_kept_apart_from_replies(line_tracker):
    server, tracker = line_tracker.server, line_tracker.driver
    assert tracker.model == "SIMTRACK-1"
    server.event("TEMP 20.4")
    server.event("BEAM_LOST")
    st = tracker.status()
    assert st.initialised
    events = [e for _, e in tracker.events(poll_s=0.1)]
    assert events == ["TEMP 20.4", "BEAM_LOST"]
    assert tracker.events() == []


def test_beam_fault_raises_beam_broken_then_recovers(line_tracker):
    cell, tracker = line_tracker.cell, line_tracker.driver
    cell.faults.arm("beam")
    with elapsed_below(1.0 + MARGIN), pytest.raises(BeamBroken, match="MEAS"):
        tracker.measure(0.1, timeout=1.0)
    assert [e for _, e in tracker.events(poll_s=0.05)] == ["BEAM_LOST", "BEAM_RESTORED"]
    tracker.measure(0.1, timeout=1.0)


def test_slow_reply_times_out_then_recovers(line_tracker):
    cell, tracker = line_tracker.cell, line_tracker.driver
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout):
        tracker.measure(0.1, timeout=0.3)
    # the driver resynchronises (reconnect) and the next call works
    m = tracker.measure(0.1, timeout=2.0)
    assert m.n == 100


def test_slow_reply_over_pty_is_discarded(cell):
    cell.faults.spec.delay_s = 0.5
    with serve_tracker("line-pty", cell) as rig:
        trk = rig.driver
        assert rig.server.url.startswith("tracker+serial:///dev/")
        cell.faults.arm("slow")
        with elapsed_below(0.2 + MARGIN), pytest.raises(CommandTimeout):
            trk.status(timeout=0.2)
        # the late OK STATUS must not be taken as the reply to MEAS
        m = trk.measure(0.05, timeout=2.0)
        assert m.n == 50


def test_dropped_connection_is_retried_once(line_tracker):
    cell, tracker = line_tracker.cell, line_tracker.driver
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN):
        m = tracker.measure(0.1, timeout=1.0)  # reconnects and measures again
    assert m.n == 100


def test_dropped_connection_twice_raises_then_connect_recovers(line_tracker):
    cell, tracker = line_tracker.cell, line_tracker.driver
    cell.faults.arm("drop", times=5)
    with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost):
        tracker.status(timeout=1.0)
    cell.faults.disarm()
    tracker.connect(timeout=1.0)
    assert tracker.status().initialised


def test_garbage_reply_is_protocol_error_then_recovers(line_tracker):
    cell, tracker = line_tracker.cell, line_tracker.driver
    cell.faults.arm("garbage")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtocolError):
        tracker.measure(0.1, timeout=1.0)
    assert tracker.measure(0.1, timeout=1.0).n == 100


def test_not_initialised_and_not_warmed_up():
    cell = make_cell(warmup_s=100.0)
    with serve_tracker("line-tcp", cell, auto_init=False) as rig:
        trk = rig.driver
        with pytest.raises(NotReady, match="NOT_INITIALISED"):
            trk.measure(0.1, 1.0)
        trk.initialise(1.0)
        with pytest.raises(NotReady, match="NOT_WARMED_UP"):
            trk.measure(0.1, 1.0)
        cell.advance(100.0)
        trk.measure(0.1, 1.0)


def test_occlusion_and_range():
    target = make_cell().true_point()
    with serve_tracker("line-tcp", make_cell(occlusions=[(target / 2, 50.0)])) as rig, \
            pytest.raises(BeamBroken, match="BEAM_BROKEN"):
        rig.driver.measure(0.1, 1.0)
    with serve_tracker("line-tcp", make_cell(tracker_range_mm=(2000.0, 3000.0))) as rig, \
            pytest.raises(BeamBroken, match="NO_TARGET"):
        rig.driver.measure(0.1, 1.0)


def test_bad_mode_is_rejected(line_tracker):
    with pytest.raises(CommandRejected, match="BAD_ARGUMENT"):
        line_tracker.driver.set_stationary_time(0)


def test_transcript():
    script = [
        ("HELLO", ["OK HELLO AT960 SN123 2.1"]),
        ("STATUS?", ["OK STATUS init=0 warm=1 beam=1 target=1"]),
        ("INIT", ["EVT TEMP 20.4", "OK INIT"]),
        ("SET MODE STATIONARY time_ms=250", ["OK MODE STATIONARY time_ms=250"]),
        (
            "MEAS",
            [
                "OK MEAS x=1.5 y=-2.25 z=3 sx=0.01 sy=0.02 sz=0.03 n=250 "
                "T=20.4 P=1012.5 H=40.0 t=1700000000.5"
            ],
        ),
        ("MEAS", ["ERR 14 BEAM_BROKEN lost"]),
        ("STATUS?", ["EVT BEAM_RESTORED", "OK STATUS init=1 warm=0 beam=1 target=1"]),
    ]
    with ScriptedPeer(script) as peer:
        trk = open_tracker(f"tracker+tcp://127.0.0.1:{peer.port}")
        try:
            trk.connect(1.0)
            assert (trk.model, trk.serial, trk.firmware) == ("AT960", "SN123", "2.1")
            m = trk.measure(0.25, timeout=1.0)
            assert np.allclose(m.xyz, [1.5, -2.25, 3.0])
            assert np.allclose(m.std, [0.01, 0.02, 0.03])
            assert m.n == 250 and m.timestamp == 1700000000.5
            assert m.env == {"temp_c": 20.4, "pressure_hpa": 1012.5, "humidity_pct": 40.0}
            with pytest.raises(BeamBroken):
                trk.measure(0.25, timeout=1.0)
            assert not trk.status().warmed_up
            assert [e for _, e in trk.events()] == ["TEMP 20.4", "BEAM_RESTORED"]
        finally:
            trk.close()
        peer.check()


def test_transcript_garbage_and_unknown_error():
    script = [
        ("HELLO", ["OK HELLO X Y Z"]),
        ("STATUS?", ["OK STATUS init=1 warm=1 beam=1"]),
        ("STATUS?", ["HELLO THERE"]),
    ]
    with ScriptedPeer(script) as peer:
        trk = open_tracker(f"tracker+tcp://127.0.0.1:{peer.port}")
        try:
            trk.connect(1.0)
            with pytest.raises(ProtocolError, match="unexpected reply"):
                trk.status(0.5)
        finally:
            trk.close()
        peer.check()
