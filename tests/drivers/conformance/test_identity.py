"""Every simulated device, over every protocol, says it is a simulator, of which robot, and
its serial number (:class:`drivers.protocols.DeviceIdentity`)."""

from __future__ import annotations

import pytest

from sim_drivers.cell import SimCell
from sim_drivers.model_truth import ModelTruth
from tests.drivers.rigs import ROBOTS, TRACKERS, serve_robot, serve_tracker

DEVICES = [("robot", name) for name, k in ROBOTS.items() if k.names_itself] + \
          [("tracker", name) for name, k in TRACKERS.items() if k.names_itself]


@pytest.fixture(scope="module")
def ur10e_cell():
    return SimCell(ModelTruth.from_spec("ur10e", None, 7), seed=7)


@pytest.mark.parametrize("role, name", DEVICES, ids=[f"{r}-{n}" for r, n in DEVICES])
def test_every_simulated_device_names_itself_a_simulator(role, name, ur10e_cell):
    serve = serve_robot if role == "robot" else serve_tracker
    with serve(name, ur10e_cell) as rig:
        ident = rig.driver.identify()
    assert ident.kind == role and ident.simulator, (name, ident)
    if role == "robot":
        assert ident.kinematics == "ur10e" and ident.serial == "SIM-ur10e-7"
        assert ident.n_joints == 6
    else:
        assert ident.serial in ("SIMTRK-7", "390130"), ident  # line protocol, emScon
