"""``sim://`` URLs: in-process drivers on a shared SimCell."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drivers.errors import BeamBroken, LimitError, ProtectiveStop
from drivers.protocols import CommandedPosition, Identified, RobotDriver, TrackerDriver
from drivers.urls import open_robot, open_tracker
from sim_drivers import inprocess

TOY = str(Path(__file__).parents[1] / "daq" / "data" / "toyarm.yaml")


@pytest.fixture(autouse=True)
def fresh_cells():
    inprocess.register()
    inprocess.reset_cells()
    yield
    inprocess.reset_cells()


def test_robot_and_tracker_share_a_cell():
    rob = open_robot(f"sim://robot?model={TOY}&seed=4&reflector=360")
    trk = open_tracker("sim://tracker?seed=4")
    assert isinstance(rob, RobotDriver) and isinstance(rob, CommandedPosition)
    assert isinstance(trk, TrackerDriver)
    assert rob.cell is trk.cell
    assert open_robot(f"sim://robot?model={TOY}&seed=5").cell is not rob.cell
    rob.connect()
    trk.connect()
    p0 = trk.measure(0.1).xyz
    rob.move_joints(np.array([0.4, 0.2, 0.1]), timeout=1.0)
    p1 = trk.measure(0.1).xyz
    assert np.linalg.norm(p1 - p0) > 10
    assert np.linalg.norm(p1 - rob.cell.true_point()) < 0.1
    assert rob.status().in_position and trk.status().initialised


def test_errors_are_typed():
    rob = open_robot(f"sim://robot?model={TOY}&seed=1&reflector=360&faults=pstop@2,beam@3")
    trk = open_tracker("sim://tracker?seed=1")
    rob.connect()
    trk.connect()
    with pytest.raises(LimitError):
        rob.move_joints(np.array([9.0, 0.0, 0.0]))
    rob.cell.faults.begin_command()
    rob.cell.faults.begin_command()
    with pytest.raises(ProtectiveStop):
        rob.move_joints(np.array([0.1, 0.0, 0.0]))
    rob.clear_protective_stop()
    rob.cell.faults.begin_command()
    with pytest.raises(BeamBroken):
        trk.measure(0.1)


@pytest.mark.parametrize(
    "url, kind",
    [
        ("sim://arm?seed=1", "robot"),
        ("sim://tracker?seed=1", "robot"),
        ("sim://robot?seed=x", "robot"),
        ("sim://robot?colour=red", "robot"),
        ("sim://robot?seed=1", "robot"),  # no model: refused, not a toy arm
        ("sim://tracker?seed=9", "tracker"),  # no robot's cell yet, no model
        ("sim://robot?model=nosuchrobot", "robot"),
        ("sim://robot?model=ur10e&tool=1,2", "robot"),
    ],
)
def test_bad_sim_urls(url, kind):
    with pytest.raises(ValueError, match="bad URL"):
        open_robot(url) if kind == "robot" else open_tracker(url)


def test_a_sim_url_is_the_calibration_backed_robot_of_its_model_and_says_so():
    rob = open_robot("sim://robot?model=ur10e&seed=2")
    trk = open_tracker("sim://tracker?seed=2")
    assert isinstance(rob, Identified) and isinstance(trk, Identified)
    ident = rob.identify()
    assert rob.n_joints == 6 and ident.n_joints == 6
    assert ident.simulator and ident.kinematics == "ur10e" and ident.serial == "SIM-ur10e-2"
    assert trk.identify().simulator
    with pytest.raises(ValueError, match="moves a ur10e"):  # the same cell, another model
        open_robot(f"sim://robot?model={TOY}&seed=2")
