"""The capture service: plan, start and resume runs; the one place that wires a run together.

The command line (``cellcal capture``, ``cellcal resume``) and the demo call it with
typed inputs; it returns a typed :class:`RunOutcome` and never prints.

::

    planned = plan_run(CaptureRequest(routine="poses", model="ur10e", params={...}))
    outcome = start_run(store, planned, robot_url=..., tracker_url=...)

    resumable = prepare_resume(store, run_id)      # records a kill found on resume
    outcome = resume_run(store, resumable)

Wiring
    :func:`plan_run` loads the model (with the controller's tool), resolves parameters
    that refer to earlier runs, makes the routine's plan and dry-runs it.
    :func:`start_run` takes the robot's lease, connects the devices (unless handed
    connected ones), asks who they are and checks the robot against the model (joint
    count; a simulator's robot model), sets up and checks the tracker
    (:mod:`daq.tracker_checks`: reflector, air, ready gate, two faces), lets the caller
    confirm the motion, finds the
    measurement frame (the given frame run, else the latest completed one of this
    cell), stores the run with the devices' identities, takes the run's lease and
    executes it. :func:`execute` runs a stored run with its routine's ``finalize`` and
    adaptive ``acquisition`` (:mod:`daq.routines`) and the run's motion guard
    (:mod:`daq.motion_guard`).

One owner per run and per robot
    Leases (:mod:`daq.store.leases`) on the run and on the robot (its URL and, once known, its
    serial number) are held while a run may move the robot; a second capture or resume
    on a live run or a busy robot is refused at once (:class:`~daq.store.leases.LeaseBusy`), a
    stale lease (dead owner) is taken over.

Same cell on resume
    :func:`resume_run` compares the devices reached with the identities stored with the
    run (:func:`daq.devices.same_cell`); another cell is refused
    (:class:`OtherCell`) unless ``other_cell``, which starts a NEW run of the same plan
    there (all points; ``source_run`` names the old one) rather than mixing two cells.

Errors: :class:`~daq.errors.RequestError` (and :class:`~daq.errors.PlanRefused`,
:class:`~daq.errors.TrackerRefused`, :class:`~daq.store.leases.LeaseBusy`, :class:`OtherCell`)
for input it refuses or a tracker that fails its checks,
:class:`~daq.errors.ConnectFailed` when the devices cannot be reached.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from calibration.cell import CellSpec

from .check import CheckResult, check_plan
from .devices import (
    CellIdentity,
    check_robot,
    default_robot_id,
    describe,
    identify,
    same_cell,
    stored_identity,
)
from .devices import devices as reach_devices
from .errors import ConnectFailed, PlanRefused, RequestError, TrackerRefused, one_line
from .executor import Executor
from .motion_guard import MotionGuard, MotionLimits
from .plans import Plan
from .remeasure import Remeasure
from .routines import get as get_routine
from .run_context import ExecutorOptions, RunContext, TrackerSetup
from .stop_signals import signal_name
from .store import RemeasureSummary, Run, RunStore, RunSummary, StoreError, StoreUnavailable
from .store.leases import Leases, held_leases, run_key, take_robot
from .store.queries import frame_run, measured_in
from .tracker_checks import check_tracker

#: called with the devices' identities before anything moves; raises to refuse
ConfirmFn = Callable[[CellIdentity, str, str], None]


class OtherCell(RequestError):
    """The devices reached are not the run's cell (resume without ``other_cell``)."""

#: progress callback of the executor: (points done, points in all, last error)
ProgressFn = Callable[[int, int, "str | None"], None]


@dataclass(frozen=True)
class CaptureRequest:
    """What to capture: a routine's plan for a model, checked and run with these settings.

    ``model`` is a built-in name or a YAML path (recorded with the run); ``params`` are
    the routine's ``make_plan`` keyword arguments; ``frame_run`` None takes the latest
    completed frame run of the same robot in the store, if any; ``acquire`` are the
    routine's acquisition options (zero20: :class:`~daq.routines.zero20.ZeroLoopOptions`
    fields); ``motion``
    the run's motion limits (default: ``floor_z_mm`` and ``max_reach_mm`` with the other
    limits' defaults); ``tracker`` the tracker's setup and checks
    (:class:`~daq.run_context.TrackerSetup`); ``robot_id`` names the robot (default: the
    controller's ``MODEL/SERIAL`` when it reports a serial number,
    :func:`daq.devices.default_robot_id`). Checked when made: :class:`RequestError`
    for a tool or floor that is not finite, motion limits that are not valid.
    """

    routine: str
    model: str
    params: dict = field(default_factory=dict)
    tool_mm: tuple[float, float, float] | None = None
    smr_radius_mm: float | None = None
    seed: int | None = None
    floor_z_mm: float | None = 0.0
    max_reach_mm: float | None = None
    frame_run: int | None = None
    executor: ExecutorOptions = field(default_factory=ExecutorOptions)
    acquire: dict = field(default_factory=dict)
    #: the cell (tracker, SMR, margins, fixtures; :mod:`calibration.cell`), the user's rough
    #: tracker position (mm, base frame), and whether to plan for the line of sight
    cell: CellSpec | None = None
    tracker_at: tuple[float, float, float] | None = None
    visibility: bool = True
    tracker: TrackerSetup = field(default_factory=TrackerSetup)
    motion: MotionLimits | None = None
    robot_id: str | None = None

    def __post_init__(self) -> None:
        if self.tool_mm is not None and (len(self.tool_mm) != 3 or not all(
                math.isfinite(float(v)) for v in self.tool_mm)):
            raise RequestError(f"the tool must be 3 finite numbers (mm), got {self.tool_mm}")
        if self.motion is None:
            try:
                limits = MotionLimits(floor_z_mm=self.floor_z_mm, max_reach_mm=self.max_reach_mm)
            except ValueError as e:
                raise RequestError(f"floor/reach: {one_line(e)}") from None
            object.__setattr__(self, "motion", limits)


@dataclass(frozen=True)
class PlannedRun:
    """A request's plan, dry-run and accepted: ``model`` has the controller's tool,
    ``acquire`` the routine's complete acquisition options, ``sight`` what the tracker
    will see of it (:class:`~daq.sight.SightReport`)."""

    request: CaptureRequest
    model: object
    plan: Plan
    check: CheckResult
    acquire: dict
    sight: object | None = None


@dataclass(frozen=True)
class Resumable:
    """A stored run found by :func:`prepare_resume`: its plan, and (unless it is already
    completed) its model and the devices' URLs."""

    run: Run
    plan: Plan
    done: int
    model: object | None = None
    robot_url: str | None = None
    tracker_url: str | None = None

    @property
    def completed(self) -> bool:
        return self.run.status == "completed"


@dataclass(frozen=True)
class RunOutcome:
    """How a (resumed) run ended.

    ``status``: ``completed``, ``paused`` (protective stop, rejected command, retries
    exhausted, a move refused or not done, stopped at once by a signal), ``stopped``
    (Ctrl-C) or ``failed`` (finalize failed); ``reason`` why it did not complete;
    ``points`` in the plan, ``samples`` stored, ``faults`` met in this session,
    ``elapsed_s`` of execution; ``frame`` and ``summary`` as stored; ``signal`` the
    signal that stopped it at once (a second Ctrl-C, SIGTERM, SIGHUP), else None;
    ``tracker_check`` what the tracker's checks found before the run (JSON-ready).
    """

    run_id: int
    routine: str
    status: str
    reason: str | None
    points: int
    samples: int
    faults: int
    elapsed_s: float
    plan_hash: str
    db: str
    frame: dict | None = None
    summary: dict | None = None
    signal: int | None = None
    tracker_check: dict | None = None

    def to_json(self) -> dict:
        """The ``--json`` document of ``cellcal capture`` / ``resume``."""
        out = {"run": self.run_id, "routine": self.routine, "status": self.status,
               "reason": self.reason, "points": self.points, "samples": self.samples,
               "faults": self.faults, "elapsed_s": self.elapsed_s,
               "plan_hash": self.plan_hash, "db": self.db}
        if self.frame is not None:
            out["frame"] = self.frame
        if self.summary:
            out["summary"] = self.summary
        if self.signal is not None:
            out["signal"] = signal_name(self.signal)
        if self.tracker_check is not None:
            out["tracker_check"] = self.tracker_check
        return out


def reflector_context(tracker, smr_radius_mm: float | None = None) -> dict:
    """``smr_radius_mm`` and ``reflector`` for the run context: the given radius, else the
    surface offset of the reflector the tracker reports (trackers with the
    :class:`~drivers.protocols.ReflectorSelect` capability); None where unknown."""
    from drivers.errors import DriverError
    from drivers.protocols import ReflectorSelect

    out = {"smr_radius_mm": smr_radius_mm, "reflector": None}
    if isinstance(tracker, ReflectorSelect):
        try:
            r = tracker.reflector()
        except DriverError:
            return out
        out["reflector"] = r.name or None
        if smr_radius_mm is None and r.surface_offset_mm > 0:
            out["smr_radius_mm"] = float(r.surface_offset_mm)
    return out


# -------------------------------------------------------------------- start
def _open_existing(db) -> RunStore:
    if db is None:
        raise RequestError("no run store given")
    try:
        return RunStore.open_existing(db)
    except (StoreError, OSError) as e:
        raise RequestError(str(e)) from None


def plan_run(request: CaptureRequest, *, model=None, db: str | Path | None = None
             ) -> PlannedRun:
    """Load the model, make the routine's plan and dry-run it.

    Parameters
    ----------
    request : CaptureRequest
    model : RobotModel, optional
        The model already loaded (``request.model`` names it); else loaded from it.
    db : path, optional
        The run store, read for a measurement frame (the tracker's position) and when the
        routine's parameters refer to an earlier run (zero20 ``--replay``).

    The plan is made for the tracker's line of sight (unless ``request.visibility`` is
    False) when the tracker position is known: ``request.tracker_at``, else the frame run
    (``request.frame_run`` or the latest in ``db``), else ``request.cell``
    (:func:`daq.sight.resolve_cell`); the planned run's ``sight`` says what the tracker
    will see of it either way.

    Raises
    ------
    RequestError
        Unknown routine or model, bad parameters or acquisition options.
    NotEnoughVisible
        The tracker would not see enough of the plan (a RequestError, exit code 3).
    PlanRefused
        The plan fails the dry run (joint limits, reach, floor).
    """
    from calibration import load_model

    from .sight import frame_from_store, predict, resolve_cell

    try:
        mod = get_routine(request.routine)
        if model is None:
            model = load_model(request.model)
        if request.tool_mm is not None:
            model = model.with_changes(tool=tuple(float(v) for v in request.tool_mm))
        params = dict(request.params)
        resolve = getattr(mod, "resolve_params", None)
        if resolve is not None:
            params = resolve(params, lambda: _open_existing(db))
        cell = resolve_cell(request.cell, request.tracker_at,
                            *frame_from_store(db, request.frame_run))
        plan = mod.make_plan(model, **params, cell=cell if request.visibility else None)
        acquire = _acquire_options(mod, request.acquire)
    except RequestError:  # NotEnoughVisible keeps its exit code
        raise
    except (ValueError, StoreError) as e:  # ModelError, CellError, pydantic's ValidationError
        raise RequestError(one_line(e)) from None
    res = check_plan(plan, model, limits=request.motion)
    if not res.ok:
        raise PlanRefused(res)
    return PlannedRun(request, model, plan, res, acquire, predict(plan, model, cell))


def _acquire_options(mod, given: dict) -> dict:
    """The routine's complete acquisition options (its defaults, then ``given``); {} for a
    routine without (which refuses any given)."""
    options = getattr(mod, "ACQUIRE_OPTIONS", None)
    if options is None:
        if given:
            raise RequestError(f"routine {mod.__name__.rsplit('.', 1)[-1]} takes no "
                               f"acquisition options ({', '.join(given)})")
        return {}
    return options(**given).model_dump()


def _frame_run(store: RunStore, run_id: int | None, cell: CellIdentity, robot_id: str | None,
               robot_url: str | None) -> Run | None:
    """:func:`daq.store.queries.frame_run`, a run that is no frame run refused as input."""
    try:
        return frame_run(store, run_id, cell, robot_id, robot_url)
    except StoreUnavailable:
        raise
    except StoreError as e:
        raise RequestError(str(e)) from None


def start_run(store: RunStore, planned: PlannedRun, *, robot_url: str, tracker_url: str,
              devices: tuple | None = None, progress: ProgressFn | None = None,
              on_started: Callable[[int, int], None] | None = None,
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
        The robot does not fit the model (joint count, a simulator of another model).
    """
    req = planned.request
    with held_leases(store, leases) as held:
        take_robot(held, robot_url)
        with reach_devices(robot_url, tracker_url, devices,
                           req.executor.connect_timeout_s) as (robot, tracker):
            cell = identify(robot, tracker, req.executor.io_timeout_s + 1.0)
            check_robot(planned.model, robot, cell.robot)
            take_robot(held, robot_url, cell.robot)
            found = check_tracker(tracker, req.tracker, req.executor)  # nothing stored yet
            if confirm is not None:
                confirm(cell, robot_url, tracker_url)
            robot_id = default_robot_id(cell.robot, req.robot_id)
            frame = _frame_run(store, req.frame_run, cell, robot_id, robot_url)
            if frame is not None and not measured_in(frame, cell):
                raise RequestError(f"frame run {frame.id} was measured in another cell (robot "
                                   f"{stored_identity(frame.robot_identity)}, tracker "
                                   f"{stored_identity(frame.tracker_identity)}): its frame "
                                   "does not hold here")
            context = RunContext(
                routine=planned.plan.routine, model=req.model,
                tool_mm=tuple(float(v) for v in planned.model.tool_mm()), robot_url=robot_url,
                tracker_url=tracker_url, seed=req.seed,
                frame_run=None if frame is None else frame.id,
                tracker_T_base=None if frame is None else frame.frame["tracker_T_base"],
                executor=req.executor, acquire=planned.acquire, motion=req.motion,
                tracker=req.tracker, tracker_check=found,
                **reflector_context(tracker, req.smr_radius_mm))
            run_id = store.create_run(planned.plan, context, robot_desc=describe(robot),
                                      tracker_desc=describe(tracker),
                                      robot_identity=cell.robot.to_dict(),
                                      tracker_identity=cell.tracker.to_dict(),
                                      robot_id=robot_id)
            held.acquire(run_key(run_id), f"run {run_id}")
            if on_started is not None:
                on_started(run_id, 0)
            return execute(store, run_id, planned.plan, robot, tracker, model=planned.model,
                           context=context, progress=progress)


# ------------------------------------------------------------------- resume
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
    (it is recorded when the run had none). A completed run comes back as it is
    (:attr:`Resumable.completed`).
    """
    from calibration import ModelError, load_model

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
    if r.status == "completed":
        return Resumable(r, plan, done)
    with held_leases(store, leases) as held:
        taken = held.acquire(run_key(r.id), f"run {r.id}")
    if robot_id and not r.robot_id:
        store.update_run(r.id, robot_id=robot_id)
    r = store.run(r.id)  # as it is now that no one else runs it
    done = store.n_samples(r.id)
    if r.status == "running":
        owner = "" if taken is None else f" (its owner, {taken.describe()}, is gone)"
        store.add_interruption(r.id, None, "killed",
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


def resume_run(store: RunStore, resumable: Resumable, *, executor: dict | None = None,
               acquire: dict | None = None, tracker_setup: dict | None = None,
               devices: tuple | None = None,
               progress: ProgressFn | None = None,
               on_started: Callable[[int, int], None] | None = None,
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
        acq = _acquire_options(get_routine(r.routine), {**stored.acquire, **(acquire or {})})
        setup = TrackerSetup(**{**stored.tracker.model_dump(), **(tracker_setup or {})})
    except ValueError as e:
        raise RequestError(one_line(e)) from None
    robot_url, tracker_url = resumable.robot_url, resumable.tracker_url

    def record(e: ConnectFailed) -> None:
        store.add_interruption(r.id, None, "connection", f"resume: cannot connect: {e}")

    with held_leases(store, leases) as held:
        held.acquire(run_key(r.id), f"run {r.id}")
        take_robot(held, robot_url)
        with reach_devices(robot_url, tracker_url, devices, options.connect_timeout_s,
                           on_fail=record) as (robot, tracker):
            cell = identify(robot, tracker, options.io_timeout_s + 1.0)
            check_robot(resumable.model, robot, cell.robot)
            take_robot(held, robot_url, cell.robot)
            same, why = same_cell(r, cell, robot_url, tracker_url)
            if not same and not other_cell:
                raise OtherCell(f"run {r.id} was measured in another cell: {why}. Resume it "
                                "with its own robot and tracker, or pass --other-cell to start "
                                "a new run of the same plan with these (the two cells' "
                                "samples are never mixed)")
            if confirm is not None:
                confirm(cell, robot_url, tracker_url)
            try:
                found = check_tracker(tracker, setup, options, two_face=False)
            except TrackerRefused as e:
                store.add_interruption(r.id, None, "not_ready", f"resume: {e}")
                raise
            if not same:
                return _repeat_elsewhere(store, resumable, cell, options, acq, robot, tracker,
                                         held, progress, on_started, why)
            context = stored.model_copy(update={"executor": options, "acquire": acq,
                                                "tracker": setup, "robot_url": robot_url,
                                                "tracker_url": tracker_url})
            if robot_url != r.robot_url or tracker_url != r.tracker_url:
                store.update_run(r.id, robot_url=robot_url, tracker_url=tracker_url)
            if r.robot_identity is None:  # a run stored before identities were
                store.update_run(r.id, robot_identity=cell.robot.to_dict(),
                                 tracker_identity=cell.tracker.to_dict())
            if not r.robot_id and (robot_id := default_robot_id(cell.robot)):
                store.update_run(r.id, robot_id=robot_id)
            done = store.n_samples(r.id)
            if on_started is not None:
                on_started(r.id, done)
            store.add_interruption(r.id, None, "resume", f"resumed with {done}/{r.n_points} "
                                   f"points stored; tracker: {found.model_dump_json()}")
            return execute(store, r.id, resumable.plan, robot, tracker,
                           model=resumable.model, context=context, progress=progress)


def _repeat_elsewhere(store, resumable: Resumable, cell: CellIdentity, options, acq, robot,
                      tracker, held: Leases, progress, on_started, why: str) -> RunOutcome:
    """``resume --other-cell``: a new run of the resumed run's plan in this cell."""
    r = resumable.run
    robot_id = default_robot_id(cell.robot)
    frame = _frame_run(store, None, cell, robot_id, resumable.robot_url)
    context = r.context.model_copy(update={
        "executor": options, "acquire": acq, "robot_url": resumable.robot_url,
        "tracker_url": resumable.tracker_url,
        "frame_run": None if frame is None else frame.id,
        "tracker_T_base": None if frame is None else frame.frame["tracker_T_base"]})
    run_id = store.create_run(resumable.plan, context, robot_desc=describe(robot),
                              tracker_desc=describe(tracker),
                              robot_identity=cell.robot.to_dict(),
                              tracker_identity=cell.tracker.to_dict(), source_run=r.id,
                              robot_id=robot_id)
    held.acquire(run_key(run_id), f"run {run_id}")
    store.add_interruption(r.id, None, "other_cell",
                           f"not resumed here: {why}; its plan runs again as run {run_id}")
    store.add_interruption(run_id, None, "other_cell",
                           f"the plan of run {r.id} again, in another cell ({why})")
    if on_started is not None:
        on_started(run_id, 0)
    return execute(store, run_id, resumable.plan, robot, tracker, model=resumable.model,
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
    ex = Executor(store, run_id, plan, robot, tracker, context.executor,
                  acquisition=None if make_acquisition is None
                  else make_acquisition(model, context),
                  progress=progress, finalize=getattr(mod, "finalize", None),
                  guard=MotionGuard(model, context.motion), remeasure=remeasure)
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
