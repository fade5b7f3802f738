"""The capture service logs its decisions at INFO: each move (the point and its target), each
sample stored, a re-measure and why, a beam break and the retry, a drift check's result,
a move the motion guard refuses (WARNING); a simulated capture in process, the faults
armed by state."""

from __future__ import annotations

import logging

import numpy as np

import sim_drivers.inprocess as inproc
from calibration import load_model
from daq.drift_checks import DriftCheck, DriftWatch, with_drift_checks
from daq.motion_guard import MotionLimits
from daq.remeasure import RunningModel
from daq.routines import make_plan
from daq.run_context import ExecutorOptions, RunContext
from daq.service import execute
from daq.store import RunStore
from drivers.urls import open_robot, open_tracker

from .capture_helpers import TOY, toy_sim

TOYM = load_model(TOY)


def _messages(caplog, logger: str, level: int = logging.INFO) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == logger and r.levelno == level]


def _run(tmp_path, plan, name, *, progress=None, motion=None, **options):
    """Execute ``plan`` on the in-process toy cell ``name`` into ``tmp_path/<name>.db``."""
    robot = open_robot(toy_sim("robot", 21, name))
    tracker = open_tracker(toy_sim("tracker", 21, name))
    robot.connect()
    tracker.connect()
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.0, **options)
    with RunStore(tmp_path / f"{name}.db") as st:
        context = RunContext(routine=plan.routine, executor=opts,
                             **({} if motion is None else {"motion": motion}))
        rid = st.create_run(plan, context)
        out = execute(st, rid, plan, robot, tracker, model=TOYM, context=context,
                      progress=progress(robot.cell) if progress else None)
        readings = st.readings(rid)
    return out, readings


def test_moves_stores_a_beam_break_and_a_re_measure_are_logged(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="daq")
    inproc.reset_cells()
    plan = make_plan("poses", TOYM, count=40, seed=3)
    warm = RunningModel(TOYM, plan).min_points
    assert warm < 35

    def armed(cell):
        fired = set()

        def progress(done, total, last_error):
            for at, fault in ((3, "beam"), (warm + 2, "blunder")):
                # the next measurement: a beam break (retried); a reading 0.5-5 mm off
                if done == at and fault not in fired:
                    fired.add(fault)
                    cell.faults.arm(fault)
        return progress

    try:
        out, readings = _run(tmp_path, plan, "log", progress=armed)
    finally:
        inproc.reset_cells()
    assert out.status == "completed" and len(readings) == 1
    log = _messages(caplog, "daq.executor")
    moves = [m for m in log if ": joint move to [" in m]
    first = plan.targets[0]
    assert moves[0].startswith(f"point 0 ({first.label}): joint move to [")
    assert moves[0].endswith(", ".join(f"{v:.3f}" for v in np.rad2deg(first.q)) + "] deg")
    assert sum(m.startswith("point ") and " stored: [" in m for m in log) == 40
    assert any(m.startswith("point 3 (") and ": beam: " in m for m in log)
    assert any(m.startswith("point 3: retrying in ") for m in log)
    assert log[0].startswith("run 1: poses, 40 points planned, 0 stored")
    assert log[-1] == "run 1 completed"
    remeasure = _messages(caplog, "daq.remeasure")
    assert any("running model fitted on" in m for m in remeasure)
    suspect = next(m for m in remeasure if ": re-measuring (up to 2 times)" in m)
    assert f"point {warm + 2} (" in suspect and "mm from the running model" in suspect
    assert any(f"point {warm + 2} (" in m and "agrees with the model" in m
               and "accepted, 1 reading(s) rejected" in m for m in remeasure)
    assert any(m.startswith(f"point {warm + 2} (") and "adaptive joint move" in m for m in log)


def test_drift_checks_and_guard_refusals_are_logged(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="daq")
    inproc.reset_cells()
    plan = with_drift_checks(make_plan("poses", TOYM, count=6, seed=3), DriftCheck(3))
    try:
        out, _ = _run(tmp_path, plan, "drift", remeasure=0)
    finally:
        inproc.reset_cells()
    assert out.status == "completed"
    drift = _messages(caplog, "daq.drift_checks")
    assert len(drift) == sum(t.set == "drift" for t in plan.targets) == 3
    assert drift[0].startswith("drift check 1, reference 1 (") and "0.0000 mm from its first" \
        in drift[0]
    assert all("the bound" in m for m in drift)
    with RunStore(tmp_path / "drift.db") as st:  # a resumed run starts from the stored ones
        watch = DriftWatch.of_run(plan, st.samples(out.run_id))
    assert list(watch.first) == [1] and len(watch.std) == 3

    caplog.clear()
    inproc.reset_cells()
    low = make_plan("poses", TOYM, count=3, seed=3)
    z = min(float(p[2]) for p in _tcp_points(low))
    try:  # a floor above the points: the first move is refused, the run paused
        out, _ = _run(tmp_path, low, "guard", remeasure=0,
                      motion=MotionLimits(floor_z_mm=z + 1.0))
    finally:
        inproc.reset_cells()
    assert out.status == "paused"
    refused = _messages(caplog, "daq.executor", logging.WARNING)
    assert refused and "refused by the motion guard" in refused[0]


def _tcp_points(plan):
    from daq.motion_guard import MotionGuard

    return MotionGuard(TOYM).tool_points(np.array([t.q for t in plan.targets]))
