"""The capture service: plan, start and resume runs; the one place that wires a run together.

The command line (``cellcal capture``, ``cellcal resume``) and the demo call it with
typed inputs (:mod:`daq.run_request`); it returns a typed :class:`RunOutcome` and never
prints.

::

    planned = plan_run(CaptureRequest(routine="poses", model="ur10e", params={...}))
    outcome = start_run(store, planned, robot_url=..., tracker_url=...)

    resumable = prepare_resume(store, run_id)      # records a kill found on resume
    outcome = resume_run(store, resumable)

Wiring
    :func:`plan_run` (:mod:`daq.planning`) loads the model with the controller's tool,
    makes the routine's plan and dry-runs it. :func:`start_run` opens the cell
    (:func:`daq.cell_session.cell_session`: leases, devices, identities, the robot and the
    tracker checked, the motion confirmed), finds the measurement frame, stores the run
    and executes it (:func:`execute`: the routine's ``finalize`` and ``acquisition``, the
    run's motion guard). Leases (:mod:`daq.store.leases`) keep one owner per run and per
    robot: a live owner's is refused at once (:class:`~daq.store.leases.LeaseBusy`).

Same cell on resume
    :func:`resume_run` opens the cell the run was measured in; another cell is refused
    (:class:`~daq.cell_session.OtherCell`) unless ``other_cell``, which starts a NEW run of
    the same plan there (``source_run`` names the old one) rather than mixing two cells.

Errors: :class:`~daq.errors.RequestError` (and :class:`~daq.errors.PlanRefused`,
:class:`~daq.errors.TrackerRefused`, :class:`~daq.store.leases.LeaseBusy`,
:class:`~daq.cell_session.OtherCell`) for input it refuses or a tracker that fails its
checks, :class:`~daq.errors.ConnectFailed` when the devices cannot be reached.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Callable

from .cell_session import CellSession, ConfirmFn, OtherCell, cell_session, frame_fields
from .devices import default_robot_id
from .errors import RequestError, one_line
from .executor import Executor
from .motion_guard import MotionGuard
from .planning import acquire_options, plan_run
from .plans import Plan
from .remeasure import Remeasure
from .resumable import Resumable, prepare_resume
from .routines import get as get_routine
from .run_context import ExecutorOptions, RunContext, TrackerSetup
from .run_request import CaptureRequest, PlannedRun, ProgressFn, RunOutcome
from .store import InterruptionKind, RemeasureSummary, RunStore, RunSummary, StoreUnavailable
from .store.leases import Leases
from .warm_gate import require_warm

__all__ = ["CaptureRequest", "ConfirmFn", "OtherCell", "PlannedRun", "ProgressFn",
           "Resumable", "RunOutcome", "execute", "plan_run", "prepare_resume",
           "resume_run", "start_run"]

log = logging.getLogger(__name__)

#: called once a run is stored, before the first move: (run id, points stored)
StartedFn = Callable[[int, int], None]


# -------------------------------------------------------------------- start
def start_run(store: RunStore, planned: PlannedRun, *, robot_url: str, tracker_url: str,
              devices: tuple | None = None, progress: ProgressFn | None = None,
              on_started: StartedFn | None = None,
              confirm: ConfirmFn | None = None, leases: Leases | None = None) -> RunOutcome:
    """Store a new run of ``planned`` (with the robot's id, :func:`daq.devices.default_robot_id`)
    and execute it.

    Parameters
    ----------
    store : RunStore
    planned : PlannedRun
    robot_url, tracker_url : str
        The devices (recorded; connected unless ``devices`` is given).
    devices : (robot, tracker), optional
        Already connected drivers (left open).
    progress : callable(done, total, last_error), optional
    on_started : callable(run_id, points_stored), optional
        Called once the run is stored, before the first move.
    confirm : callable(cell identity, robot_url, tracker_url), optional
        Called once the devices said who they are, before the run is stored; raises to
        refuse (nothing is stored, nothing moved).
    leases : Leases, optional
        Where the run's and the robot's leases are held (default: this call's own).

    Raises
    ------
    LeaseBusy
        The robot is in use by another live process.
    RequestError
        The robot does not fit the model (joint count, a simulator of another model);
        :class:`~daq.warm_gate.NotWarm` when the request requires a warm robot
        (``require_warm_min``) and it is not.
    """
    req = planned.request
    with cell_session(store, planned.model, robot_url, tracker_url, req.tracker, req.executor,
                      devices=devices, leases=leases, confirm=confirm) as session:
        robot_id = default_robot_id(session.cell.robot, req.robot_id)
        if req.require_warm_min is not None:
            require_warm(store, session.robot, robot_id, req.require_warm_min,
                         timeout=req.executor.io_timeout_s)
        frame = session.frame_run(req.frame_run, robot_id)
        context = RunContext(
            routine=planned.plan.routine, model=req.model,
            tool_mm=tuple(float(v) for v in planned.model.tool_mm()), robot_url=robot_url,
            tracker_url=tracker_url, seed=req.seed, **frame_fields(frame),
            executor=req.executor, acquire=planned.acquire, motion=req.motion,
            tracker=req.tracker, tracker_check=session.tracker_check,
            **session.reflector_context(req.smr_radius_mm))
        run_id = session.create_run(planned.plan, context, robot_id=robot_id)
        log.info("run %d stored: %s, %d points, plan %s, robot %s, frame run %s, in %s",
                 run_id, planned.plan.routine, planned.plan.n_planned,
                 planned.plan.hash[:16], robot_id or "-", context.frame_run,
                 store.address)
        return _go(session, run_id, 0, planned.plan, planned.model, context, progress,
                   on_started)


# ------------------------------------------------------------------- resume
def resume_run(store: RunStore, resumable: Resumable, *, executor: dict | None = None,
               acquire: dict | None = None, tracker_setup: dict | None = None,
               devices: tuple | None = None,
               progress: ProgressFn | None = None,
               on_started: StartedFn | None = None,
               confirm: ConfirmFn | None = None, leases: Leases | None = None,
               other_cell: bool = False) -> RunOutcome:
    """Continue a run from :func:`prepare_resume`: the points not yet stored.

    ``executor``, ``acquire`` and ``tracker_setup`` override the stored executor and
    acquisition options and tracker setup (e.g. new ``meteo``) for this session (the
    stored context keeps its own). The run's and the robot's
    leases are taken (:class:`~daq.store.leases.LeaseBusy` when another process holds them).
    The devices must be the run's cell (:func:`daq.devices.same_cell`), else
    :class:`OtherCell` — or, with ``other_cell``, a NEW run of the same plan (every
    point; its ``source_run`` is this one; the measurement frame of a frame run of that
    cell, if any) is created and executed instead, and this run is left as it is. New
    URLs of the same cell are stored with the run. ``confirm`` as :func:`start_run`. A
    failed connection is recorded as an interruption, then :class:`ConnectFailed`; a
    tracker that fails its checks (the two faces are not checked again) likewise, then
    :class:`TrackerRefused`.
    """
    r = resumable.run
    stored = r.context
    try:
        options = ExecutorOptions(**{**stored.executor.model_dump(), **(executor or {})})
        acq = acquire_options(get_routine(r.routine), {**stored.acquire, **(acquire or {})})
        setup = TrackerSetup(**{**stored.tracker.model_dump(), **(tracker_setup or {})})
    except ValueError as e:
        raise RequestError(one_line(e)) from None
    robot_url, tracker_url = resumable.robot_url, resumable.tracker_url
    with cell_session(store, resumable.model, robot_url, tracker_url, setup, options,
                      devices=devices, leases=leases, confirm=confirm, resumed=r,
                      other_cell=other_cell) as session:
        if session.elsewhere:
            return _repeat_elsewhere(session, resumable, options, acq, progress, on_started)
        context = stored.model_copy(update={"executor": options, "acquire": acq,
                                            "tracker": setup, "robot_url": robot_url,
                                            "tracker_url": tracker_url})
        if robot_url != r.robot_url or tracker_url != r.tracker_url:
            store.update_run(r.id, robot_url=robot_url, tracker_url=tracker_url)
        cell = session.cell
        if r.robot_identity is None:  # a run stored before identities were
            store.update_run(r.id, robot_identity=cell.robot.to_dict(),
                             tracker_identity=cell.tracker.to_dict())
        if not r.robot_id and (robot_id := default_robot_id(cell.robot)):
            store.update_run(r.id, robot_id=robot_id)
        done = store.n_samples(r.id)
        log.info("run %d resumed: %s, %d of %d points stored, in %s", r.id, r.routine, done,
                 r.n_points, store.address)
        return _go(session, r.id, done, resumable.plan, resumable.model, context, progress,
                   on_started, note=f"resumed with {done}/{r.n_points} points stored; "
                   f"tracker: {session.tracker_check.model_dump_json()}")


def _repeat_elsewhere(session: CellSession, resumable: Resumable, options, acq,
                      progress: ProgressFn | None, on_started: StartedFn | None) -> RunOutcome:
    """``resume --other-cell``: a new run of the resumed run's plan in this cell."""
    r, store, why = resumable.run, session.store, session.elsewhere
    robot_id = default_robot_id(session.cell.robot)
    context = r.context.model_copy(update={
        "executor": options, "acquire": acq, "robot_url": resumable.robot_url,
        "tracker_url": resumable.tracker_url,
        **frame_fields(session.frame_run(None, robot_id))})
    run_id = session.create_run(resumable.plan, context, robot_id=robot_id, source_run=r.id)
    log.info("run %d not resumed here (%s): its plan runs again as run %d", r.id, why, run_id)
    store.add_interruption(r.id, None, InterruptionKind.OTHER_CELL,
                           f"not resumed here: {why}; its plan runs again as run {run_id}")
    store.add_interruption(run_id, None, InterruptionKind.OTHER_CELL,
                           f"the plan of run {r.id} again, in another cell ({why})")
    return _go(session, run_id, 0, resumable.plan, resumable.model, context, progress,
               on_started)


def _go(session: CellSession, run_id: int, done: int, plan: Plan, model, context: RunContext,
        progress: ProgressFn | None, on_started: StartedFn | None,
        note: str | None = None) -> RunOutcome:
    """Tell ``on_started`` (``done`` points stored), record ``note`` (a resume), then
    :func:`execute` the run."""
    if on_started is not None:
        on_started(run_id, done)
    if note is not None:
        session.store.add_interruption(run_id, None, InterruptionKind.RESUME, note)
    return execute(session.store, run_id, plan, session.robot, session.tracker, model=model,
                   context=context, progress=progress)


# ------------------------------------------------------------------ execute
def execute(store: RunStore, run_id: int, plan: Plan, robot, tracker, *, model,
            context: RunContext, progress: ProgressFn | None = None) -> RunOutcome:
    """Run (or continue) stored run ``run_id`` with ``context``'s executor options and the
    routine's finalize and acquisition; the outcome as stored afterwards."""
    mod = get_routine(plan.routine)
    make_acquisition = getattr(mod, "acquisition", None)
    remeasure = None
    if make_acquisition is None and model is not None:  # a closed loop judges its own
        remeasure = Remeasure.for_run(store, run_id, plan, model, context.executor)
    log.info("run %d: executor %s; re-measure policy %s", run_id,
             context.executor.model_dump_json(), "on" if remeasure is not None else "off")
    ex = Executor(store, run_id, plan, robot, tracker, context.executor,
                  acquisition=None if make_acquisition is None
                  else make_acquisition(model, context),
                  progress=progress, finalize=getattr(mod, "finalize", None),
                  guard=MotionGuard(model, context.motion), remeasure=remeasure,
                  enough=getattr(mod, "enough", None))
    t0 = time.monotonic()
    try:
        status = ex.run()
    finally:
        if remeasure is not None:
            # a store away now (the run paused for it): resume recounts from the store
            with contextlib.suppress(StoreUnavailable):
                _remeasure_summary(store, run_id, remeasure)
    elapsed = time.monotonic() - t0
    try:
        run = store.run(run_id)
        reason, n, frame, summary = (run.reason, store.n_samples(run_id), run.frame,
                                     run.summary and run.summary.to_json())
        check = run.context.tracker_check
    except StoreUnavailable:  # paused because the store is away: what the executor knows
        reason, n, frame, summary, check = ex.last_error, ex.n_done, None, None, None
    return RunOutcome(run_id, plan.routine, status, reason, plan.n_planned, n, ex.n_faults,
                      elapsed, plan.hash, store.address, frame, summary, ex.stop_signal,
                      None if check is None else check.model_dump(mode="json"))


def _remeasure_summary(store: RunStore, run_id: int, remeasure: Remeasure) -> None:
    """The run summary's ``remeasure``: the counts of the store
    (:meth:`RunStore.remeasure_counts`), the running model's warm-up and its refits over
    every session."""
    summary = store.run(run_id).summary or RunSummary()
    before = summary.remeasure or RemeasureSummary()
    running = remeasure.running
    sizes = [n for n, _ in running.refits]
    summary.remeasure = RemeasureSummary(
        **store.remeasure_counts(run_id), max_remeasures=remeasure.n,
        warmup_points=running.min_points,
        refits=int(before.refits or 0) + len(running.refits),
        refit_s=float(before.refit_s or 0.0) + sum(s for _, s in running.refits),
        largest_refit_rows=max([int(before.largest_refit_rows or 0), *sizes]))
    store.update_run(run_id, summary=summary)
