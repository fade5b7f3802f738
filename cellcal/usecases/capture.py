"""``cellcal capture ROUTINE``: a routine's plan, dry-run, then run into the run store.

:class:`CaptureArgs` is what the user asked (every flag, checked once and named by its
flag); :func:`capture` plans and dry-runs it with the capture service
(:func:`daq.service.plan_run`), draws the plan when asked, and unless it is a dry run
stores and executes the run (:func:`daq.service.start_run`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Annotated, Any, Self

from pydantic import AfterValidator, BeforeValidator, Field

from ..errors import UsageError
from ..flags.capture_flags import EXEC_FLAGS, flag_values
from ..flags.routine_args import ROUTINE_ARGS
from ..flags.values import parse_floats
from ..request import Request
from .flag_errors import aliases, build


def comma_numbers(n: int):
    """A before-validator: ``"1,2,3"`` as a tuple of ``n`` floats (None stays None)."""
    def parse(v):
        return v if v is None or isinstance(v, tuple) else tuple(parse_floats(v, n))
    return BeforeValidator(parse)


def _tool(v):
    if v is None or isinstance(v, tuple):
        return v
    return tuple(parse_floats(v, 3))


def _radius(v: float | None) -> float | None:
    if v is not None and not 0 < v < 1000:
        raise ValueError(f"{v:g} is not a radius in mm (0 < r < 1000)")
    return v


def _boxes(v):
    return tuple(tuple(parse_floats(b, 6)) if isinstance(b, str) else b for b in v or ())


Point = tuple[float, float, float]


def check_urls(robot: str | None, tracker: str | None) -> None:
    """Refuse a malformed robot or tracker URL before anything is opened or created."""
    from drivers.urls import check_url

    try:
        for url, kind in ((robot, "robot"), (tracker, "tracker")):
            if url is not None:
                check_url(url, kind)
    except ValueError as e:
        raise UsageError(str(e)) from None


class CaptureArgs(Request):
    """What ``cellcal capture ROUTINE`` was asked (docs: ``cellcal capture ROUTINE
    --help``). ``params`` are the routine's own (:mod:`cellcal.flags.routine_args`),
    ``executor`` and ``acquire`` the settings given (attribute -> value)."""

    routine: str = Field(alias="ROUTINE")
    model: str = Field(alias="--model")
    db: str = Field(alias="--db")
    robot: str = Field(alias="--robot")
    tracker: str = Field(alias="--tracker")
    robot_id: str | None = Field(None, alias="--robot-id")
    synchronous: str = Field("FULL", alias="--synchronous")
    tool_mm: Annotated[Point | None, BeforeValidator(_tool)] = Field(None, alias="--tool-mm")
    smr_radius_mm: Annotated[float | None, AfterValidator(_radius)] = Field(
        None, alias="--smr-radius-mm")
    seed: int | None = Field(None, alias="--seed")
    floor_z_mm: float = Field(0.0, alias="--floor-z-mm")
    no_floor: bool = Field(False, alias="--no-floor")
    max_reach_mm: float | None = Field(None, alias="--max-reach-mm")
    keepout_mm: Annotated[tuple[tuple[float, ...], ...], BeforeValidator(_boxes)] = Field(
        (), alias="--keepout-mm")
    check_paths: bool = Field(False, alias="--check-paths")
    frame_run: int | None = Field(None, alias="--frame-run")
    dry_run: bool = Field(False, alias="--dry-run")
    tracker_at: Annotated[Point | None, comma_numbers(3)] = Field(None, alias="--tracker-at")
    cell: str | None = Field(None, alias="--cell")
    no_visibility: bool = Field(False, alias="--no-visibility")
    plot: str | None = Field(None, alias="--plot")
    meteo: Annotated[Point | None, comma_numbers(3)] = Field(None, alias="--meteo")
    reflector: str | None = Field(None, alias="--reflector")
    two_face_tol_mm: float | None = Field(None, gt=0, alias="--two-face-tol-mm")
    no_two_face_check: bool = Field(False, alias="--no-two-face-check")
    drift_check: str | None = Field(None, alias="--drift-check")
    drift_references: int = Field(1, ge=1, alias="--drift-references")
    drift_bound_mm: float | None = Field(None, gt=0, alias="--drift-bound-mm")
    require_warm: float | None = Field(None, ge=0, alias="--require-warm")
    params: dict = {}
    executor: dict = {}
    acquire: dict = {}

    @classmethod
    def from_args(cls, args: Any, **given: Any) -> Self:
        """The request of ``cellcal capture ROUTINE``'s arguments: the URLs checked first,
        then the routine's parameters, then every flag (UsageError naming the flag)."""
        check_urls(args.robot, args.tracker)
        spec = ROUTINE_ARGS[args.routine]
        try:
            params = spec.params(args)
        except ValueError as e:
            raise UsageError(str(e)) from None
        return super().from_args(args, params=params, executor=flag_values(args, EXEC_FLAGS),
                                 acquire=flag_values(args, spec.acquire_flags), **given)

    def tracker_given(self) -> dict:
        """The tracker setup the flags give (:class:`~daq.run_context.TrackerSetup` fields)."""
        given: dict = {} if self.meteo is None else {"meteo": self.meteo}
        if self.reflector is not None:
            given["reflector"] = self.reflector
        if self.no_two_face_check:
            given["two_face_check"] = False
        if self.two_face_tol_mm is not None:
            given["two_face_tol_mm"] = self.two_face_tol_mm
        return given


def executor_options(values: dict, base=None):
    """ExecutorOptions from flag values (over ``base``'s); UsageError naming the flag."""
    from daq.run_context import ExecutorOptions

    return build(ExecutorOptions, {**(base.model_dump() if base is not None else {}), **values},
                 {attr: flag for flag, attr, _, _ in EXEC_FLAGS})


def tracker_setup(given: dict, stored: dict | None = None):
    """The tracker setup of ``given`` fields over ``stored`` (a resumed run's); UsageError
    with the setup's own reasons (they name their flags)."""
    from pydantic import ValidationError

    from daq.run_context import TrackerSetup

    try:
        return TrackerSetup(**{**(stored or {}), **given})
    except ValidationError as e:
        raise UsageError("; ".join(err["msg"].removeprefix("Value error, ")
                                   for err in e.errors())) from None


def service_request(req: CaptureArgs):
    """The capture service's request (:class:`daq.service.CaptureRequest`): the motion
    limits, the cell, the executor and the tracker setup checked (UsageError naming the
    flag)."""
    from calibration.cell.cell import load_cell
    from daq.motion_guard import MotionLimits
    from daq.service import CaptureRequest

    limits = build(MotionLimits, {
        "floor_z_mm": None if req.no_floor else req.floor_z_mm,
        "max_reach_mm": req.max_reach_mm, "keepout_mm": req.keepout_mm,
        "check_paths": req.check_paths}, aliases(CaptureArgs))
    try:
        cell = None if req.cell is None else load_cell(req.cell)
    except ValueError as e:
        raise UsageError(str(e)) from None
    return CaptureRequest(
        cell=cell, tracker_at=req.tracker_at, visibility=not req.no_visibility,
        routine=req.routine, model=req.model, params=req.params, tool_mm=req.tool_mm,
        smr_radius_mm=req.smr_radius_mm, seed=req.seed, floor_z_mm=limits.floor_z_mm,
        max_reach_mm=limits.max_reach_mm, frame_run=req.frame_run,
        executor=executor_options(req.executor), acquire=req.acquire, motion=limits,
        tracker=tracker_setup(req.tracker_given()), robot_id=req.robot_id,
        drift_check=drift_check(req), require_warm_min=req.require_warm)


def drift_check(req: CaptureArgs):
    """The drift checks asked for (:class:`daq.drift_checks.DriftCheck`), or None;
    UsageError naming the flag."""
    from daq.drift_checks import DriftCheck

    if req.drift_check is None:
        if req.drift_references != 1 or req.drift_bound_mm is not None:
            raise UsageError("--drift-references and --drift-bound-mm go with --drift-check")
        return None
    try:
        return DriftCheck.parse(req.drift_check, references=req.drift_references,
                                bound_mm=req.drift_bound_mm)
    except ValueError as e:
        raise UsageError(f"--drift-check {req.drift_check!r}: {e}") from None


@dataclass(frozen=True)
class CaptureResult:
    """A capture: its plan, dry-run and accepted (``planned``, a
    :class:`~daq.service.PlannedRun`), the estimated capture time (:func:`daq.sight.estimate_time`)
    and how the run ended (a :class:`~daq.service.RunOutcome`; None for a dry run)."""

    planned: Any
    estimate: dict
    outcome: Any = None

    def dry_run_json(self) -> dict:
        """The ``capture --dry-run --json`` document."""
        plan = self.planned.plan
        return {"routine": plan.routine, "points": plan.n_planned,
                "spares": len(plan) - plan.n_planned, "plan_hash": plan.hash, "check": "ok",
                "params": plan.params, "sight": self.planned.sight.to_json(), **self.estimate}


def capture(req: CaptureArgs, *, model=None,
            on_planned: Callable[[CaptureResult], None] | None = None,
            progress=None, on_started: Callable[[int, int], None] | None = None,
            confirm=None) -> CaptureResult:
    """Plan and dry-run the request (the plan drawn into ``req.plot`` when given); unless
    ``req.dry_run``, store and execute the run.

    ``model``: the robot model already loaded (``req.model`` names it; ``validate``
    passes its calibration's). ``on_planned(result)`` is called once the plan is accepted
    (before the store is opened); ``progress``, ``on_started`` and ``confirm`` go to
    :func:`daq.service.start_run`. Raises what the service raises (RequestError,
    PlanRefused, ConnectFailed, StoreUnavailable, LeaseBusy); a run store that cannot be
    opened is a UsageError.
    """
    from daq.service import plan_run, start_run
    from daq.sight import estimate_time
    from daq.store import RunStore, StoreError

    request = service_request(req)
    planned = plan_run(request, model=model, db=req.db)
    result = CaptureResult(planned, estimate_time(planned.plan, request.executor))
    if req.plot:
        from presentation.plan_figure import plan_figure

        plan_figure(planned.model, planned.plan, planned.sight.cell).savefig(req.plot, dpi=110)
    if on_planned is not None:
        on_planned(result)
    if req.dry_run:
        return result
    try:
        store = RunStore(req.db, synchronous=req.synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None
    try:
        return replace(result, outcome=start_run(
            store, planned, robot_url=req.robot, tracker_url=req.tracker, progress=progress,
            on_started=on_started, confirm=confirm))
    finally:
        store.close()
