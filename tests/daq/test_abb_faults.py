"""A capture on the simulated ABB (an IRB 2600 moved over Robot Web Services through the
RAPID server module) meets each fault of the controller and of the link: each ends in a
clear error or is recovered, and once the operator has dealt with it the run resumes and
completes, every point stored once (nothing lost, nothing doubled)."""

from __future__ import annotations

import numpy as np
import pytest

from daq.routines import make_plan
from daq.run_context import ExecutorOptions
from daq.store import RunStore

from .abb_program import controller_model, irb2600_truth
from .capture_helpers import connected, rough_cell, run_plan, served_cell

FAST = dict(io_timeout_s=0.5, measure_timeout_s=0.5, move_timeout_s=2.0, backoff_s=0.001,
            backoff_max_s=0.01, max_retries=3, measure_s=0.01)

#: fault → (what the pause says, or None: recovered by the executor; the operator's fix)
CASES = {
    "pstop": ("protective stop at point", lambda stack: stack.cell.clear_protective_stop()),
    "motoroff": ("controller motoroff", lambda stack: _abb(stack).controller.motors(True)),
    "mastership": ("mastership held by another client (FlexPendant)",
                   lambda stack: _abb(stack).controller.release_mastership()),
    "rapid": ("RAPID stopped during the move: event 41617", lambda stack: None),
    "drop": (None, None),
    "slow": (None, None),
}


def _abb(stack):
    return stack.servers[-1]


@pytest.mark.parametrize("fault", list(CASES))
def test_each_fault_ends_clearly_and_the_run_resumes(tmp_path, fault):
    said, fix = CASES[fault]
    model = controller_model()
    plan = make_plan("poses", model, count=24, seed=5, cell=rough_cell())
    opts = ExecutorOptions(**FAST)
    with served_cell(irb2600_truth, seed=5, abb=True,
                     faults="delay=1.0" if fault == "slow" else None) as stack, \
            RunStore(tmp_path / "cell.db") as store:
        robot_url = _abb(stack).url
        assert robot_url.startswith("abb://")
        with connected(robot_url, stack.urls[2]) as (robot, tracker):
            stack.faults.arm(fault)  # fires at the first move (or request) of the run
            run_id, status = run_plan(store, plan, robot, tracker, options=opts)
            reasons = [r for _, _, _, r in store.interruptions(run_id)]
            assert [name for _, name in stack.faults.log] == [fault]
            if said is None:  # a link fault: a read asked again, or reconnected and retried
                assert status == "completed", reasons
                assert len(reasons) <= 1, reasons
            else:
                assert status == "paused", reasons
                assert said in reasons[-1], reasons  # the pause says why
                assert store.n_samples(run_id) == 0  # it came at the first move
                fix(stack)
                _, status = run_plan(store, plan, robot, tracker, options=opts, run_id=run_id)
                assert status == "completed"
            s = store.samples(run_id)
            assert np.array_equal(s.point_index, np.arange(24))  # each once, no gap
        print(f"\n{fault}: {reasons}")
