"""EmsconTracker's own behaviour over real sockets against the simulated emScon server:
units and coordinates another client set, packet framing, status changes, emScon's result
codes. What every tracker driver does is checked by the conformance suite
(tests/drivers/conformance/), on this driver too."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np
import pytest

from drivers.errors import BeamBroken, CommandRejected, CommandTimeout, NotReady, ProtocolError
from drivers.leica import codec
from drivers.leica.driver import EmsconTracker
from drivers.leica.enums import (
    ES_AngleUnit,
    ES_LengthUnit,
    ES_PressureUnit,
    ES_TemperatureUnit,
)
from drivers.leica.enums import ES_CoordinateSystemType as CS
from drivers.protocols import ReflectorSelect
from drivers.urls import open_tracker
from tests.drivers.rigs import serve_tracker
from tests.sim_drivers.helpers import MARGIN, elapsed_below, make_cell


def _raw(trk, packet):
    """Send one command as a raw emScon packet (another client changing the server)."""
    return trk._call(packet, time.monotonic() + 2.0)


def _close_to_truth(m, cell, k=6.0):
    truth = cell.true_point()
    assert np.all(np.abs(m.xyz - truth) < k * cell.tracker_sigma(truth)), (m.xyz, truth)


def test_measure_against_truth(emscon_tracker):
    cell, server, tracker = emscon_tracker.cell, emscon_tracker.server, emscon_tracker.driver
    assert isinstance(tracker, EmsconTracker) and isinstance(tracker, ReflectorSelect)
    assert server.stationary[0] != 200
    m = tracker.measure(duration_s=0.2, timeout=2.0)
    assert server.stationary == (200, 0)  # the measuring time went to the server
    _close_to_truth(m, cell)
    assert m.cov is not None and np.allclose(np.diag(m.cov), m.std**2)
    assert m.reflector == "RRR 1.5in" and m.face == 1 and m.n == 1


def test_connect_initialises_a_tracker_that_is_not(cell):
    cell.tracker_initialised = False
    with serve_tracker("emscon", cell) as rig:
        assert cell.tracker_initialised
        rig.driver.measure(0.01, 2.0)


def test_result_without_covariances(cell):
    with serve_tracker("emscon", cell, serve_kw={"result2": False}) as rig:
        m = rig.driver.measure(0.05, 2.0)
        assert m.cov is None
        _close_to_truth(m, cell)


@pytest.mark.parametrize("units,coords", [
    ((ES_LengthUnit.ES_LU_Meter, ES_AngleUnit.ES_AU_Degree, ES_TemperatureUnit.ES_TU_Celsius,
      ES_PressureUnit.ES_PU_Mbar, 0), CS.ES_CS_RHR),
    ((ES_LengthUnit.ES_LU_Inch, ES_AngleUnit.ES_AU_Gon, ES_TemperatureUnit.ES_TU_Fahrenheit,
      ES_PressureUnit.ES_PU_Psi, 0), CS.ES_CS_LHRY),
    ((ES_LengthUnit.ES_LU_Foot, ES_AngleUnit.ES_AU_Degree, ES_TemperatureUnit.ES_TU_Fahrenheit,
      ES_PressureUnit.ES_PU_InHg, 0), CS.ES_CS_SCC),
])
def test_a_server_left_in_other_units_by_another_client(cell, units, coords):
    with serve_tracker("emscon", cell) as rig:
        srv, other = rig.server, rig.driver
        # the other client leaves the server in its own units and coordinates
        _raw(other, codec.SetUnitsCT(lenUnitType=units[0], angUnitType=units[1],
                                     tempUnitType=units[2], pressUnitType=units[3]))
        _raw(other, codec.SetCoordinateSystemTypeCT(coordSysType=coords))
        other.close()
        assert srv.units[0] == units[0] and srv.coord_sys == coords
        with open_tracker(srv.url) as trk:
            trk.connect(2.0)
            m = trk.measure(0.05, 2.0)
        _close_to_truth(m, cell)
        assert m.temp_c == pytest.approx(20.0, abs=0.1)
        assert m.pressure_hpa == pytest.approx(1013.25, abs=1e-6)


def test_units_changed_by_another_client_between_measurements(emscon_tracker):
    cell, server, tracker = emscon_tracker.cell, emscon_tracker.server, emscon_tracker.driver
    tracker.measure(0.05, 2.0)
    with open_tracker(server.url) as other:
        other.connect(2.0)
        _raw(other, codec.SetUnitsCT(lenUnitType=ES_LengthUnit.ES_LU_Meter))
        _raw(other, codec.SetStationaryModeParamsCT(lMeasTime=3000, bUseADM=1))
    m = tracker.measure(0.05, 2.0)  # the status changes make the driver check and reset
    _close_to_truth(m, cell)
    assert server.units[0] == ES_LengthUnit.ES_LU_Millimeter and server.stationary == (50, 0)
    names = [e for _, e in tracker.events()]
    assert "ES_SSC_UnitsChanged" in names and "ES_SSC_StationaryModeParamsChanged" in names


def test_units_changed_during_the_measurement_measures_again(emscon_tracker):
    cell, server, tracker = emscon_tracker.cell, emscon_tracker.server, emscon_tracker.driver
    tracker.measure(0.05, 2.0)
    calls = {"n": 0}
    real = cell.tracker_measure

    def measure_while_another_client_sets_metres(duration_s):
        calls["n"] += 1
        if calls["n"] == 1:
            with open_tracker(server.url) as other:
                other.connect(2.0)
                _raw(other, codec.SetUnitsCT(lenUnitType=ES_LengthUnit.ES_LU_Meter))
        return real(duration_s)

    cell.tracker_measure = measure_while_another_client_sets_metres
    m = tracker.measure(0.05, 2.0)
    assert calls["n"] == 2
    _close_to_truth(m, cell)


@pytest.mark.parametrize("chunk", [1, 5, 13])
def test_packets_split_over_many_reads(cell, chunk):
    with serve_tracker("emscon", cell, serve_kw={"chunk_bytes": chunk}) as rig:
        trk = rig.driver
        _close_to_truth(trk.measure(0.05, 5.0), cell)
        assert len(trk.reflectors(5.0)) == 5


def test_interleaved_status_changes_and_packets_in_one_read(cell):
    with serve_tracker("emscon", cell, serve_kw={"chatter": True}) as rig:
        trk = rig.driver
        for _ in range(3):
            _close_to_truth(trk.measure(0.05, 2.0), cell)
        assert trk.environment().temp_c == pytest.approx(20.0)
        names = [e for _, e in trk.events()]
        assert names.count("ES_SSC_EnvironmentParamsChanged") >= 10


def test_beam_break_in_the_middle_of_measuring(emscon_tracker):
    cell, tracker = emscon_tracker.cell, emscon_tracker.driver
    cell.faults.arm("beam")
    with elapsed_below(2.0 + MARGIN), pytest.raises(BeamBroken, match="10009 ES_RS_NoStationary"):
        tracker.measure(0.05, 2.0)
    _close_to_truth(tracker.measure(0.05, 2.0), cell)  # restored: the next one is fine
    names = [e for _, e in tracker.events()]
    assert "ES_SSC_MeasStatus_NotReady" in names and "ES_SSC_MeasStatus_Ready" in names


def test_occluded_beam_is_beam_broken_with_the_code(emscon_tracker):
    emscon_tracker.cell.beam_ok = False
    with pytest.raises(BeamBroken, match="10004 ES_RS_MeasurementStatusNotReady"):
        emscon_tracker.driver.measure(0.05, 2.0)


def test_not_initialised_and_not_warmed_up(cell):
    cell.tracker_initialised = False
    with serve_tracker("emscon", cell, auto_init=False) as rig:
        trk = rig.driver
        with pytest.raises(NotReady, match="39 ES_RS_TrackerNotInitialized"):
            trk.measure(0.05, 2.0)
        with pytest.raises(NotReady, match="not initialised"):
            trk.check_ready()
        trk.initialise(2.0)
        cell.warmup_s = cell.now() + 3600.0
        with pytest.raises(NotReady, match="10012 ES_RS_SensorNotWarmedUp"):
            trk.measure(0.05, 2.0)
        r = trk.ready()
        assert r.initialised and not r.warmed_up and "ES_LPS_LaserHeatingUp" in r.problems[0]


def test_robot_moving_is_no_stationary_result(emscon_tracker):
    cell, tracker = emscon_tracker.cell, emscon_tracker.driver
    cell.time_scale = 1e-3
    cell.command_move_joints(np.array([0.5, 0.5, -0.5]), speed=0.01)
    with pytest.raises(BeamBroken, match="ES_RS_NoStationaryResult"):
        tracker.measure(0.05, 2.0)


def test_garbage_is_protocol_error_within_timeout_then_recovers(emscon_tracker):
    cell, tracker = emscon_tracker.cell, emscon_tracker.driver
    cell.faults.arm("garbage")
    with elapsed_below(1.0 + MARGIN), pytest.raises(ProtocolError, match="not emScon"):
        tracker.measure(0.05, 1.0)
    _close_to_truth(tracker.measure(0.05, 2.0), cell)  # reconnected


def test_slow_server_is_a_timeout_then_recovers(emscon_tracker):
    cell, tracker = emscon_tracker.cell, emscon_tracker.driver
    cell.faults.spec.delay_s = 1.0
    cell.faults.arm("slow")
    with elapsed_below(0.3 + MARGIN), pytest.raises(CommandTimeout, match="no answer in time"):
        tracker.measure(0.05, 0.3)
    _close_to_truth(tracker.measure(0.05, 3.0), cell)


def _mute_server(reply: bytes = b""):
    """A TCP peer that reads everything and answers ``reply`` once (or nothing)."""
    ls = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def run():
        ls.settimeout(0.05)
        conns = []
        while not stop.is_set():
            try:
                c, _ = ls.accept()
                conns.append(c)
                if reply:
                    c.sendall(reply)
            except TimeoutError:
                pass
        for c in conns:
            c.close()
        ls.close()

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return ls.getsockname()[1], stop, t


@pytest.mark.parametrize("reply", [b"", b"HELLO WORLD\n" * 4, bytes(range(40))])
def test_silence_or_garbage_at_connect_is_a_typed_error_within_timeout(reply):
    port, stop, t = _mute_server(reply)
    try:
        trk = open_tracker(f"emscon://127.0.0.1:{port}")
        with elapsed_below(0.5 + MARGIN), pytest.raises((CommandTimeout, ProtocolError)):
            trk.connect(0.5)
        assert not trk.connected
    finally:
        stop.set()
        t.join(2.0)


def test_unknown_reflector_is_rejected_naming_the_known_ones(emscon_tracker):
    with pytest.raises(CommandRejected, match="RRR 0.5in"):
        emscon_tracker.driver.set_reflector("Nope 2in")


def test_reflector_by_name_and_its_distance_constant(emscon_tracker):
    cell, server, tracker = emscon_tracker.cell, emscon_tracker.server, emscon_tracker.driver
    r = tracker.set_reflector("catseye 3IN")
    assert (r.name, r.target_type) == ("CatsEye 3in", "ES_TT_CatsEye")
    assert tracker.reflector().name == "CatsEye 3in" and cell.tracker_reflector.id == r.id
    truth = cell.true_point()
    d = np.mean([np.linalg.norm(tracker.measure(0.05, 2.0).xyz) for _ in range(40)])
    # the mounted RRR has constant 0, the selected cat's eye 0.25 mm: reads 0.25 mm short
    assert d - np.linalg.norm(truth) == pytest.approx(-0.25, abs=0.01)
    m = tracker.measure(0.05, 2.0)
    assert m.reflector == "CatsEye 3in"
    # another client selects another reflector: the driver puts its own back
    with open_tracker(server.url) as other:
        other.connect(2.0)
        other.set_reflector("RRR 0.5in")
    assert tracker.measure(0.05, 2.0).reflector == "CatsEye 3in"
    assert cell.tracker_reflector.name == "CatsEye 3in"


def test_two_faces_cancel_the_collimation_error():
    c = 20e-6
    cell = make_cell(seed=6, tracker_collimation_rad=c)
    with serve_tracker("emscon", cell) as rig:
        trk = rig.driver
        truth = cell.true_point()
        pairs = [trk.measure_faces(0.05, 10.0) for _ in range(20)]
        assert trk.face() in (1, 2)
    f1 = np.mean([a.xyz for a, _ in pairs], axis=0)
    f2 = np.mean([b.xyz for _, b in pairs], axis=0)
    assert all(a.face == 1 and b.face == 2 for a, b in pairs)
    rho = np.hypot(truth[0], truth[1])
    assert np.linalg.norm(f1 - f2) == pytest.approx(2 * c * rho, rel=0.1)
    assert np.linalg.norm((f1 + f2) / 2 - truth) < 0.01


def test_url_parameters():
    trk = open_tracker("emscon://10.0.0.9?reflector=RRR%200.5in")
    assert trk._link.port == 700 and trk._want_reflector == "RRR 0.5in"
    with pytest.raises(ValueError, match="unknown parameter"):
        open_tracker("emscon://10.0.0.9:700?units=m")
