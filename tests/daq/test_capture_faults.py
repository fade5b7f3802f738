"""The executor over real sockets with injected faults: nothing lost, nothing duplicated."""

from __future__ import annotations

import collections

import numpy as np
import pytest

from daq.routines import make_plan
from daq.run_context import ExecutorOptions
from daq.store import RunStore
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import (
    connected,
    rough_cell,
    run_plan,
    served_cell,
    ur10e_controller_model,
)

#: every fault the servers know, each on ~5 % of the points (a point is ~15 commands)
FAULTS = ("beam=0.05,slow=0.004,drop=0.004,garbage=0.025,pstop=0.035,modbus=0.005,"
          "stale=0.01,delay=0.3")
FAST = dict(io_timeout_s=0.2, measure_timeout_s=0.25, move_timeout_s=0.25, backoff_s=0.001,
            backoff_max_s=0.01, max_retries=20, measure_s=0.01)


@pytest.mark.slow
def test_500_points_with_faults_of_every_kind(tmp_path):
    model = ur10e_controller_model()
    plan = make_plan("poses", model, count=500, seed=3, cell=rough_cell())
    with served_cell(model_truth_factory, faults=FAULTS, seed=3) as stack:
        robot_url, tracker_url = stack.urls[0], stack.urls[2]  # Modbus robot, TCP tracker
        store = RunStore(tmp_path / "cell.db")
        run_id, rounds = None, 0
        with connected(robot_url, tracker_url) as (robot, tracker):
            while True:
                rounds += 1
                run_id, status = run_plan(store, plan, robot, tracker,
                                          options=ExecutorOptions(**FAST), run_id=run_id,
                                          urls=(robot_url, tracker_url))
                if status == "completed":
                    break
                assert status == "paused" and rounds < 200
                stack.cell.clear_protective_stop()  # the operator clears the stop
        s = store.samples(run_id)
        kinds = collections.Counter(k for _, _, k, _ in store.interruptions(run_id))
        fired = collections.Counter(name for _, name in stack.faults.log)
        n_cmd = stack.faults.command_index
        store.close()
    assert len(s.point_index) == 500
    assert np.array_equal(s.point_index, np.arange(500))  # each once, no gaps
    for name in ("beam", "slow", "drop", "garbage", "pstop", "modbus", "stale"):
        assert fired[name] > 0, (name, fired)
    assert kinds["protective_stop"] >= 1 and kinds["beam"] >= 1
    assert kinds["timeout"] + kinds["connection"] + kinds["protocol"] >= 1
    print(f"\n{n_cmd} commands, faults fired {dict(fired)}, interruptions {dict(kinds)}, "
          f"{rounds} resumes")
