"""A stored run to resume: found, its plan checked, its lease taken, a kill recorded.

:func:`prepare_resume` finds the run and what resuming it needs (:class:`Resumable`);
:func:`daq.service.resume_run` then continues it at the cell.
"""

from __future__ import annotations

from dataclasses import dataclass

from calibration import ModelError, load_model

from .errors import RequestError
from .plans import Plan
from .store import InterruptionKind, Run, RunStatus, RunStore, StoreError
from .store.leases import Leases, held_leases, run_key

#: the statuses of a run with nothing left to resume
FINISHED = (RunStatus.COMPLETED, RunStatus.INCOMPLETE)


@dataclass(frozen=True)
class Resumable:
    """A stored run found by :func:`prepare_resume`: its plan, and (unless it is already
    finished: completed or incomplete) its model and the devices' URLs."""

    run: Run
    plan: Plan
    done: int
    model: object | None = None
    robot_url: str | None = None
    tracker_url: str | None = None

    @property
    def completed(self) -> bool:
        return self.run.status == RunStatus.COMPLETED

    @property
    def finished(self) -> bool:
        """Nothing left to resume: completed, or incomplete (its skipped points are not
        retried: :mod:`daq.completeness`)."""
        return self.run.status in FINISHED


def prepare_resume(store: RunStore, run_id: int | None = None, *,
                   robot_url: str | None = None, tracker_url: str | None = None,
                   leases: Leases | None = None,
                   robot_id: str | None = None) -> Resumable:
    """Find run ``run_id`` (default: the latest) and what resuming it needs.

    Unless it is completed, the run's lease is taken first (in ``leases``, kept; else
    for this call only): a run a live process still executes is refused at once
    (:class:`~daq.store.leases.LeaseBusy`, naming the owner). A run found ``running`` without
    a live owner (its process was killed) then gets a ``killed`` interruption.
    ``robot_url``/``tracker_url`` replace the stored ones for this resume (stored only
    once the devices prove to be the run's cell). ``robot_id`` must be the run's robot
    (it is recorded when the run had none). A finished run (completed or incomplete) comes
    back as it is (:attr:`Resumable.finished`).
    """
    try:
        r = store.run(run_id)
    except StoreError as e:
        raise RequestError(str(e)) from None
    plan = Plan.from_json(r.plan_json)
    if plan.hash != r.plan_hash:
        raise RequestError(f"run {r.id}: stored plan does not match its hash (edited store?)")
    if robot_id and r.robot_id and robot_id != r.robot_id:
        raise RequestError(f"run {r.id} is a run of robot {r.robot_id}, not {robot_id}")
    done = store.n_samples(r.id)
    if r.status in FINISHED:
        return Resumable(r, plan, done)
    with held_leases(store, leases) as held:
        taken = held.acquire(run_key(r.id), f"run {r.id}")
    if robot_id and not r.robot_id:
        store.update_run(r.id, robot_id=robot_id)
    r = store.run(r.id)  # as it is now that no one else runs it
    done = store.n_samples(r.id)
    if r.status == "running":
        owner = "" if taken is None else f" (its owner, {taken.describe()}, is gone)"
        store.add_interruption(r.id, None, InterruptionKind.KILLED,
                               "found still running on resume: the process was killed or "
                               f"crashed, or lost its run store{owner}")
    try:
        model = load_model(r.model or plan.model)
        if r.context.tool_mm is not None:
            model = model.with_changes(tool=tuple(r.context.tool_mm))
    except ModelError as e:
        raise RequestError(f"run {r.id}: model {r.model!r}: {e}") from None
    robot_url = robot_url or r.robot_url
    tracker_url = tracker_url or r.tracker_url
    if not robot_url or not tracker_url:
        raise RequestError(f"run {r.id}: no stored URLs; pass --robot and --tracker")
    return Resumable(r, plan, done, model, robot_url, tracker_url)
