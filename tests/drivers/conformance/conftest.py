"""The conformance suite's fixtures: every driver of :data:`tests.drivers.rigs.ROBOTS` and
:data:`~tests.drivers.rigs.TRACKERS` on the simulated cell, one test run each."""

from __future__ import annotations

import pytest

from tests.drivers.rigs import ROBOTS, TRACKERS, serve_robot, serve_tracker


@pytest.fixture(params=list(ROBOTS))
def robot_kind(request) -> str:
    return request.param


@pytest.fixture(params=list(TRACKERS))
def tracker_kind(request) -> str:
    return request.param


@pytest.fixture
def robot(robot_kind, cell):
    """The robot driver on the cell, connected (a :class:`~tests.drivers.rigs.Rig`)."""
    with serve_robot(robot_kind, cell, **ROBOTS[robot_kind].options(cell)) as rig:
        yield rig


@pytest.fixture
def tracker(tracker_kind, cell):
    """The tracker driver on the cell, connected (a :class:`~tests.drivers.rigs.Rig`)."""
    with serve_tracker(tracker_kind, cell, **TRACKERS[tracker_kind].options(cell)) as rig:
        yield rig
