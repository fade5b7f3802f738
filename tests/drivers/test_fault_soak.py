"""Random faults from a spec string: every call ends in time, with a result or a typed error."""

from __future__ import annotations

import contextlib
import time

import numpy as np
import pytest

from drivers.errors import DriverError
from sim_drivers.faults import FaultSpec
from tests.drivers.rigs import serve_robot, serve_tracker
from tests.sim_drivers.helpers import MARGIN, make_cell

SPEC = "beam=0.15,garbage=0.1,drop=0.1,slow=0.04,pstop=0.1,modbus=0.1,delay=0.4"
TIMEOUT = 0.25


def _reconnect(driver):
    with contextlib.suppress(DriverError):
        driver.connect(2.0)


def _soak(call, reconnect, n=40):
    ok, errors = 0, {}
    for i in range(n):
        t0 = time.monotonic()
        try:
            call(i)
            ok += 1
        except DriverError as e:
            errors[type(e).__name__] = errors.get(type(e).__name__, 0) + 1
            if not e.transient or "not connected" in str(e):
                reconnect()
        dt = time.monotonic() - t0
        assert dt < 3 * TIMEOUT + MARGIN, f"call {i} took {dt:.2f} s (a hang, not a slow call)"
    return ok, errors


@pytest.mark.parametrize("kind", ["line-tcp"])
def test_tracker_soak(kind):
    cell = make_cell(seed=21)
    with serve_tracker(kind, cell) as rig:
        trk = rig.driver
        cell.faults.spec = FaultSpec.parse(SPEC)
        ok, errors = _soak(lambda i: trk.measure(0.01, timeout=TIMEOUT), lambda: _reconnect(trk))
    assert ok > 15, errors
    assert set(errors) <= {"BeamBroken", "ProtocolError", "CommandTimeout", "ConnectionLost"}
    assert errors, "the spec should have caused some errors"


@pytest.mark.parametrize("kind", ["line-tcp", "modbus"])
def test_robot_soak(kind):
    cell = make_cell(seed=22)
    targets = np.random.default_rng(0).uniform(-1, 1, (40, 3))
    with serve_robot(kind, cell) as rig:
        rob = rig.driver
        cell.faults.spec = FaultSpec.parse(SPEC)

        def step(i):
            if rob.status(timeout=TIMEOUT).protective_stop:
                rob.clear_protective_stop(timeout=TIMEOUT)
            rob.move_joints(targets[i], speed=1.0, timeout=TIMEOUT)
            rob.read_joints(timeout=TIMEOUT)

        ok, errors = _soak(step, lambda: _reconnect(rob))
    assert ok > 5, errors
    allowed = {"ProtectiveStop", "ProtocolError", "CommandTimeout", "ConnectionLost",
               "CommandRejected"}
    assert set(errors) <= allowed, errors
