"""What the capture service is asked and what it answers: a capture request, its planned
run, and how a run ended (:mod:`daq.service`).

:class:`CaptureRequest` is checked when made (:class:`~daq.errors.RequestError` for a tool
or floor that is not finite, motion limits that are not valid); :class:`PlannedRun` is a
request's plan accepted by the dry run (:func:`daq.planning.plan_run`);
:class:`RunOutcome` is what :func:`daq.service.start_run` and
:func:`daq.service.resume_run` return, with its ``--json`` document.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from calibration.cell.cell import CellSpec

from .check import CheckResult
from .drift_checks import DriftCheck
from .errors import RequestError, one_line
from .motion_guard import MotionLimits
from .plans import Plan
from .run_context import ExecutorOptions, TrackerSetup
from .stop_signals import signal_name

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
    :func:`daq.devices.default_robot_id`); ``drift_check`` the drift checks inserted into
    the plan, ``require_warm_min`` the warm-up the run requires. Checked when made:
    :class:`RequestError` for a tool or floor that is not finite, motion limits that are
    not valid.
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
    #: the cell (tracker, SMR, margins, fixtures; :mod:`calibration.cell.cell`), the user's rough
    #: tracker position (mm, base frame), and whether to plan for the line of sight
    cell: CellSpec | None = None
    tracker_at: tuple[float, float, float] | None = None
    visibility: bool = True
    tracker: TrackerSetup = field(default_factory=TrackerSetup)
    motion: MotionLimits | None = None
    robot_id: str | None = None
    #: reference poses measured again during the run (:mod:`daq.drift_checks`), or None
    drift_check: DriftCheck | None = None
    #: refuse the run unless the robot's last warm-up ended at most this many minutes ago
    #: and its joints have not cooled since (:mod:`daq.warm_gate`); None: not required
    require_warm_min: float | None = None

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
class RunOutcome:
    """How a (resumed) run ended.

    ``status``: ``completed``, ``incomplete`` (too many points skipped:
    :mod:`daq.completeness`), ``paused`` (protective stop, rejected command, retries
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
