"""Fixtures of every driver test: the simulated cell, and each driver on it
(:mod:`tests.drivers.rigs` serves it; the conformance suite runs them all)."""

from __future__ import annotations

import pytest

from tests.sim_drivers.helpers import make_cell

from .rigs import serve_robot, serve_tracker


@pytest.fixture
def cell():
    """A ToyArm cell with a fault injector (nothing armed)."""
    return make_cell(seed=3)


def _rig_fixture(serve, name: str, doc: str):
    def rig(cell):
        with serve(name, cell) as r:
            yield r

    rig.__doc__ = doc
    return pytest.fixture(rig)


line_robot = _rig_fixture(serve_robot, "line-tcp", "SerialRobot over TCP, connected.")
modbus_robot = _rig_fixture(serve_robot, "modbus", "ModbusRobot, connected.")
line_tracker = _rig_fixture(serve_tracker, "line-tcp", "LineTracker over TCP, connected.")
emscon_tracker = _rig_fixture(serve_tracker, "emscon", "EmsconTracker, connected.")
