"""``cellcal resume [RUN]``: continue an interrupted run where it left off.

:class:`ResumeArgs` is what the user asked; :func:`resume` finds the run
(:func:`daq.service.prepare_resume`) and, unless it is completed, continues it with the
settings given over the stored ones (:func:`daq.service.resume_run`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Self

from pydantic import Field

from ..flags.capture_flags import EXEC_FLAGS, flag_values
from ..flags.routine_args import ACQUIRE_FLAGS, ROUTINE_ARGS
from ..request import Request
from .capture import check_urls, comma_numbers, executor_options, tracker_setup


class ResumeArgs(Request):
    """What ``cellcal resume`` was asked: ``executor`` the executor settings given
    (attribute -> value), ``acquire`` the acquisition flags given (flag -> value; those of
    the run's routine apply)."""

    run_id: int | None = Field(None, alias="RUN")
    db: str = Field(alias="--db")
    robot: str | None = Field(None, alias="--robot")
    tracker: str | None = Field(None, alias="--tracker")
    robot_id: str | None = Field(None, alias="--robot-id")
    synchronous: str = Field("FULL", alias="--synchronous")
    other_cell: bool = Field(False, alias="--other-cell")
    meteo: Annotated[tuple[float, float, float] | None, comma_numbers(3)] = Field(
        None, alias="--meteo")
    executor: dict = {}
    acquire: dict = {}

    @classmethod
    def from_args(cls, args: Any, **given: Any) -> Self:
        """The executor settings checked first, then the URLs, then the other flags."""
        executor = flag_values(args, EXEC_FLAGS)
        executor_options(executor)  # UsageError naming the flag, before anything else
        check_urls(args.robot, args.tracker)
        acquire = {flag: v for flag, _, _, _ in ACQUIRE_FLAGS
                   if (v := getattr(args, flag.lstrip("-").replace("-", "_"), None)) is not None}
        return super().from_args(args, executor=executor, acquire=acquire, **given)

    def acquire_of(self, routine: str) -> dict:
        """The acquisition options given for a run of ``routine`` (attribute -> value)."""
        return {attr: self.acquire[flag]
                for flag, attr, _, _ in ROUTINE_ARGS[routine].acquire_flags
                if flag in self.acquire}


@dataclass(frozen=True)
class ResumeResult:
    """The run found (a :class:`~daq.service.Resumable`) and how the session ended (a
    :class:`~daq.service.RunOutcome`; None when the run was already finished: completed,
    or incomplete)."""

    resumable: Any
    outcome: Any = None


def resume(req: ResumeArgs, *, progress=None,
           on_started: Callable[[Any, int, int], None] | None = None,
           confirm=None) -> ResumeResult:
    """Continue run ``req.run_id`` (default: the latest) of the store.

    ``on_started(run, run_id, done)`` is called once the session starts (``run_id`` is a
    new run's with ``--other-cell`` in another cell); ``progress`` and ``confirm`` go to
    :func:`daq.service.resume_run`. A missing store is a UsageError; the service's errors
    (RequestError, OtherCell, LeaseBusy, ConnectFailed, StoreUnavailable) pass through.
    """
    from daq.service import prepare_resume, resume_run
    from daq.store.leases import Leases

    from .stores import open_store

    store = open_store(req.db, synchronous=req.synchronous)
    try:
        with Leases(store) as leases:
            res = prepare_resume(store, req.run_id, robot_url=req.robot,
                                 tracker_url=req.tracker, leases=leases,
                                 robot_id=req.robot_id)
            r = res.run
            if res.finished:
                return ResumeResult(res)
            given = {} if req.meteo is None else {"meteo": req.meteo}
            tracker_setup(given, r.context.tracker.model_dump())  # checked over the stored
            return ResumeResult(res, resume_run(
                store, res, executor=req.executor, acquire=req.acquire_of(r.routine),
                tracker_setup=given, progress=progress,
                on_started=None if on_started is None else
                lambda run_id, done: on_started(r, run_id, done),
                leases=leases, other_cell=req.other_cell, confirm=confirm))
    finally:
        store.close()
