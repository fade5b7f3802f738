"""Fault ``blunder``: tracker readings displaced by 0.5-5 mm, over the wire and in process,
reproducible by seed, with the truth recorded by the cell."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.urls import open_robot, open_tracker
from sim_drivers import inprocess
from sim_drivers.faults import FaultSpec
from sim_drivers.serve import ServeConfig, SimStack
from sim_drivers.tracker_server import TrackerServer
from tests.daq.capture_helpers import toy_sim
from tests.sim_drivers.helpers import make_cell

#: the beam direction at a point: the tracker sits at the origin of its frame
ALONG_DEG = 1.0


def _angle_to_beam(offset, true_xyz) -> float:
    c = abs(offset @ true_xyz) / (np.linalg.norm(offset) * np.linalg.norm(true_xyz))
    return float(np.degrees(np.arccos(min(c, 1.0))))


def _capture(cell, url: str, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Measure ``n`` poses through the tracker driver at ``url``; (readings, true points)."""
    rng = np.random.default_rng(seed)
    readings, truth = [], []
    with open_tracker(url) as trk:
        trk.connect(2.0)
        for _ in range(n):
            cell.command_move_joints(rng.uniform(-1.0, 1.0, cell.n_joints), 1.0)
            readings.append(trk.measure(0.05, timeout=2.0).xyz)
            truth.append(cell.true_point())
    return np.array(readings), np.array(truth)


def _check_against_truth(cell, readings, truth):
    """Every reading the log names is displaced by its offset; every other one is not."""
    err = np.linalg.norm(readings - truth, axis=1)
    hit = np.array([b.measurement - 1 for b in cell.blunder_log], int)
    clean = np.setdiff1d(np.arange(len(readings)), hit)
    assert err[clean].max() < 0.1  # tracker noise only (sigma ~ 0.02 mm)
    for b in cell.blunder_log:
        i = b.measurement - 1
        assert np.allclose(b.true_xyz, truth[i])
        assert 0.5 <= np.linalg.norm(b.offset_mm) <= 5.0
        assert np.linalg.norm(readings[i] - truth[i] - b.offset_mm) < 0.1
        if b.along_beam:
            assert _angle_to_beam(b.offset_mm, b.true_xyz) < ALONG_DEG
    return hit


def test_spec_knows_blunder():
    assert FaultSpec.parse("blunder=0.03").probability == {"blunder": 0.03}
    assert FaultSpec.parse("blunder@4").schedule == {"blunder": {4}}


def test_blunders_over_the_wire_match_the_recorded_truth():
    cell = make_cell(seed=5, faults="blunder=0.3")
    with TrackerServer(cell) as srv:
        readings, truth = _capture(cell, srv.url, 60, seed=1)
    hit = _check_against_truth(cell, readings, truth)
    assert 8 <= hit.size <= 30  # 30 % of 60
    kinds = {b.along_beam for b in cell.blunder_log}
    assert kinds == {True, False}  # both kinds occur


def test_blunders_are_reproducible_by_seed():
    def run(seed):
        cell = make_cell(seed=seed, faults="blunder=0.3")
        with TrackerServer(cell) as srv:
            _capture(cell, srv.url, 30, seed=2)
        return [(b.measurement, tuple(np.round(b.offset_mm, 9))) for b in cell.blunder_log]

    a, b, c = run(7), run(7), run(8)
    assert a and a == b and a != c


def test_sim_serve_stack_blunders_and_no_blunders_without_the_fault():
    config = ServeConfig(seed=3, faults="blunder=0.5", pty=False,
                         ports={"modbus": 0, "line_robot": 0, "tracker": 0})
    with SimStack(config) as stack:
        tracker_url = stack.urls[2]
        readings, truth = _capture(stack.cell, tracker_url, 20, seed=3)
    assert stack.cell.blunder_log
    _check_against_truth(stack.cell, readings, truth)
    quiet = make_cell(seed=3)  # no fault spec: no blunder, and the noise is unchanged
    with TrackerServer(quiet) as srv:
        readings, truth = _capture(quiet, srv.url, 20, seed=3)
    assert not quiet.blunder_log
    assert np.linalg.norm(readings - truth, axis=1).max() < 0.1


@pytest.fixture
def fresh_cells():
    inprocess.reset_cells()
    yield
    inprocess.reset_cells()


def test_blunders_in_process(fresh_cells):
    with open_robot(toy_sim("robot", 11, "bl", faults="blunder=1")) as rob, \
            open_tracker(toy_sim("tracker", 11, "bl")) as trk:
        rob.connect()
        trk.connect()
        cell = inprocess.get_cell("bl", 11)
        rob.move_joints([0.2, 0.3, 0.1], timeout=5.0)
        m = trk.measure(0.1)
    (b,) = cell.blunder_log
    assert b.measurement == 1
    assert np.linalg.norm(m.xyz - cell.true_point() - b.offset_mm) < 0.1
