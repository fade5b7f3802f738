"""Every tracker driver keeps the TrackerDriver contract (drivers/protocols.py) and its
capabilities on the simulated cell: one test, every driver
(:data:`tests.drivers.rigs.TRACKERS`); what only one driver does is in its own test file."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.errors import BeamBroken, CommandRejected, CommandTimeout, ConnectionLost, NotReady
from drivers.protocols import (
    EnvironmentSensor,
    Identified,
    ReadyGate,
    TrackerDriver,
    TwoFace,
)
from sim_drivers.tracker_optics import refractive_index
from tests.drivers.rigs import serve_tracker
from tests.sim_drivers.helpers import MARGIN, elapsed_below, make_cell


def _close_to_truth(m, cell, k=6.0):
    truth = cell.true_point()
    assert np.all(np.abs(m.xyz - truth) < k * cell.tracker_sigma(truth)), (m.xyz, truth)


def test_measures_the_target(tracker):
    trk, cell = tracker.driver, tracker.cell
    assert isinstance(trk, TrackerDriver)
    for cap in (Identified, ReadyGate, EnvironmentSensor, TwoFace):
        assert isinstance(trk, cap), cap
    st = trk.status()
    assert st.initialised and st.warmed_up and st.beam_ok
    m = trk.measure(duration_s=0.2, timeout=2.0)
    _close_to_truth(m, cell)
    sigma = cell.tracker_sigma(cell.true_point())
    assert np.allclose(m.std, sigma, rtol=0.5)
    assert m.n == tracker.tol.get("n", round(0.2 * tracker.tol.get("n_per_s", 0)))
    assert m.temp_c == pytest.approx(20.0, abs=0.1)
    assert m.pressure_hpa == pytest.approx(1013.25)
    assert m.humidity_pct == pytest.approx(45.0)
    assert m.face == 1
    assert abs(m.timestamp - time.time()) < 5


def test_measurements_are_stamped_strictly_later(tracker):
    ts = [tracker.driver.measure(0.001, 2.0).timestamp for _ in range(5)]
    assert ts == sorted(ts) and len(set(ts)) == 5  # strictly later, even within a millisecond


def test_closed_driver_does_not_reconnect_by_itself(tracker):
    trk = tracker.driver
    trk.close()
    trk.close()  # idempotent
    with pytest.raises(ConnectionLost, match="not connected"):
        trk.measure(0.05, timeout=0.5)
    trk.connect(5.0)
    _close_to_truth(trk.measure(0.05, 2.0), tracker.cell)


def test_beam_break_raises_beam_broken_then_recovers(tracker):
    trk, cell = tracker.driver, tracker.cell
    cell.faults.arm("beam")
    with elapsed_below(2.0 + MARGIN), pytest.raises(BeamBroken, match=tracker.words["beam"]):
        trk.measure(0.05, timeout=2.0)
    _close_to_truth(trk.measure(0.05, 2.0), cell)  # restored: the next one is fine


def test_occluded_beam_is_beam_broken(tracker):
    trk, cell = tracker.driver, tracker.cell
    cell.beam_ok = False
    with pytest.raises(BeamBroken):
        trk.measure(0.05, 2.0)
    assert not trk.status().beam_ok
    assert not trk.ready().target


def test_not_warmed_up_is_not_ready(tracker_kind):
    cell = make_cell(warmup_s=100.0)
    with serve_tracker(tracker_kind, cell) as rig:
        trk = rig.driver
        with pytest.raises(NotReady, match=rig.words["warm"]):
            trk.measure(0.1, 1.0)
        r = trk.ready()
        assert r.initialised and not r.warmed_up and not r.ok
        assert not trk.status().warmed_up
        cell.advance(100.0)
        _close_to_truth(trk.measure(0.1, 1.0), cell)


def test_a_measurement_out_of_time_raises_timeout_then_recovers(tracker_kind):
    cell = make_cell(time_scale=0.05)
    with serve_tracker(tracker_kind, cell) as rig:
        trk = rig.driver
        with elapsed_below(0.1 + MARGIN), pytest.raises(CommandTimeout):
            trk.measure(4.0, timeout=0.1)  # 4 s simulated = 0.2 s wall
        deadline = time.monotonic() + 2.0 + MARGIN
        while True:  # busy (NotReady, transient) until the late measurement has ended
            try:
                m = trk.measure(0.05, timeout=2.0 + MARGIN)
                break
            except NotReady:
                assert time.monotonic() < deadline, "still busy"
                time.sleep(0.01)
        _close_to_truth(m, cell)


def test_two_faces(tracker):
    trk = tracker.driver
    assert trk.face() == 1
    a, b = trk.measure_faces(0.05, 5.0)
    assert (a.face, b.face) == (1, 2) and trk.face() == 2
    assert np.linalg.norm(a.xyz - b.xyz) < 0.1  # no collimation error in this cell


def test_environment_from_the_station(tracker):
    trk, cell = tracker.driver, tracker.cell
    assert trk.check_ready().ok
    env = trk.environment()
    assert (env.temp_c, env.pressure_hpa, env.source) == (20.0, 1013.25, "station")
    cell.pressure_hpa = 990.0
    env = trk.environment()
    assert (env.pressure_hpa, env.source) == (990.0, "station")


@pytest.mark.parametrize("air", [(20.0, 1063.25, 45.0),  # 50 hPa too high
                                 (40.0, 1013.25, 45.0)],  # 20 °C too warm
                         ids=["pressure", "temperature"])
def test_environment_by_hand_without_weather_station(tracker_kind, air):
    cell = make_cell(seed=4, weather_station=False)
    cell.manual_environment = (20.0, 1013.25, 45.0)  # the right air: no refraction error
    with serve_tracker(tracker_kind, cell) as rig:
        trk = rig.driver
        r = trk.ready()
        assert not r.weather_station and not r.ok and "set_environment" in r.problems[0]
        with pytest.raises(NotReady, match="weather station"):
            trk.check_ready()
        base = np.mean([np.linalg.norm(trk.measure(0.01, 2.0).xyz) for _ in range(40)])
        trk.set_environment(*air)
        env = trk.environment()
        assert (env.temp_c, env.pressure_hpa, env.source) == (air[0], air[1], "manual")
        assert trk.measure(0.05, 2.0).temp_c == air[0]
        wrong = np.mean([np.linalg.norm(trk.measure(0.01, 2.0).xyz) for _ in range(40)])
        with pytest.raises(CommandRejected, match=rig.words["bad_air"]):
            trk.set_environment(20.0, 5000.0, 45.0)
    L = np.linalg.norm(cell.true_point())
    expected = L * (refractive_index(20, 1013.25, 45) / refractive_index(*air) - 1)
    if air[0] == 40.0:
        assert expected == pytest.approx(L * 18.6e-6, rel=0.05)  # ~0.93 ppm/K
    else:
        assert expected < 0
    assert wrong - base == pytest.approx(expected, abs=0.006)
