"""LineTracker against the simulated tracker server over real TCP sockets and a pty."""

from __future__ import annotations

import time

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
from drivers.line_tracker import LineTracker
from drivers.protocols import TrackerDriver
from drivers.urls import open_tracker
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.helpers import MARGIN, ScriptedPeer, elapsed_below, make_cell


@pytest.fixture
def cell():
    return make_cell(seed=3)


@pytest.fixture
def server(cell):
    with TrackerServer(cell) as srv:
        yield srv


@pytest.fixture
def tracker(server):
    trk = open_tracker(server.url)
    trk.connect(timeout=2.0)
    yield trk
    trk.close()


def test_measure_over_tcp(cell, server, tracker):
    assert isinstance(tracker, TrackerDriver)
    assert tracker.model == "SIMTRACK-1"
    st = tracker.status()
    assert st.initialised and st.warmed_up and st.beam_ok
    truth = cell.true_point()
    sigma = cell.tracker_sigma(truth)
    m = tracker.measure(duration_s=0.2, timeout=2.0)
    assert m.n == 200
    assert np.all(np.abs(m.xyz - truth) < 6 * sigma)
    assert np.allclose(m.std, sigma, rtol=0.5)
    assert m.env["temp_c"] == pytest.approx(20.0, abs=0.1)
    assert m.env["pressure_hpa"] == pytest.approx(1013.25)
    assert abs(m.timestamp - time.time()) < 5


def test_measure_noise_is_reproducible_and_matches_sigma():
    out = []
    for _ in range(2):
        cell = make_cell(seed=11)
        with TrackerServer(cell) as srv:
            trk = open_tracker(srv.url)
            trk.connect(2.0)
            try:
                out.append(np.array([trk.measure(0.01, 2.0).xyz for _ in range(60)]))
            finally:
                trk.close()
    assert np.allclose(out[0], out[1], atol=1e-4)  # 5 decimals on the wire
    sigma = cell.tracker_sigma(cell.true_point())
    assert np.std(out[0], axis=0) == pytest.approx([sigma] * 3, rel=0.4)


def test_measure_over_pty(cell):
    with TrackerServer(cell, transport="pty") as srv:
        assert srv.url.startswith("tracker+serial:///dev/")
        trk = open_tracker(srv.url + "?baud=115200")
        trk.connect(2.0)
        try:
            m = trk.measure(0.1, timeout=2.0)
            assert np.linalg.norm(m.xyz - cell.true_point()) < 0.1
        finally:
            trk.close()


def test_events_are_kept_apart_from_replies(server, tracker):
    server.event("TEMP 20.4")
    server.event("BEAM_LOST")
    st = tracker.status()
    assert st.initialised
    events = [e for _, e in tracker.events(poll_s=0.1)]
    assert events == ["TEMP 20.4", "BEAM_LOST"]
    assert tracker.events() == []


def test_beam_fault_raises_beam_broken_then_recovers(cell, server, tracker):
    cell.faults.arm("beam")
    with elapsed_below(1.0 + MARGIN), pytest.raises(BeamBroken, match="MEAS"):
        tracker.measure(0.1, timeout=1.0)
    assert [e for _, e in tracker.events(poll_s=0.05)] == ["BEAM_LOST", "BEAM_RESTORED"]
    tracker.measure(0.1, timeout=1.0)


def test_slow_reply_times_out_then_recovers(cell, server, tracker):
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout):
        tracker.measure(0.1, timeout=0.3)
    # the driver resynchronises (reconnect) and the next call works
    m = tracker.measure(0.1, timeout=2.0)
    assert m.n == 100


def test_slow_reply_over_pty_is_discarded(cell):
    cell.faults.spec.delay_s = 0.5
    with TrackerServer(cell, transport="pty") as srv:
        trk = open_tracker(srv.url)
        trk.connect(2.0)
        try:
            cell.faults.arm("slow")
            with elapsed_below(0.2 + MARGIN), pytest.raises(CommandTimeout):
                trk.status(timeout=0.2)
            # the late OK STATUS must not be taken as the reply to MEAS
            m = trk.measure(0.05, timeout=2.0)
            assert m.n == 50
        finally:
            trk.close()


def test_dropped_connection_is_retried_once(cell, server, tracker):
    cell.faults.arm("drop")
    with elapsed_below(1.0 + MARGIN):
        m = tracker.measure(0.1, timeout=1.0)  # reconnects and measures again
    assert m.n == 100


def test_dropped_connection_twice_raises_then_connect_recovers(cell, server, tracker):
    cell.faults.arm("drop", times=5)
    with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost):
        tracker.status(timeout=1.0)
    cell.faults.disarm()
    tracker.connect(timeout=1.0)
    assert tracker.status().initialised


def test_garbage_reply_is_protocol_error_then_recovers(cell, server, tracker):
    cell.faults.arm("garbage")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtocolError):
        tracker.measure(0.1, timeout=1.0)
    assert tracker.measure(0.1, timeout=1.0).n == 100


def test_not_initialised_and_not_warmed_up():
    cell = make_cell(warmup_s=100.0)
    with TrackerServer(cell) as srv:
        trk = LineTracker(srv.url, f"socket://{srv.address}", auto_init=False)
        trk.connect(1.0)
        try:
            with pytest.raises(NotReady, match="NOT_INITIALISED"):
                trk.measure(0.1, 1.0)
            trk.initialise(1.0)
            with pytest.raises(NotReady, match="NOT_WARMED_UP"):
                trk.measure(0.1, 1.0)
            cell.advance(100.0)
            trk.measure(0.1, 1.0)
        finally:
            trk.close()


def test_occlusion_and_range():
    target = make_cell().true_point()
    cell = make_cell(occlusions=[(target / 2, 50.0)])
    with TrackerServer(cell) as srv, open_tracker(srv.url) as trk:
        trk.connect(1.0)
        with pytest.raises(BeamBroken, match="BEAM_BROKEN"):
            trk.measure(0.1, 1.0)
    cell = make_cell(tracker_range_mm=(2000.0, 3000.0))
    with TrackerServer(cell) as srv, open_tracker(srv.url) as trk:
        trk.connect(1.0)
        with pytest.raises(BeamBroken, match="NO_TARGET"):
            trk.measure(0.1, 1.0)


def test_bad_mode_is_rejected(server, tracker):
    with pytest.raises(CommandRejected, match="BAD_ARGUMENT"):
        tracker.set_stationary_time(0)


def test_server_gone_raises_connection_lost(cell):
    srv = TrackerServer(cell).start()
    trk = open_tracker(srv.url)
    trk.connect(1.0)
    srv.stop()
    try:
        with elapsed_below(1.0 + MARGIN), pytest.raises(ConnectionLost):
            trk.status(timeout=1.0)
        with pytest.raises(ConnectionLost):
            trk.connect(timeout=0.5)
    finally:
        trk.close()


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


# ------------------------------------------------------------ capabilities
def test_line_tracker_capabilities(cell, server, tracker):
    from drivers.protocols import EnvironmentSensor, ReadyGate, TwoFace

    assert isinstance(tracker, ReadyGate) and isinstance(tracker, EnvironmentSensor)
    assert isinstance(tracker, TwoFace)
    assert tracker.check_ready().ok
    env = tracker.environment()
    assert (env.temp_c, env.pressure_hpa, env.source) == (20.0, 1013.25, "station")
    assert tracker.face() == 1
    a, b = tracker.measure_faces(0.05, 5.0)
    assert (a.face, b.face) == (1, 2) and tracker.face() == 2
    assert np.linalg.norm(a.xyz - b.xyz) < 0.1  # no collimation error in this cell


def test_line_tracker_environment_by_hand():
    from sim_drivers.tracker_optics import refractive_index

    cell = make_cell(seed=4, weather_station=False)
    cell.manual_environment = (20.0, 1013.25, 45.0)
    with TrackerServer(cell) as srv:
        trk = open_tracker(srv.url)
        trk.connect(2.0)
        try:
            r = trk.ready()
            assert not r.weather_station and "set_environment" in r.problems[0]
            with pytest.raises(NotReady, match="weather station"):
                trk.check_ready()
            base = np.mean([np.linalg.norm(trk.measure(0.01, 2.0).xyz) for _ in range(40)])
            trk.set_environment(20.0, 1063.25, 45.0)  # 50 hPa too high
            env = trk.environment()
            assert (env.pressure_hpa, env.source) == (1063.25, "manual")
            high = np.mean([np.linalg.norm(trk.measure(0.01, 2.0).xyz) for _ in range(40)])
            with pytest.raises(CommandRejected, match="BAD_ARGUMENT"):
                trk.set_environment(20.0, 5000.0, 45.0)
        finally:
            trk.close()
    L = np.linalg.norm(cell.true_point())
    expected = L * (refractive_index(20, 1013.25, 45) / refractive_index(20, 1063.25, 45) - 1)
    assert expected < 0 and high - base == pytest.approx(expected, abs=0.006)
