"""The executor: runs a plan one point at a time and loses nothing.

For each target not yet in the store: move (via the pre-position if any) →
wait until settled (+ an optional dwell) → read the joints (and the
controller's nominal TCP when the robot offers :class:`CommandedPosition`) →
measure (averaged; a per-axis std above ``max_std_mm`` is remeasured) → read the
joints again → the re-measure policy when there is one (the reading judged against the
model fitted so far, a suspect re-measured: :mod:`daq.remeasure`) → write one sample
(with the readings not accepted) in one transaction of the run store, with what the tracker says
of its measurement (std, covariance, air, reflector, face) and the joints' temperatures
where the robot reports them (:class:`~drivers.protocols.JointTemperatures`). That commit
is the checkpoint.

Safe motion
    Every move — planned, via, or adaptive — is checked by the run's
    :class:`~daq.motion_guard.MotionGuard` before it is sent (joint limits, floor,
    keep-out, reach, multi-turn linear moves, and for adaptive moves the deviation from
    the point's planned posture); a refused move pauses the run
    (:class:`~daq.motion_guard.MotionRefused`). After every move the joints read back
    must match the command before the tracker is asked, and they must not have changed
    during the measurement (someone else moving the robot); otherwise
    :class:`~daq.motion_guard.MotionMismatch` pauses the run — never a stored sample. A
    measurement that is not newer than the previous one (a tracker repeating its reply:
    same time, or the very same numbers) is refused (:class:`StaleMeasurement`,
    transient: measured again). A re-measure policy's moves and readings
    (:mod:`daq.remeasure`) go through the same checked moves, read-back and
    measurement (:class:`PointContext`).

Entry move
    A plan's linear targets carry the joints the controller reaches moving from the
    previous target (a linear move keeps the flange orientation it starts with). Where
    the robot comes from is unknown at the first point of a session (a start, a resume,
    a reconnected robot), so when that point is a linear one the executor first makes a
    checked joint move to its planned posture, then the linear move(s).

Adaptive acquisition
    A routine may hand the executor an :class:`Acquisition` strategy: after the move
    the executor calls ``acquisition.acquire(target, ctx)`` in place of the single
    read-joints → measure, and the strategy returns the joints and the measurement
    of the point. It acts through ``ctx`` (a :class:`PointContext`: the executor's
    own moves, reads and quality-checked measurements, and the run's summary as
    state kept across resumes), so its faults are handled like any other. zero20's
    closed loop is one (:mod:`daq.routines.zero20`).

Faults
    * transient errors (``DriverError.transient``: beam break, timeout, dropped
      connection, garbage, device not ready; ``CaptureError.transient``: a
      measurement too noisy) are recorded, then the point is retried after a
      backoff (doubling, capped) and a reconnection (close + connect) of the device
      that failed; after ``max_retries`` the run is paused;
    * a protective stop pauses the run (status ``paused``, the reason recorded
      and printed); an operator clears it, then ``cellcal resume``;
    * any other driver or capture error (command rejected, limit, a closed loop that
      did not converge) pauses the run too;
    * Ctrl-C (SIGINT) stops after the current point (status ``stopped``); a second
      Ctrl-C, SIGTERM or SIGHUP stops at once: the controller's stop is sent and the
      run is ``paused`` with the reason (:mod:`daq.stop_signals`; :attr:`Executor.stop_signal`);
    * a lost run store connection (:class:`~daq.store.StoreUnavailable`: a PostgreSQL
      server restarting or out of reach) holds the robot where it is and keeps the
      point's sample: the executor reconnects with the same backoff for up to
      ``store_wait_s``, then commits the sample (the insert is idempotent, so a commit
      that did land before the connection broke is not doubled) and goes on, recording a
      ``store`` interruption; a store still away after that pauses the run (status
      ``paused`` once it can be written; ``cellcal resume`` redoes the points not stored).
    * a full disk under the store (:class:`~daq.store.StoreFull`: nothing of the
      commit was stored) pauses the run at once with the reason, written in the room
      the store keeps in reserve (:meth:`~daq.store.RunStore.release_reserve`);
      ``cellcal resume`` completes it once there is space.

Beam breaks (the line of sight)
    A beam break is a fault like any other (recorded with the point and the tracker's
    reason, retried). When it persists — more than :data:`BEAM_RETRIES` breaks at one point
    (a link or fixture in the beam, the SMR facing away) — the point is skipped instead
    of pausing the run: an interruption of kind ``skipped`` records it, and the plan's
    next spare point (``info.spare``, measured only for this) is measured in its place
    once the regular points are done. zero20's closed-loop points are never skipped.
    The run's summary counts ``beam_breaks``, lists ``skipped_points`` and counts
    ``spares_measured``, and keeps ``capture_s``, the wall time spent executing the run
    (summed over its sessions), to set against the dry run's estimate.

Every interruption goes to the store's ``interruptions`` table. A point whose
sample was not committed is simply done again on resume; the store's
``UNIQUE(run_id, point_index)`` makes a double write impossible.

Log (``daq.executor``)
    The executor's decisions at INFO: the run started or resumed, each move (the point,
    joint or linear, its target in deg or mm), each sample stored, every fault and retry,
    a point skipped, a measurement repeated for its std, the store lost and found again,
    the run's end and why; a move the motion guard refuses or a robot not where it was
    sent at WARNING; a controller's stop that could not be sent at ERROR. Drift checks
    are logged as they are stored (:class:`~daq.drift_checks.DriftWatch`).

Units: rad, mm, s.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
import time
from collections.abc import Callable
from typing import Protocol

import numpy as np

from drivers.errors import (
    BeamBroken,
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.protocols import CommandedPosition, JointReading, JointTemperatures, Measurement

from .completeness import end_status
from .drift_checks import DRIFT_SET, DriftWatch
from .errors import CaptureError, QualityError
from .motion_guard import MotionGuard, MotionMismatch, MotionRefused
from .plans import Plan, Target
from .run_context import ExecutorOptions
from .stop_signals import StopNow, signal_name, stop_handlers
from .store import (
    InterruptionKind,
    RunStatus,
    RunStore,
    RunSummary,
    Sample,
    StoreFull,
    StoreUnavailable,
)

log = logging.getLogger(__name__)

#: beam breaks retried at one point before it is skipped (and a spare measured in its place)
BEAM_RETRIES = 3


class _Shown:
    """Numbers for the log, formatted only when a record is written: joints (rad) in deg,
    or a point in mm."""

    __slots__ = ("unit", "v")

    def __init__(self, v, unit: str = "deg") -> None:
        self.v, self.unit = v, unit

    def __str__(self) -> str:
        v = np.asarray(self.v, float)
        if self.unit == "deg":
            v = np.rad2deg(v)
        return "[" + ", ".join(f"{x:.3f}" for x in v) + f"] {self.unit}"


class StaleMeasurement(CaptureError):
    """The tracker's reply is not newer than the previous one (repeated or older)."""

    transient = True
    kind = "stale_measurement"


class _Pause(Exception):  # noqa: N818 - control flow
    def __init__(self, status: str, reason: str) -> None:
        self.status, self.reason = status, reason
        super().__init__(reason)


def fault_kind(e: BaseException) -> InterruptionKind:
    """The kind of a fault for the interruptions table."""
    K = InterruptionKind  # noqa: N806 - an alias
    if isinstance(e, CaptureError):
        return K(e.kind)
    for cls, kind in ((ProtectiveStop, K.PROTECTIVE_STOP), (BeamBroken, K.BEAM),
                      (CommandTimeout, K.TIMEOUT), (ConnectionLost, K.CONNECTION),
                      (ProtocolError, K.PROTOCOL), (NotReady, K.NOT_READY)):
        if isinstance(e, cls):
            return kind
    return K.REJECTED if isinstance(e, DriverError) else K.ERROR


def approach_dirs(prev, cmd_q, deadband_rad: float) -> np.ndarray:
    """The sign of each joint's motion from ``prev`` to ``cmd_q`` (0 within the deadband)."""
    step = np.asarray(cmd_q, float) - np.asarray(prev, float)
    return np.where(np.abs(step) > deadband_rad, np.sign(step), 0).astype(int)


class Acquisition(Protocol):
    """A routine's adaptive acquisition of a point (see the module docstring)."""

    def acquire(self, target: Target, ctx: PointContext) -> tuple[JointReading, Measurement]:
        """The joints and the measurement of ``target``, the robot having moved to it."""
        ...


class PointContext:
    """What an :class:`Acquisition` may do at one point: the executor's own actions.

    Moves and reads go through the executor, which notes the device in use so a fault
    reconnects the right one; :meth:`measure` is quality-checked (remeasured, then
    :class:`~daq.errors.QualityError`). :meth:`summary` / :meth:`save_summary` keep
    state with the run (it survives a resume).
    """

    def __init__(self, executor: Executor, phase: list[str], target: Target) -> None:
        self._ex, self._phase, self.target = executor, phase, target

    @property
    def robot_url(self) -> str:
        return getattr(self._ex.robot, "url", "")

    @property
    def guard(self) -> MotionGuard:
        """The run's motion guard (its limits bound an acquisition's own moves)."""
        return self._ex.guard

    def at(self, target: Target) -> PointContext:
        """The context of another point of the plan (a re-measure policy's revisit): its
        moves are checked against that point's planned posture."""
        return PointContext(self._ex, self._phase, target)

    def _here(self) -> Executor:
        self._ex._target = self.target  # the point the guard checks moves against
        return self._ex

    def move_joints(self, q) -> JointReading:
        """Adaptive joint move to ``q`` (rad): checked by the motion guard (limits,
        floor, reach, deviation from the point's planned posture) before it is sent,
        then settled and read back; returns the joints read."""
        return self._here()._move_joints(q, self._phase, adaptive=True)

    def move_entry(self) -> JointReading | None:
        """The executor's entry move to the point (a checked joint move to its planned
        posture, where the plan's linear chain starts) when it is a linear one; None
        (nothing moved) otherwise."""
        return self._here()._entry_move(self.target, self._phase)

    def move_via(self) -> np.ndarray | None:
        """The plan's move to the point's pre-position, if it has one (checked, read
        back); the joints the approach to the target starts from (None: no via)."""
        return self._here()._via_move(self.target, self._phase)

    def move_target(self) -> JointReading:
        """The plan's move to the point's target (checked, settled, read back)."""
        return self._here()._target_move(self.target, self._phase)

    def read_joints(self) -> JointReading:
        return self._ex._read_q(self._phase)

    def measure(self) -> Measurement:
        """An averaged measurement whose per-axis std is within ``max_std_mm``, newer
        than the previous one."""
        return self._ex._measure(self._phase)

    def measure_at(self, jr: JointReading) -> tuple[JointReading, Measurement]:
        """The point's reading where the robot stands (``jr``: the joints read after the
        move): the dwell (the joints read again must not have moved), a quality-checked
        measurement, then the joints read back must still be ``jr``'s."""
        ex = self._here()
        jr = ex._dwell(jr, self._phase)
        m = ex._measure(self._phase)
        ex._held(jr, self._phase)
        return jr, m

    def summary(self) -> RunSummary:
        """The run's summary as stored (a copy: :meth:`save_summary` stores a change)."""
        return self._ex.store.run(self._ex.run_id).summary or RunSummary()

    def save_summary(self, summary: RunSummary) -> None:
        self._ex.store.update_run(self._ex.run_id, summary=summary)


class Executor:
    """Runs (or resumes) one stored run.

    Parameters
    ----------
    store : RunStore
    run_id : int
    plan : Plan
        The run's plan (its hash must match the stored one).
    robot, tracker : RobotDriver, TrackerDriver
        Connected drivers (they are reconnected after transient faults).
    options : ExecutorOptions
    acquisition : Acquisition, optional
        The routine's adaptive acquisition (needed by ``zero`` targets).
    progress : callable(done, total, last_error), optional
        Called after every point and every fault.
    finalize : callable(plan, samples, run) -> dict, optional
        Called once every point is stored; may return ``frame`` and/or ``summary``
        dicts for the run.
    guard : MotionGuard, optional
        Checks every move (default: read-back only, no model).
    remeasure : daq.remeasure.Remeasure, optional
        The re-measure policy: judges each point's sample before its commit (and may
        re-measure it), see :mod:`daq.remeasure`.
    enough : callable(plan, samples, run) -> str | None, optional
        Called after every stored point: a reason (the routine's goal is reached, e.g. a
        warm-up that settled) ends the run there, completed, the points left not measured.
    """

    def __init__(
        self,
        store: RunStore,
        run_id: int,
        plan: Plan,
        robot,
        tracker,
        options: ExecutorOptions | None = None,
        *,
        acquisition: Acquisition | None = None,
        progress: Callable[[int, int, str | None], None] | None = None,
        finalize: Callable | None = None,
        guard: MotionGuard | None = None,
        remeasure=None,
        enough: Callable | None = None,
    ) -> None:
        run = store.run(run_id)
        if run.plan_hash != plan.hash:
            raise ValueError(f"run {run_id}: plan hash {plan.hash[:12]} differs from the stored "
                             f"{run.plan_hash[:12]}")
        self.store, self.run_id, self.plan = store, run_id, plan
        self.robot, self.tracker = robot, tracker
        self.o = options or ExecutorOptions()
        self.acquisition = acquisition
        self.progress = progress
        self.finalize = finalize
        self.enough = enough
        self.guard = guard or MotionGuard()
        self.remeasure = remeasure
        self._stop = threading.Event()
        self._halting = False
        self._last_cmd_q: np.ndarray | None = None
        self._q_now: np.ndarray | None = None  # the joints last read (None: unknown)
        self._entry = True  # no planned move done yet this session (see "Entry move")
        self._last_meas: Measurement | None = None
        self._target: Target | None = None
        self._drift: DriftWatch | None = None
        #: the robot reports its joints' temperatures (False once it refused to)
        self._temps = isinstance(robot, JointTemperatures)
        #: the signal that stopped the run at once (SIGINT twice, SIGTERM, SIGHUP), or None
        self.stop_signal: int | None = None
        self.last_error: str | None = None
        self.n_faults = 0
        self._t0 = time.monotonic()
        self.commit_s = 0.0
        self.n_committed = 0
        self._n_done = 0

    # -------------------------------------------------------------- control
    @property
    def n_done(self) -> int:
        """Points stored, as last counted."""
        return self._n_done

    def request_stop(self) -> None:
        """Stop after the current point (what Ctrl-C does)."""
        self._stop.set()

    def _halt_robot(self) -> str:
        """Send the controller's stop (reconnecting once if the link is in a bad state);
        what happened, in words. Signals are ignored from now on (the run is ending)."""
        self._halting = True
        log.info("sending the controller's stop")
        try:
            self.robot.stop(timeout=self.o.io_timeout_s + 1.0)
            return "the controller's stop was sent"
        except Exception as first:  # noqa: BLE001 - whatever failed, try once more
            with contextlib.suppress(Exception):
                self.robot.close()
            try:
                self.robot.connect(timeout=self.o.connect_timeout_s)
                self.robot.stop(timeout=self.o.io_timeout_s + 1.0)
                return "the controller's stop was sent (after reconnecting)"
            except Exception as e:  # noqa: BLE001
                return (f"the controller's stop could NOT be sent ({first}; {e}): check the "
                        "robot at once")

    def _report(self, done: int | None = None) -> None:
        if done is not None:
            self._n_done = done
        if self.progress is not None:
            self.progress(self._n_done, self.plan.n_planned, self.last_error)

    # ------------------------------------------------------------------ run
    def run(self) -> str:
        """Run every point not yet stored; returns the final status.

        ``completed`` (``incomplete`` with too many points skipped:
        :mod:`daq.completeness`), ``paused`` (protective stop, rejected command or retries
        exhausted), ``stopped`` (Ctrl-C / :meth:`request_stop`) or ``failed``
        (the finalize step failed).
        """
        store, rid = self.store, self.run_id
        store.set_status(rid, "running")
        self._t0 = time.monotonic()
        n_done = store.n_samples(rid)
        t = None
        log.info("run %d: %s, %d points planned, %d stored: executing the rest", rid,
                 self.plan.routine, self.plan.n_planned, n_done)
        self._drift = DriftWatch.of_run(self.plan, store.samples(rid)) if (
            self.plan.params.get("drift_check")) else None
        self._report(n_done)
        with stop_handlers(self._stop.set, self._stop.is_set, lambda: self._halting):
            try:
                for t in self._pending():
                    if self._stop.is_set():
                        raise _Pause("stopped", f"stopped by the operator before point {t.index}")
                    if self._point(t):
                        n_done += 1
                    self._report(n_done)
                    if self.enough is not None and (why := self.enough(
                            self.plan, store.samples(rid), store.run(rid))):
                        log.info("run %d: %s: ending here, %d points stored", rid, why,
                                 n_done)
                        break
            except _Pause as p:
                log.info("run %d %s: %s", rid, p.status, p.reason)
                kind = (InterruptionKind.SIGINT if p.status == RunStatus.STOPPED
                        else InterruptionKind.PAUSE)
                self._record_stop(getattr(t, "index", None), kind, p.status, p.reason)
                self.last_error = p.reason
                self._report(n_done)
                return p.status
            except StopNow as e:
                self.stop_signal = e.signum
                what = self._halt_robot()
                name = ("a second Ctrl-C" if e.signum == signal.SIGINT
                        else signal_name(e.signum))
                where = f"at point {t.index}" if t is not None else "before the first point"
                reason = (f"stopped at once by {name} {where}: {what}; resume with "
                          "`cellcal resume`")
                (log.error if "could NOT" in what else log.info)("run %d paused: %s", rid, reason)
                self._record_stop(getattr(t, "index", None), InterruptionKind.STOP_NOW,
                                  "paused", reason, summarise=False)
                self.last_error = reason
                self._report(n_done)
                return "paused"
            except StoreUnavailable as e:  # the store went away outside a commit
                reason = (f"run store unreachable at point {getattr(t, 'index', None)}: {e}; "
                          "`cellcal resume` once it is back")
                log.info("run %d paused: %s", rid, reason)
                self._record_stop(getattr(t, "index", None), InterruptionKind.STORE, "paused",
                                  reason)
                self.last_error = reason
                self._report(n_done)
                return "paused"
            except BaseException as e:
                log.info("run %d failed at point %s: %s: %s", rid, getattr(t, "index", None),
                         type(e).__name__, e)
                store.add_interruption(rid, getattr(t, "index", None), InterruptionKind.ERROR,
                                       f"{type(e).__name__}: {e}")
                store.set_status(rid, "failed", f"{type(e).__name__}: {e}")
                raise
        if self.finalize is not None:
            try:
                extra = self.finalize(self.plan, store.samples(rid), store.run(rid)) or {}
                store.update_run(rid, **extra)
            except (ValueError, np.linalg.LinAlgError) as e:
                log.info("run %d failed: finalize: %s", rid, e)
                store.add_interruption(rid, None, InterruptionKind.FINALIZE, str(e))
                self._summarise()
                store.set_status(rid, "failed", f"finalize: {e}")
                return "failed"
        self._summarise()
        status, reason = end_status(self.plan, store.done_indices(rid), self._skipped())
        store.set_status(rid, status, reason)
        log.info("run %d %s%s", rid, status, f": {reason}" if reason else "")
        return str(status)

    # ------------------------------------------------------- skips and spares
    def _skipped(self) -> set[int]:
        return {i.point_index for i in self.store.interruptions(self.run_id)
                if i.kind == InterruptionKind.SKIPPED}

    def _pending(self):
        """The points to do: those neither stored nor skipped, then spares while fewer
        spares are stored than points were skipped (re-read after every point)."""
        done, skipped = self.store.done_indices(self.run_id), self._skipped()
        for t in self.plan.targets:
            if not t.spare and t.index not in done and t.index not in skipped:
                yield t
        for t in self.plan.targets:
            if not t.spare:
                continue
            done, skipped = self.store.done_indices(self.run_id), self._skipped()
            if t.index in done or t.index in skipped:
                continue
            owed = sum(not self.plan.targets[i].spare for i in skipped)
            if sum(self.plan.targets[i].spare for i in done) >= owed:
                return
            yield t

    def _summarise(self) -> None:
        """The run's summary: beam breaks, skipped points, spares measured, capture time."""
        rid = self.run_id
        kinds = [(i.point_index, i.kind) for i in self.store.interruptions(rid)]
        done = self.store.done_indices(rid)
        summary = self.store.run(rid).summary or RunSummary()
        session = time.monotonic() - self._t0
        self._t0 = time.monotonic()
        summary.beam_breaks = sum(k == InterruptionKind.BEAM for _, k in kinds)
        summary.skipped_points = sorted({p for p, k in kinds if k == InterruptionKind.SKIPPED})
        summary.spares_measured = sum(self.plan.targets[i].spare for i in done)
        summary.capture_s = round(float(summary.capture_s or 0.0) + session, 3)
        self.store.update_run(rid, summary=summary)

    # ---------------------------------------------------------------- point
    def _point(self, t: Target) -> bool:
        """Acquire and store point ``t``; False when it was skipped (its beam stayed broken)."""
        attempt = beams = 0
        while True:
            attempt += 1
            phase = ["robot"]
            log.info("point %d (%s, set %s): attempt %d", t.index, t.label, t.set, attempt)
            try:
                sample = self._acquire(t, attempt, phase)
                rejected, revisited, settled = (), (), None
                if self.remeasure is not None:
                    at_target, self._last_cmd_q = self._last_cmd_q, None  # moved: read again
                    settled = self.remeasure.settle(t, sample, PointContext(self, phase, t))
                    sample, rejected, revisited = (settled.sample, settled.rejected,
                                                   settled.revisited)
                    if not revisited:  # a re-measurement ends at the target
                        self._last_cmd_q = at_target
                stored = self._commit(t, sample, rejected, revisited)
                if stored and self.remeasure is not None:
                    self.remeasure.committed(settled)
                if stored and t.set == DRIFT_SET and self._drift is not None:
                    self._drift.observe(t, sample.tracker_p_smr, sample.std_mm)
                return True
            except ProtectiveStop as e:
                self._fault(t, e)
                raise _Pause("paused", f"protective stop at point {t.index}: {e}; clear it at "
                             "the controller, then `cellcal resume`") from e
            except (DriverError, CaptureError) as e:
                self._fault(t, e)
                beams += isinstance(e, BeamBroken)
                if beams > BEAM_RETRIES and t.move != "zero":
                    log.info("point %d (%s) skipped: the beam broke %d times; a spare is "
                             "measured in its place if the plan has one", t.index, t.label,
                             beams)
                    self.store.add_interruption(
                        self.run_id, t.index, InterruptionKind.SKIPPED,
                        f"point {t.index} ({t.label}) skipped: the beam broke {beams} times, "
                        f"last: {e}")
                    return False
                if not e.transient:
                    raise _Pause("paused", f"{fault_kind(e)} at point {t.index}: {e}") from e
                if attempt > self.o.max_retries:
                    raise _Pause("paused", f"point {t.index}: {attempt} attempts failed, last: "
                                 f"{fault_kind(e)}: {e}") from e
                wait = min(self.o.backoff_s * 2 ** (attempt - 1), self.o.backoff_max_s)
                log.info("point %d: retrying in %.2f s after reconnecting the %s (attempt %d "
                         "of %d)", t.index, wait, phase[0], attempt + 1, self.o.max_retries + 1)
                time.sleep(wait)
                self._reconnect(t, phase[0])

    def _commit(self, t: Target, sample: Sample, rejected=(), revisited=()) -> bool:
        """Store the point's sample (with the readings the re-measure policy did not
        accept and the earlier points it re-measured: :meth:`RunStore.add_sample`); a lost
        store is waited for (module docstring), unless the operator asks to stop (the
        point is then redone on resume). True when the sample is stored (by this commit or
        by the one the lost connection interrupted)."""
        attempt, lost, t_lost = 0, None, 0.0
        while True:
            try:
                if lost is not None:
                    self.store.reconnect()
                t0 = time.perf_counter()
                stored = self.store.add_sample(self.run_id, sample, rejected, revisited)
                self.commit_s += time.perf_counter() - t0
                self.n_committed += 1
                log.info("point %d (%s) stored: %s, std %.4f mm, %d attempt(s)%s%s%s",
                         t.index, t.label, _Shown(sample.tracker_p_smr, "mm"),
                         float(np.max(sample.std_mm)), sample.attempts,
                         f", verdict {sample.verdict}" if sample.verdict else "",
                         f", {len(rejected)} reading(s) rejected" if rejected else "",
                         f", {len(revisited)} warm-up point(s) revisited" if revisited else "")
                break
            except StoreFull as e:  # a full disk: nothing was stored
                self.store.release_reserve()  # room to record the pause and why
                raise _Pause("paused", f"the run store could not be written at point "
                             f"{t.index}: {e}; free space, then `cellcal resume`") from e
            except StoreUnavailable as e:
                if lost is None:
                    lost, t_lost = e, time.monotonic()
                    self.n_faults += 1
                    log.info("point %d: run store unreachable: %s; holding the robot and the "
                             "sample, reconnecting for up to %.0f s", t.index, e,
                             self.o.store_wait_s)
                self.last_error = f"store: {e}"
                self._report()
                waited = time.monotonic() - t_lost
                if self._stop.is_set():
                    raise _Pause("stopped", f"stopped by the operator while waiting for the "
                                 f"run store at point {t.index}") from e
                if waited >= self.o.store_wait_s:
                    raise _Pause("paused", f"run store unreachable at point {t.index} for "
                                 f"{waited:.0f} s: {e}; `cellcal resume` once it is back"
                                 ) from e
                attempt += 1
                time.sleep(min(self.o.backoff_s * 2 ** (attempt - 1), self.o.backoff_max_s,
                               self.o.store_wait_s - waited))
        if lost is not None:
            log.info("point %d: run store back after %.1f s, sample committed", t.index,
                     time.monotonic() - t_lost)
            self.store.add_interruption(self.run_id, t.index, InterruptionKind.STORE,
                                        f"connection lost for {time.monotonic() - t_lost:.1f} "
                                        f"s, point kept and committed after reconnecting: "
                                        f"{lost}")
            self.last_error = None
            # the point is not stored twice: an insert skipped after a lost connection is
            # this very sample, stored by the commit the connection broke during
            stored = True
        return stored

    def _record_stop(self, index, kind: InterruptionKind, status: str, reason: str, *,
                     summarise: bool = True) -> None:
        """Record why the run stopped and its status; when the store is away (the reason
        it stopped, perhaps) one reconnection is tried, then the record is left out: the
        run stays ``running`` in the store and ``cellcal resume`` finds it so. ``summarise``:
        update the run's summary first (:meth:`_summarise`)."""
        for retry in (False, True):
            try:
                if retry:
                    self.store.reconnect()
                with contextlib.suppress(StoreFull):  # a full disk: the status first
                    self.store.add_interruption(self.run_id, index, kind, reason)
                if summarise:
                    with contextlib.suppress(StoreFull):
                        self._summarise()
                self.store.set_status(self.run_id, status, reason)
                return
            except StoreUnavailable:
                continue

    def _fault(self, t: Target, e: DriverError | CaptureError) -> None:
        self.n_faults += 1
        self.last_error = f"{fault_kind(e)}: {e}"
        log.info("point %d (%s): %s: %s", t.index, t.label, fault_kind(e), e)
        self.store.add_interruption(self.run_id, t.index, fault_kind(e), str(e))
        self._report(self.store.n_samples(self.run_id))

    def _reconnect(self, t: Target, which: str) -> None:
        dev = self.robot if which == "robot" else self.tracker
        log.info("point %d: reconnecting the %s", t.index, which)
        try:
            dev.close()
            dev.connect(timeout=self.o.connect_timeout_s)
        except DriverError as e:  # counted as one more failed attempt by the caller's loop
            log.info("point %d: reconnecting the %s failed: %s", t.index, which, e)
            self.store.add_interruption(self.run_id, t.index, InterruptionKind.RECONNECT, str(e))
            self.last_error = f"reconnect {which}: {e}"
        if which == "robot":
            self._last_cmd_q = None  # the controller may have moved on: read again
            self._q_now = None
            self._entry = True

    # -------------------------------------------------------------- actions
    def _where(self) -> str:
        t = self._target
        return "" if t is None else f"point {t.index} ({t.label})"

    def _refuse(self, problems: list[str], move: str) -> None:
        if problems:
            log.warning("%s: %s refused by the motion guard: %s", self._where() or "run",
                        move, "; ".join(problems))
            raise MotionRefused(f"robot {getattr(self.robot, 'url', '')}", self._where(),
                                f"{move} refused: " + "; ".join(problems))

    def _mismatch(self, problems: list[str], after: str) -> None:
        if problems:
            log.warning("%s: the robot is not where it was sent (%s): %s",
                        self._where() or "run", after, "; ".join(problems))
            raise MotionMismatch(f"robot {getattr(self.robot, 'url', '')}", self._where(),
                                 f"{after}: " + "; ".join(problems))

    def _move_joints(self, q, phase, *, adaptive: bool = False) -> JointReading:
        """Checked joint move to ``q``, settled and read back (the reading)."""
        o, t = self.o, self._target
        q = np.asarray(q, float)
        planned = None if t is None or t.q is None else np.asarray(t.q, float)
        self._refuse(self.guard.check_joint_move(self._q_now, q, planned=planned,
                                                 adaptive=adaptive), "joint move")
        phase[0] = "robot"
        self._q_now = None  # moving: unknown until read back
        log.info("%s: %sjoint move to %s", self._where() or "run", "adaptive " if adaptive else "",
                 _Shown(q))
        self.robot.move_joints(q, speed=o.speed_rad_s, timeout=o.move_timeout_s)
        jr = self._read_q(phase)
        self._mismatch(self.guard.check_arrival(jr.q, q_cmd=q), "after the joint move")
        return jr

    def _move_linear(self, xyz, phase, planned=None) -> JointReading:
        """Checked linear move to ``xyz``, settled and read back (the reading)."""
        o = self.o
        xyz = np.asarray(xyz, float)
        self._refuse(self.guard.check_linear_move(self._q_now, xyz, planned=planned),
                     "linear move")
        phase[0] = "robot"
        self._q_now = None
        log.info("%s: linear move to %s", self._where() or "run", _Shown(xyz, "mm"))
        self.robot.move_linear(xyz, speed=o.speed_mm_s, timeout=o.move_timeout_s)
        jr = self._read_q(phase)
        self._mismatch(self.guard.check_arrival(jr.q, xyz=xyz, planned=planned),
                       "after the linear move")
        return jr

    def _read_q(self, phase) -> JointReading:
        phase[0] = "robot"
        jr = self.robot.read_joints(timeout=self.o.io_timeout_s)
        self._q_now = np.asarray(jr.q, float)
        return jr

    def _measure(self, phase):
        """An averaged measurement whose per-axis std is within the threshold, newer than
        the previous one."""
        o = self.o
        phase[0] = "tracker"
        worst = None
        dev = f"tracker {getattr(self.tracker, 'url', '')}"
        for _ in range(max(1, o.max_remeasure)):
            measure = self.tracker.measure_pose if o.six_dof else self.tracker.measure
            m = measure(duration_s=o.measure_s, timeout=o.measure_timeout_s)
            last, self._last_meas = self._last_meas, m
            if last is not None and (m.timestamp <= last.timestamp or (
                    np.array_equal(m.xyz, last.xyz) and np.array_equal(m.std, last.std))):
                log.info("%s: the tracker's reply is not newer than the previous one",
                         self._where() or "run")
                raise StaleMeasurement(dev, "measure", (
                    f"the reply is not newer than the previous one (t {m.timestamp:.6f} after "
                    f"{last.timestamp:.6f}, xyz {np.round(m.xyz, 5).tolist()}): a repeated "
                    "reply?"))
            worst = float(np.max(m.std))
            if worst <= o.max_std_mm:
                return m
            log.info("%s: std %.4f mm above %g mm: measuring again", self._where() or "run",
                     worst, o.max_std_mm)
        raise QualityError(dev, "measure", f"std {worst:.4f} mm above {o.max_std_mm} mm after "
                           f"{o.max_remeasure} measurements")

    def _entry_move(self, t: Target, phase) -> JointReading | None:
        """A joint move to a linear target's planned posture (where the plan's linear
        chain starts from); None for other targets."""
        if t.move == "linear" and t.q is not None:
            return self._move_joints(t.q, phase)
        return None

    def _via_move(self, t: Target, phase) -> np.ndarray | None:
        """The plan's move to ``t``'s pre-position; the joints the approach to the target
        starts from (commanded; read after a linear via), None without a via."""
        if t.via is None:
            return None
        if t.move == "linear":
            self._move_linear(t.via, phase)
            return self._q_now
        self._move_joints(t.via, phase)
        return np.asarray(t.via, float)

    def _target_move(self, t: Target, phase) -> JointReading:
        if t.move == "linear":
            return self._move_linear(t.base_p_tcp, phase, planned=t.q)
        return self._move_joints(t.q, phase)

    def _dwell(self, jr: JointReading, phase) -> JointReading:
        """The optional dwell after a move; the joints read after it must not have moved."""
        if self.o.dwell_s <= 0:
            return jr
        time.sleep(self.o.dwell_s)
        after = self._read_q(phase)
        self._mismatch(self.guard.check_arrival(after.q, q_cmd=jr.q), "during the dwell")
        return after

    def _held(self, jr: JointReading, phase) -> None:
        """The joints read back after a measurement must still be ``jr``'s."""
        after = self._read_q(phase)
        self._mismatch(self.guard.check_arrival(after.q, q_cmd=jr.q),
                       "the robot moved during the measurement")

    def _acquire(self, t: Target, attempt: int, phase) -> Sample:
        o = self.o
        self._target = t
        if self._q_now is None:
            self._read_q(phase)
        if self._entry:
            self._entry_move(t, phase)
        if self._last_cmd_q is None:
            self._last_cmd_q = self._q_now
        self._entry = False
        if t.via is not None:
            self._last_cmd_q = self._via_move(t, phase)
        prev = self._last_cmd_q
        jr = self._dwell(self._target_move(t, phase), phase)
        m = None
        if self.acquisition is not None:
            jr, m = self.acquisition.acquire(t, PointContext(self, phase, t))
        elif t.move == "zero":
            raise ValueError(f"point {t.index}: a zero target needs its routine's acquisition "
                             "(zero20's closed loop)")
        cmd_q = np.asarray(t.q, float) if t.move == "joints" else jr.q
        dirs = approach_dirs(prev, cmd_q, o.dir_deadband_rad)
        cmd = None
        if isinstance(self.robot, CommandedPosition):
            cmd = np.asarray(self.robot.read_tcp(timeout=o.io_timeout_s), float)
        if m is None:
            m = self._measure(phase)
        self._held(jr, phase)
        self._last_cmd_q = cmd_q
        env = m.env or {}
        joint_temp = self._joint_temperatures()
        return Sample(
            point_index=t.index, q=jr.q, tracker_p_smr=m.xyz, std_mm=m.std, n_averaged=m.n,
            t_s=m.timestamp, pose_id=t.label, set_name=t.set, target=t.to_dict(),
            temp_c=env.get("temp_c"), pressure_hpa=env.get("pressure_hpa"),
            humidity_pct=env.get("humidity_pct"), cmd=cmd, dirs=dirs,
            attempts=attempt, joints_t=jr.timestamp, reflector=m.reflector or None,
            face=m.face or None, cov_mm2=m.cov, joint_temp=joint_temp,
            quat=getattr(m, "quat", None), sigma_deg=getattr(m, "sigma_deg", None),
        )

    def _joint_temperatures(self) -> np.ndarray | None:
        """The joints' temperatures (°C) where the robot reports them; a controller that
        refuses the request (:class:`~drivers.errors.CommandRejected`) has none and is not
        asked again."""
        if not self._temps:
            return None
        try:
            return np.asarray(self.robot.joint_temperatures(timeout=self.o.io_timeout_s), float)
        except CommandRejected:
            log.info("the robot reports no joint temperatures: not asked again")
            self._temps = False
            return None
