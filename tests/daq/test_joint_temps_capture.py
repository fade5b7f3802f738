"""Joint temperatures travel from the controller to the measurement CSV (issue 26): a
capture over RTDE (the real ur-rtde client's receive side), Modbus and the line protocol
of a served simulated cell that warms up stores each sample's joint temperatures, and
``cellcal export`` writes them as ``joint_temp1..6`` beside ``t_s``; one with no thermal
model reports the air's temperature, constant, over every wire (issue 36); a controller
without them gives a capture without the columns (asked once, not at every point)."""

from __future__ import annotations

import numpy as np
import pytest

from calibration.data.dataset import load_csv
from cellcal.cli import main
from daq.routines import make_plan
from daq.store import RunStore
from drivers.urls import open_tracker
from sim_drivers.model_truth import model_truth_factory
from sim_drivers.serve import ServeConfig, SimStack

from .capture_helpers import (
    FREE_PORTS,
    rough_cell,
    run_plan,
    stack_robot,
    ur10e_controller_model,
)


def _capture(tmp_path, protocol: str, thermal: str | None, joint_temps: bool = True):
    model = ur10e_controller_model()
    plan = make_plan("steps", model, step_mm=40.0, count=3, cell=rough_cell())
    cfg = ServeConfig(seed=3, ports=dict(FREE_PORTS), pty=False, rtde=False, thermal=thermal)
    db, csv = tmp_path / f"{protocol}.db", tmp_path / f"{protocol}.csv"
    with SimStack(cfg, truth_factory=model_truth_factory, joint_temps=joint_temps) as stack, \
            RunStore(db) as store:
        tracker = open_tracker(stack.urls[2])
        tracker.connect(2.0)
        try:
            with stack_robot(stack, protocol) as robot:
                _, status = run_plan(store, plan, robot, tracker)
        finally:
            tracker.close()
        assert status == "completed"
        final = stack.cell.joint_temperatures()
    assert main(["export", "--db", str(db), "--out", str(csv)]) == 0
    return load_csv(csv, model), final, csv


@pytest.mark.parametrize("protocol", ["rtde", "modbus", "line"])
def test_joint_temperatures_reach_the_csv(tmp_path, protocol, capsys):
    data, final, csv = _capture(tmp_path, protocol, "cold")
    header = csv.read_text().splitlines()
    header = next(h for h in header if not h.startswith("#")).split(",")
    assert [f"joint_temp{j}" for j in range(1, 7)] == [h for h in header
                                                       if h.startswith("joint_temp")]
    T = data.joint_temp
    assert T.shape == (data.n, 6)
    # a cold robot at work: above the air's 20 °C, warming point after point, never
    # warmer than the controller is at the end (Modbus: centidegrees)
    assert np.all(T > 20.0) and np.all(np.diff(T.mean(axis=1)) > 0)
    assert np.all(final + 0.01 >= T)
    assert data.t_s is not None and np.all(np.diff(data.t_s) > 0)


@pytest.mark.parametrize("protocol", ["rtde", "modbus", "line"])
def test_a_robot_without_a_thermal_model_reports_the_air_temperature(tmp_path, protocol,
                                                                      capsys):
    """Issue 36: a real UR always reports its joints' temperatures; the simulated one, with
    no thermal model, reports the air's, constant, over every wire, so the export has
    ``joint_temp1..6`` as at a real cell (and nothing drifts)."""
    data, final, csv = _capture(tmp_path, protocol, None)
    header = next(h for h in csv.read_text().splitlines() if not h.startswith("#"))
    assert [h for h in header.split(",") if h.startswith("joint_temp")] == \
        [f"joint_temp{j}" for j in range(1, 7)]
    assert data.joint_temp.shape == (data.n, 6)
    np.testing.assert_array_equal(data.joint_temp, 20.0)
    np.testing.assert_array_equal(final, 20.0)


def test_a_controller_without_temperatures_exports_none(tmp_path, capsys):
    data, final, _ = _capture(tmp_path, "line", None, joint_temps=False)
    assert final is None and data.joint_temp is None
