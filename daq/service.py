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
    :func:`start_run` finds the measurement frame (the given frame run, else the latest
    completed one), builds the run's :class:`~daq.run_context.RunContext`, connects the
    devices (unless handed connected ones), stores the run and executes it.
    :func:`execute` runs a stored run with its routine's ``finalize`` and adaptive
    ``acquisition`` (:mod:`daq.routines`).

Errors: :class:`~daq.errors.RequestError` (and :class:`~daq.errors.PlanRefused`) for
input it refuses, :class:`~daq.errors.ConnectFailed` when the devices cannot be reached.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from .check import CheckResult, check_plan
from .errors import ConnectFailed, PlanRefused, RequestError
from .executor import Executor
from .plans import Plan
from .routines import get as get_routine
from .run_context import ExecutorOptions, RunContext
from .store import Run, RunStore, StoreError, StoreUnavailable

#: progress callback of the executor: (points done, points in all, last error)
ProgressFn = Callable[[int, int, "str | None"], None]


@dataclass(frozen=True)
class CaptureRequest:
    """What to capture: a routine's plan for a model, checked and run with these settings.

    ``model`` is a built-in name or a YAML path (recorded with the run); ``params`` are
    the routine's ``make_plan`` keyword arguments; ``frame_run`` None takes the latest
    completed frame run of the same robot in the store, if any; ``acquire`` are the
    routine's acquisition options (zero20: :class:`~daq.routines.zero20.ZeroLoopOptions`
    fields); ``robot_id`` names the robot (default: the controller's ``MODEL/SERIAL`` when
    it reports a serial number, :func:`robot_identity`).
    """

    routine: str
    model: str
    params: dict = field(default_factory=dict)
    tool_mm: tuple[float, float, float] | None = None
    seed: int | None = None
    floor_z_mm: float | None = 0.0
    max_reach_mm: float | None = None
    frame_run: int | None = None
    executor: ExecutorOptions = field(default_factory=ExecutorOptions)
    acquire: dict = field(default_factory=dict)
    robot_id: str | None = None


@dataclass(frozen=True)
class PlannedRun:
    """A request's plan, dry-run and accepted: ``model`` has the controller's tool,
    ``acquire`` the routine's complete acquisition options."""

    request: CaptureRequest
    model: object
    plan: Plan
    check: CheckResult
    acquire: dict


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
    exhausted), ``stopped`` (Ctrl-C) or ``failed`` (finalize failed); ``reason`` why it
    did not complete; ``points`` in the plan, ``samples`` stored, ``faults`` met in this
    session, ``elapsed_s`` of execution; ``frame`` and ``summary`` as stored.
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
        return out


# ------------------------------------------------------------------ devices
def describe(driver) -> str:
    """A one-line description of a driver (class, model, serial, firmware when known)."""
    parts = [type(driver).__name__]
    for k in ("model", "serial", "firmware"):
        v = getattr(driver, k, "")
        if isinstance(v, str) and v:
            parts.append(f"{k}={v}")
    n = getattr(driver, "n_joints", 0)
    if isinstance(n, int) and n:
        parts.append(f"joints={n}")
    return " ".join(parts)


def robot_identity(robot, given: str | None = None) -> str | None:
    """Who the robot is: ``given`` (a name from the command line), else the controller's
    ``MODEL/SERIAL`` when its protocol reports a serial number, else None."""
    if given:
        return given
    model, serial = getattr(robot, "model", ""), getattr(robot, "serial", "")
    if isinstance(serial, str) and serial:
        return f"{model}/{serial}" if isinstance(model, str) and model else serial
    return None


def open_drivers(robot_url: str, tracker_url: str, timeout: float = 5.0):
    """Connected (robot, tracker); closes what was opened when the other fails.

    :class:`RequestError` for a URL no driver knows, :class:`ConnectFailed` when a
    device cannot be reached.
    """
    import sim_drivers.inprocess  # noqa: F401  (registers sim://)
    from drivers.errors import DriverError
    from drivers.urls import open_robot, open_tracker

    try:
        robot = open_robot(robot_url)
        tracker = open_tracker(tracker_url)
    except ValueError as e:
        raise RequestError(str(e)) from None
    try:
        robot.connect(timeout=timeout)
        tracker.connect(timeout=timeout)
    except DriverError as e:
        robot.close()
        tracker.close()
        raise ConnectFailed(str(e)) from e
    return robot, tracker


@contextlib.contextmanager
def _devices(robot_url, tracker_url, devices, timeout, on_fail=None) -> Iterator[tuple]:
    """The given connected devices (left open), else the URLs' (closed at the end);
    ``on_fail(error)`` is called before a :class:`ConnectFailed` propagates."""
    if devices is not None:
        yield devices
        return
    try:
        robot, tracker = open_drivers(robot_url, tracker_url, timeout)
    except ConnectFailed as e:
        if on_fail is not None:
            on_fail(e)
        raise
    try:
        yield robot, tracker
    finally:
        robot.close()
        tracker.close()


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
        The run store, opened only when the routine's parameters refer to an earlier
        run (zero20 ``--replay``).

    Raises
    ------
    RequestError
        Unknown routine or model, bad parameters or acquisition options.
    PlanRefused
        The plan fails the dry run (joint limits, reach, floor).
    """
    from calibration import load_model

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
        plan = mod.make_plan(model, **params)
        acquire = _acquire_options(mod, request.acquire)
    except ValueError as e:  # ModelError, pydantic's ValidationError, RequestError too
        raise RequestError(str(e)) from None
    res = check_plan(plan, model, floor_z_mm=request.floor_z_mm,
                     max_reach_mm=request.max_reach_mm)
    if not res.ok:
        raise PlanRefused(res)
    return PlannedRun(request, model, plan, res, acquire)


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


def _same_robot(r: Run, robot_id: str | None, robot_url: str | None) -> bool:
    """Run ``r`` measured this robot: the same identity when both know theirs; the same URL
    when only one does; any run when neither does (a store of one cell)."""
    if robot_id and r.robot_id:
        return r.robot_id == robot_id
    if robot_id or r.robot_id:
        return r.robot_url == robot_url
    return True


def frame_run(store: RunStore, run_id: int | None, robot_id: str | None = None,
              robot_url: str | None = None) -> Run | None:
    """The frame run ``run_id`` (it must have a frame), else the latest completed frame
    run of the same robot (``robot_id``, ``robot_url``: :func:`_same_robot`), else None."""
    if run_id is not None:
        try:
            r = store.run(run_id)
        except StoreError as e:
            raise RequestError(str(e)) from None
        if r.frame is None:
            raise RequestError(f"run {run_id} has no measurement frame (not a completed "
                               "frame run)")
        return r
    for r in reversed(store.runs()):
        if (r.routine == "frame" and r.status == "completed" and r.frame is not None
                and _same_robot(r, robot_id, robot_url)):
            return r
    return None


def start_run(store: RunStore, planned: PlannedRun, *, robot_url: str, tracker_url: str,
              devices: tuple | None = None, progress: ProgressFn | None = None,
              on_started: Callable[[int, int], None] | None = None) -> RunOutcome:
    """Store a new run of ``planned`` (with the robot's identity, :func:`robot_identity`)
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
    """
    req = planned.request
    given_frame = frame_run(store, req.frame_run) if req.frame_run is not None else None
    with _devices(robot_url, tracker_url, devices, req.executor.connect_timeout_s) as (
            robot, tracker):
        robot_id = robot_identity(robot, req.robot_id)
        frame = given_frame or frame_run(store, None, robot_id, robot_url)
        context = RunContext(
            routine=planned.plan.routine, model=req.model,
            tool_mm=tuple(float(v) for v in planned.model.tool_mm()), robot_url=robot_url,
            tracker_url=tracker_url, seed=req.seed,
            frame_run=None if frame is None else frame.id,
            tracker_T_base=None if frame is None else frame.frame["tracker_T_base"],
            executor=req.executor, acquire=planned.acquire)
        run_id = store.create_run(planned.plan, context, robot_desc=describe(robot),
                                  tracker_desc=describe(tracker), robot_id=robot_id)
        if on_started is not None:
            on_started(run_id, 0)
        return execute(store, run_id, planned.plan, robot, tracker, model=planned.model,
                       context=context, progress=progress)


# ------------------------------------------------------------------- resume
def prepare_resume(store: RunStore, run_id: int | None = None, *,
                   robot_url: str | None = None, tracker_url: str | None = None,
                   robot_id: str | None = None) -> Resumable:
    """Find run ``run_id`` (default: the latest) and what resuming it needs.

    A run found still ``running`` (its process was killed, or it lost its run store) gets
    a ``killed`` interruption. ``robot_url``/``tracker_url`` replace the stored ones.
    ``robot_id`` must be the run's robot (it is recorded when the run had none). A
    completed run comes back as it is (:attr:`Resumable.completed`).
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
    if robot_id and not r.robot_id:
        store.update_run(r.id, robot_id=robot_id)
    if r.status == "running":
        store.add_interruption(r.id, None, "killed",
                               "found still running on resume: the process was killed or "
                               "crashed, or lost its run store")
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
               acquire: dict | None = None, devices: tuple | None = None,
               progress: ProgressFn | None = None,
               on_started: Callable[[int, int], None] | None = None) -> RunOutcome:
    """Continue a run from :func:`prepare_resume`: the points not yet stored.

    ``executor`` and ``acquire`` override the stored executor and acquisition options
    for this session (the stored context keeps its own). New URLs are stored with the run. A failed
    connection is recorded as an interruption, then :class:`ConnectFailed`.
    """
    r = resumable.run
    stored = r.context
    try:
        options = ExecutorOptions(**{**stored.executor.model_dump(), **(executor or {})})
        acq = _acquire_options(get_routine(r.routine), {**stored.acquire, **(acquire or {})})
    except ValueError as e:
        raise RequestError(str(e)) from None
    context = stored.model_copy(update={"executor": options, "acquire": acq,
                                        "robot_url": resumable.robot_url,
                                        "tracker_url": resumable.tracker_url})

    def record(e: ConnectFailed) -> None:
        store.add_interruption(r.id, None, "connection", f"resume: cannot connect: {e}")

    with _devices(resumable.robot_url, resumable.tracker_url, devices,
                  options.connect_timeout_s, on_fail=record) as (robot, tracker):
        if resumable.robot_url != r.robot_url or resumable.tracker_url != r.tracker_url:
            store.update_run(r.id, robot_url=resumable.robot_url,
                             tracker_url=resumable.tracker_url)
        done = store.n_samples(r.id)
        if on_started is not None:
            on_started(r.id, done)
        store.add_interruption(r.id, None, "resume", f"resumed with {done}/{r.n_points} "
                               "points stored")
        return execute(store, r.id, resumable.plan, robot, tracker, model=resumable.model,
                       context=context, progress=progress)


# ------------------------------------------------------------------ execute
def execute(store: RunStore, run_id: int, plan: Plan, robot, tracker, *, model,
            context: RunContext, progress: ProgressFn | None = None) -> RunOutcome:
    """Run (or continue) stored run ``run_id`` with ``context``'s executor options and the
    routine's finalize and acquisition; the outcome as stored afterwards."""
    mod = get_routine(plan.routine)
    make_acquisition = getattr(mod, "acquisition", None)
    ex = Executor(store, run_id, plan, robot, tracker, context.executor,
                  acquisition=None if make_acquisition is None
                  else make_acquisition(model, context),
                  progress=progress, finalize=getattr(mod, "finalize", None))
    t0 = time.monotonic()
    status = ex.run()
    elapsed = time.monotonic() - t0
    try:
        run = store.run(run_id)
        reason, n, frame, summary = run.reason, store.n_samples(run_id), run.frame, run.summary
    except StoreUnavailable:  # paused because the store is away: what the executor knows
        reason, n, frame, summary = ex.last_error, ex.n_done, None, None
    return RunOutcome(run_id, plan.routine, status, reason, len(plan), n, ex.n_faults,
                      elapsed, plan.hash, store.address, frame, summary)
