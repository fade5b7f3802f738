"""Opt-in tests against real hardware: ``pytest --robot-url URL --tracker-url URL``.

Skipped unless the URLs are given. They only read, except the robot test,
which moves joint 1 by +0.5° and back at a slow speed: run it with the cell
clear and a hand on the stop button.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.protocols import RobotDriver, TrackerDriver
from drivers.urls import open_robot, open_tracker

pytestmark = pytest.mark.hardware


def test_tracker_status_and_measure(tracker_url):
    trk = open_tracker(tracker_url)
    assert isinstance(trk, TrackerDriver)
    trk.connect(timeout=30.0)
    try:
        st = trk.status(timeout=5.0)
        assert st.connected
        m = trk.measure(duration_s=0.5, timeout=20.0)
        assert m.xyz.shape == (3,) and np.all(np.isfinite(m.xyz))
        assert np.all(m.std < 1.0)
    finally:
        trk.close()


def test_robot_read_and_small_move(robot_url):
    rob = open_robot(robot_url)
    assert isinstance(rob, RobotDriver)
    rob.connect(timeout=10.0)
    try:
        st = rob.status(timeout=2.0)
        assert st.connected and not st.protective_stop
        q0 = rob.read_joints(timeout=2.0).q
        q1 = q0.copy()
        q1[0] += np.deg2rad(0.5)
        rob.move_joints(q1, speed=0.05, timeout=30.0)
        rob.wait_settled(timeout=30.0)
        assert np.allclose(rob.read_joints().q, q1, atol=np.deg2rad(0.05))
        rob.move_joints(q0, speed=0.05, timeout=30.0)
        rob.wait_settled(timeout=30.0)
    finally:
        rob.close()
