"""The run store's records of runs: a run as stored (:class:`Run`, its :class:`RunStatus`
and its summary, :class:`daq.store.summary.RunSummary`), why it was interrupted
(:class:`Interruption`, of an :class:`InterruptionKind`), a recorded calibration
(:class:`Calibration`) and a check of one on new poses (:class:`Check`). Plain data, no
database (:mod:`daq.store`); a run's measurements are :mod:`daq.store.samples`.

Statuses and interruption kinds are stored as their strings (``paused``, ``beam``): a
store written before they were enums reads back the same.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from enum import StrEnum
from typing import NamedTuple, TypeVar, overload

from ..run_context import RunContext
from .summary import RunSummary


class RunStatus(StrEnum):
    """Where a run stands."""

    #: capturing (or killed while capturing: ``resume`` finds it so)
    RUNNING = "running"
    #: protective stop, retries exhausted, a store away: resumable
    PAUSED = "paused"
    #: Ctrl-C: resumable
    STOPPED = "stopped"
    COMPLETED = "completed"
    #: refused or broken: resumable once the cause is fixed
    FAILED = "failed"
    #: went through its plan with more than a small share of its points missing (skipped,
    #: their beam broken: :mod:`daq.completeness`); not resumable, the reason names them
    INCOMPLETE = "incomplete"


#: the run statuses as stored (:class:`RunStatus`)
STATUSES = tuple(s.value for s in RunStatus)


class InterruptionKind(StrEnum):
    """What interrupted a run at a point (the ``interruptions`` table's ``kind``)."""

    # a device's fault (daq.executor.fault_kind)
    PROTECTIVE_STOP = "protective_stop"
    BEAM = "beam"
    TIMEOUT = "timeout"
    CONNECTION = "connection"
    PROTOCOL = "protocol"
    NOT_READY = "not_ready"
    REJECTED = "rejected"
    # the capture's own refusals (daq.errors.CaptureError.kind and its subclasses')
    CAPTURE = "capture"
    QUALITY = "quality"
    STALE_MEASUREMENT = "stale_measurement"
    ZERO_NOT_REACHED = "zero_not_reached"
    ZERO_DIVERGED = "zero_diverged"
    MOVE_REFUSED = "move_refused"
    MOTION_MISMATCH = "motion_mismatch"
    # what the executor did about it
    SKIPPED = "skipped"
    RECONNECT = "reconnect"
    STORE = "store"
    # how a session ended
    PAUSE = "pause"
    SIGINT = "sigint"
    STOP_NOW = "stop_now"
    ERROR = "error"
    FINALIZE = "finalize"
    # what resume found and did
    KILLED = "killed"
    RESUME = "resume"
    OTHER_CELL = "other_cell"


class Interruption(NamedTuple):
    """One row of ``interruptions``: the point (None: the run's), when (epoch s), its kind
    (a plain string for a kind this cellcal does not know) and the message."""

    point_index: int | None
    t: float
    kind: InterruptionKind | str
    message: str


_E = TypeVar("_E", bound=StrEnum)


@overload
def known(enum: type[_E], value: str) -> _E | str: ...


@overload
def known(enum: type[_E], value: None) -> None: ...


def known(enum: type[_E], value: str | None) -> _E | str | None:
    """``value`` as a member of ``enum``, or as given when it is none (an older or newer
    cellcal's string, None)."""
    if value is None:
        return None
    try:
        return enum(value)
    except ValueError:
        return value


@dataclass
class Run:
    """One row of ``runs``: plan, frame, summary and context decoded.

    ``robot_url``, ``tracker_url``, ``seed`` and ``model`` are the context's;
    ``robot_id`` is who the robot is (the controller's ``MODEL/SERIAL`` or the name given
    with ``--robot-id``; None when neither was known).
    """

    id: int
    routine: str
    plan_json: str
    plan_hash: str
    n_points: int
    robot_desc: str | None
    tracker_desc: str | None
    software: str | None
    started: float | None
    stopped: float | None
    status: RunStatus | str  # a plain string for a status this cellcal does not know
    reason: str | None
    frame: dict | None
    summary: RunSummary | None
    context: RunContext
    robot_id: str | None = None
    #: who the devices said they were (DeviceIdentity dicts), None when not recorded
    robot_identity: dict | None = None
    tracker_identity: dict | None = None
    #: the run whose plan this run repeats on another cell (``resume --other-cell``)
    source_run: int | None = None

    @property
    def robot_url(self) -> str | None:
        return self.context.robot_url

    @property
    def tracker_url(self) -> str | None:
        return self.context.tracker_url

    @property
    def seed(self) -> int | None:
        return self.context.seed

    @property
    def model(self) -> str | None:
        return self.context.model


@dataclass(frozen=True)
class Calibration:
    """One row of ``calibrations``: a robot's calibration as its params.json.

    ``t`` when its data were measured (epoch s: the latest ``t_s`` of the data, else when
    it was recorded), ``recorded`` when it was stored, ``source_file`` the measurement
    CSV, ``source_run`` the run it came from (when known), ``software`` the cellcal that
    fitted it.
    """

    id: int
    robot_id: str
    t: float
    recorded: float
    params_json: str
    source_file: str | None
    source_run: int | None
    software: str | None

    @property
    def params(self) -> dict:
        """The params.json document (docs/formats.md)."""
        return json.loads(self.params_json)


@dataclass(frozen=True)
class Check:
    """One row of ``checks``: a robot's calibration checked on new poses (``cellcal check
    --db``).

    ``t`` when the poses were measured (epoch s: the latest ``t_s`` of the data, else when
    it was recorded), ``recorded`` when it was stored; ``params_sha256`` the params.json
    checked and ``calibration_id`` the calibration of the same robot recorded with those
    parameters (None when they were not recorded); ``n``, ``rms_mm`` ... ``max_mm`` the
    error statistics; ``tolerance_mm`` and ``within_tolerance`` (None without a
    tolerance); ``refitted`` the effects refitted (``["base"]`` or empty); ``result_json``
    the check's ``--json`` object; ``source_file``, ``source_run``, ``software`` as a
    calibration's.
    """

    id: int
    robot_id: str
    t: float
    recorded: float
    params_sha256: str
    calibration_id: int | None
    n: int
    rms_mm: float | None
    mean_mm: float | None
    p95_mm: float | None
    max_mm: float | None
    tolerance_mm: float | None
    within_tolerance: bool | None
    refitted: tuple[str, ...]
    result_json: str
    source_file: str | None
    source_run: int | None
    software: str | None

    @property
    def result(self) -> dict:
        """The check's ``--json`` object (docs/formats.md §4)."""
        return json.loads(self.result_json)
