"""The executor: runs a plan one point at a time and loses nothing.

For each target not yet in the store: move (via the pre-position if any) →
wait until settled (+ an optional dwell) → read the joints (and the
controller's nominal TCP when the robot offers :class:`CommandedPosition`) →
measure (averaged; a per-axis std above ``max_std_mm`` is remeasured) → write
one sample in one SQLite transaction. That commit is the checkpoint.

Faults
    * transient driver errors (``DriverError.transient``: beam break, timeout,
      dropped connection, garbage, device not ready) are recorded, then the
      point is retried after a backoff (doubling, capped) and a reconnection
      (close + connect) of the device that failed; after ``max_retries`` the
      run is paused;
    * a protective stop pauses the run (status ``paused``, the reason recorded
      and printed); an operator clears it, then ``cellcal resume``;
    * any other driver error (command rejected, limit) pauses the run too;
    * Ctrl-C (SIGINT) stops after the current point (status ``stopped``).

Every interruption goes to the store's ``interruptions`` table. A point whose
sample was not committed is simply done again on resume; the store's
``UNIQUE(run_id, point_index)`` makes a double write impossible.

Units: rad, mm, s.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from drivers.errors import (
    BeamBroken,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.protocols import CommandedPosition

from .plans import Plan, Target
from .store import RunStore, Sample


@dataclass
class ExecutorOptions:
    """Motion, measurement and retry settings (rad/s, mm/s, s, mm)."""

    speed_rad_s: float = 0.5
    speed_mm_s: float = 100.0
    move_timeout_s: float = 120.0
    io_timeout_s: float = 1.0
    connect_timeout_s: float = 5.0
    dwell_s: float = 0.0
    measure_s: float = 0.5
    measure_timeout_s: float = 10.0
    max_std_mm: float = 0.05
    max_remeasure: int = 3
    max_retries: int = 8
    backoff_s: float = 0.02
    backoff_max_s: float = 1.0
    zero_tol_mm: float = 0.01
    zero_max_iter: int = 25
    zero_damping_mm: float = 1.0
    #: size of the three probe moves that measure the tracker's orientation for the
    #: zero-point loop when the run has no measurement frame, mm
    zero_probe_mm: float = 5.0
    #: the loop also stops once the tip is within this many times the 3-D std of the
    #: measurement (a tolerance below the tracker's noise cannot be confirmed)
    zero_noise_k: float = 1.5
    #: tracker measurements averaged per step of the zero-point loop (their mean's std is
    #: taken as std/sqrt(n): independent measurements; a tracker whose noise is correlated
    #: over seconds gains less)
    zero_average: int = 1
    #: the loop stops only after a correction that moved the tip by at most this (mm):
    #: a large correction leaves a residual along its own direction (model Jacobian,
    #: tracker rotation: ~1 %) that is systematic, not noise, and would bias the offsets
    zero_confirm_step_mm: float = 0.5
    #: a joint moved by less than this (rad) approached with direction 0
    dir_deadband_rad: float = 1e-6
    extra: dict = field(default_factory=dict)


class QualityError(DriverError):
    """The tracker's std stayed above the threshold after the remeasurements."""

    transient = True


class _Pause(Exception):  # noqa: N818 - control flow
    def __init__(self, status: str, reason: str) -> None:
        self.status, self.reason = status, reason
        super().__init__(reason)


def fault_kind(e: BaseException) -> str:
    """Short name of a fault for the interruptions table."""
    for cls, name in ((ProtectiveStop, "protective_stop"), (BeamBroken, "beam"),
                      (QualityError, "quality"), (CommandTimeout, "timeout"),
                      (ConnectionLost, "connection"), (ProtocolError, "protocol"),
                      (NotReady, "not_ready")):
        if isinstance(e, cls):
            return name
    return "rejected" if isinstance(e, DriverError) else "error"


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


def tool_jacobian(model, q: np.ndarray) -> np.ndarray:
    """d(tool point)/dq of the nominal model at ``q`` (rad, (N,)): shape (3, N), mm/rad."""
    from calibration.kinematics import run_chain

    r = run_chain(model.convention, model.dh_table(), np.asarray(q, float)[None],
                  model.tool_mm(), jacobian=False, prismatic=model.prismatic_mask())
    return r.dP_dq[0]


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
    model : RobotModel, optional
        Needed by ``zero`` targets (closed-loop joint corrections).
    progress : callable(done, total, last_error), optional
        Called after every point and every fault.
    finalize : callable(plan, samples, run) -> dict, optional
        Called once every point is stored; may return ``frame`` and/or ``summary``
        dicts for the run.
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
        model=None,
        progress: Callable[[int, int, str | None], None] | None = None,
        finalize: Callable | None = None,
    ) -> None:
        run = store.run(run_id)
        if run.plan_hash != plan.hash:
            raise ValueError(f"run {run_id}: plan hash {plan.hash[:12]} differs from the stored "
                             f"{run.plan_hash[:12]}")
        self.store, self.run_id, self.plan = store, run_id, plan
        self.robot, self.tracker = robot, tracker
        self.o = options or ExecutorOptions()
        self.model = model
        self.progress = progress
        self.finalize = finalize
        self._stop = threading.Event()
        self._last_cmd_q: np.ndarray | None = None
        self.last_error: str | None = None
        self.n_faults = 0
        self.commit_s = 0.0
        self.n_committed = 0

    # -------------------------------------------------------------- control
    def request_stop(self) -> None:
        """Stop after the current point (what Ctrl-C does)."""
        self._stop.set()

    @contextlib.contextmanager
    def _sigint(self):
        if threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = signal.getsignal(signal.SIGINT)

        def handler(signum, frame):
            if self._stop.is_set():  # second Ctrl-C: stop now
                signal.signal(signal.SIGINT, previous)
                raise KeyboardInterrupt
            self._stop.set()

        signal.signal(signal.SIGINT, handler)
        try:
            yield
        finally:
            signal.signal(signal.SIGINT, previous)

    def _report(self, done: int) -> None:
        if self.progress is not None:
            self.progress(done, len(self.plan), self.last_error)

    # ------------------------------------------------------------------ run
    def run(self) -> str:
        """Run every point not yet stored; returns the final status.

        ``completed``, ``paused`` (protective stop, rejected command or retries
        exhausted), ``stopped`` (Ctrl-C / :meth:`request_stop`) or ``failed``
        (the finalize step failed).
        """
        store, rid = self.store, self.run_id
        done = store.done_indices(rid)
        pending = [t for t in self.plan.targets if t.index not in done]
        store.set_status(rid, "running")
        n_done = len(done)
        t = None
        self._report(n_done)
        with self._sigint():
            try:
                for t in pending:
                    if self._stop.is_set():
                        raise _Pause("stopped", f"stopped by the operator before point {t.index}")
                    self._point(t)
                    n_done += 1
                    self._report(n_done)
            except _Pause as p:
                kind = "sigint" if p.status == "stopped" else "pause"
                store.add_interruption(rid, getattr(t, "index", None), kind, p.reason)
                store.set_status(rid, p.status, p.reason)
                self.last_error = p.reason
                self._report(n_done)
                return p.status
            except KeyboardInterrupt:
                store.add_interruption(rid, getattr(t, "index", None), "sigint",
                                       "interrupted (second Ctrl-C)")
                store.set_status(rid, "stopped", "interrupted (second Ctrl-C)")
                raise
            except BaseException as e:
                store.add_interruption(rid, getattr(t, "index", None), "error",
                                       f"{type(e).__name__}: {e}")
                store.set_status(rid, "failed", f"{type(e).__name__}: {e}")
                raise
        if self.finalize is not None:
            try:
                extra = self.finalize(self.plan, store.samples(rid), store.run(rid)) or {}
                store.update_run(rid, **extra)
            except (ValueError, np.linalg.LinAlgError) as e:
                store.add_interruption(rid, None, "finalize", str(e))
                store.set_status(rid, "failed", f"finalize: {e}")
                return "failed"
        store.set_status(rid, "completed")
        return "completed"

    # ---------------------------------------------------------------- point
    def _point(self, t: Target) -> None:
        attempt = 0
        while True:
            attempt += 1
            phase = ["robot"]
            try:
                sample = self._acquire(t, attempt, phase)
                t0 = time.perf_counter()
                self.store.add_sample(self.run_id, sample)
                self.commit_s += time.perf_counter() - t0
                self.n_committed += 1
                return
            except ProtectiveStop as e:
                self._fault(t, e)
                raise _Pause("paused", f"protective stop at point {t.index}: {e}; clear it at "
                             "the controller, then `cellcal resume`") from e
            except DriverError as e:
                self._fault(t, e)
                if not e.transient:
                    raise _Pause("paused", f"{fault_kind(e)} at point {t.index}: {e}") from e
                if attempt > self.o.max_retries:
                    raise _Pause("paused", f"point {t.index}: {attempt} attempts failed, last: "
                                 f"{fault_kind(e)}: {e}") from e
                time.sleep(min(self.o.backoff_s * 2 ** (attempt - 1), self.o.backoff_max_s))
                self._reconnect(t, phase[0])

    def _fault(self, t: Target, e: DriverError) -> None:
        self.n_faults += 1
        self.last_error = f"{fault_kind(e)}: {e}"
        self.store.add_interruption(self.run_id, t.index, fault_kind(e), str(e))
        self._report(self.store.n_samples(self.run_id))

    def _reconnect(self, t: Target, which: str) -> None:
        dev = self.robot if which == "robot" else self.tracker
        try:
            dev.close()
            dev.connect(timeout=self.o.connect_timeout_s)
        except DriverError as e:  # counted as one more failed attempt by the caller's loop
            self.store.add_interruption(self.run_id, t.index, "reconnect", str(e))
            self.last_error = f"reconnect {which}: {e}"
        if which == "robot":
            self._last_cmd_q = None  # the controller may have moved on: read again

    # -------------------------------------------------------------- actions
    def _move_joints(self, q, phase) -> None:
        o = self.o
        phase[0] = "robot"
        self.robot.move_joints(np.asarray(q, float), speed=o.speed_rad_s,
                               timeout=o.move_timeout_s)
        self.robot.wait_settled(timeout=o.move_timeout_s)

    def _move_linear(self, xyz, phase) -> None:
        o = self.o
        phase[0] = "robot"
        self.robot.move_linear(np.asarray(xyz, float), speed=o.speed_mm_s,
                               timeout=o.move_timeout_s)
        self.robot.wait_settled(timeout=o.move_timeout_s)

    def _read_q(self, phase):
        phase[0] = "robot"
        return self.robot.read_joints(timeout=self.o.io_timeout_s)

    def _measure(self, phase):
        """An averaged measurement whose per-axis std is within the threshold."""
        o = self.o
        phase[0] = "tracker"
        worst = None
        for _ in range(max(1, o.max_remeasure)):
            m = self.tracker.measure(duration_s=o.measure_s, timeout=o.measure_timeout_s)
            worst = float(np.max(m.std))
            if worst <= o.max_std_mm:
                return m
        raise QualityError(f"tracker {getattr(self.tracker, 'url', '')}", "measure",
                           f"std {worst:.4f} mm above {o.max_std_mm} mm after "
                           f"{o.max_remeasure} measurements")

    def _measure_zero(self, phase):
        """The zero-point loop's measurement: the mean of ``zero_average`` measurements."""
        k = max(1, int(self.o.zero_average))
        ms = [self._measure(phase) for _ in range(k)]
        if k == 1:
            return ms[0]
        from dataclasses import replace

        std = np.sqrt(np.mean([m.std**2 for m in ms], axis=0) / k)
        return replace(ms[-1], xyz=np.mean([m.xyz for m in ms], axis=0), std=std,
                       n=int(sum(m.n for m in ms)))

    def _acquire(self, t: Target, attempt: int, phase) -> Sample:
        o = self.o
        if self._last_cmd_q is None:
            self._last_cmd_q = self._read_q(phase).q
        if t.via is not None:
            if t.move == "linear":
                self._move_linear(t.via, phase)
                self._last_cmd_q = self._read_q(phase).q
            else:
                self._move_joints(t.via, phase)
                self._last_cmd_q = np.asarray(t.via, float)
        prev = self._last_cmd_q
        if t.move == "linear":
            self._move_linear(t.xyz, phase)
        else:
            self._move_joints(t.q, phase)
        if o.dwell_s > 0:
            time.sleep(o.dwell_s)
        if t.move == "zero":
            jr, m = self._close_loop(t, phase)
        else:
            jr = self._read_q(phase)
            m = None
        cmd_q = np.asarray(t.q, float) if t.move == "joints" else jr.q
        step = cmd_q - prev
        dirs = np.where(np.abs(step) > o.dir_deadband_rad, np.sign(step), 0).astype(int)
        cmd = None
        if isinstance(self.robot, CommandedPosition):
            cmd = np.asarray(self.robot.read_tcp(timeout=o.io_timeout_s), float)
        if m is None:
            m = self._measure(phase)
        self._last_cmd_q = cmd_q
        env = m.env or {}
        return Sample(
            point_index=t.index, q=jr.q, xyz=m.xyz, std=m.std, n=m.n, t=m.timestamp,
            pose_id=t.label, set_name=t.set, target=t.to_dict(),
            temp_c=env.get("temp_c"), pressure_hpa=env.get("pressure_hpa"),
            humidity_pct=env.get("humidity_pct"), cmd=cmd, dirs=dirs, attempts=attempt,
            joints_t=jr.timestamp,
        )

    # ------------------------------------------------------- zero-point loop
    def _zero_target(self, m_xyz: np.ndarray) -> np.ndarray:
        """The zero-point target in the tracker frame: fixed by the first zero point."""
        run = self.store.run(self.run_id)
        summary = dict(run.summary or {})
        if "zero_target_tracker_mm" not in summary:
            summary["zero_target_tracker_mm"] = [float(v) for v in m_xyz]
            self.store.update_run(self.run_id, summary=summary)
        return np.asarray(summary["zero_target_tracker_mm"], float)

    def _zero_rotation(self, jr, m, phase):
        """Rotation tracker <- base (3x3) for the zero-point loop, and the current state.

        From the run's measurement frame (``options['tracker_R_base']``, from a frame
        run) when known; else from the run summary (``zero_tracker_R_base``, measured
        earlier in this run); else measured now: three probe moves of
        ``zero_probe_mm`` along the base axes (nominal model), their nominal tip
        displacements matched to the measured ones (Kabsch). The tracker may stand in
        any orientation: with a wrong rotation the corrections point the wrong way
        (the loop diverges beyond 90 degrees).

        Returns
        -------
        R : (3, 3) tracker_R_base
        jr, m : the joints read and the measurement at the robot's current position
        """
        run = self.store.run(self.run_id)
        if run.options.get("tracker_R_base") is not None:
            return np.asarray(run.options["tracker_R_base"], float), jr, m
        summary = dict(run.summary or {})
        if "zero_tracker_R_base" in summary:
            return np.asarray(summary["zero_tracker_R_base"], float), jr, m
        from calibration.inverse import ChainFK

        fk = ChainFK.from_model(self.model)
        q0 = np.asarray(jr.q, float)
        p0 = fk.point(q0[None])[0]
        m0 = np.asarray(m.xyz, float)
        A, B = [], []
        for k in range(3):
            dp = np.zeros(3)
            dp[k] = self.o.zero_probe_mm
            dq = np.linalg.lstsq(tool_jacobian(self.model, q0), dp, rcond=None)[0]
            self._move_joints(q0 + dq, phase)
            jr = self._read_q(phase)
            m = self._measure_zero(phase)
            A.append(fk.point(np.asarray(jr.q, float)[None])[0] - p0)
            B.append(np.asarray(m.xyz, float) - m0)
        R = kabsch_rotation(np.array(A), np.array(B))
        summary["zero_tracker_R_base"] = R.tolist()
        self.store.update_run(self.run_id, summary=summary)
        return R, jr, m

    def _close_loop(self, t: Target, phase):
        """Damped-least-squares joint corrections until the tool tip is on the target.

        The tool Jacobian comes from the nominal model (base frame), turned into the
        tracker frame with the run's frame rotation (:meth:`_zero_rotation`). The loop
        stops when the measured tip is within ``zero_tol_mm`` of the target, or within
        ``zero_noise_k`` times the measurement's own 3-D std when that is larger, and the
        last correction moved the tip by at most ``zero_confirm_step_mm`` (else one more
        correction: after a large one, the tip's residual error is systematic).
        """
        if self.model is None:
            raise ValueError("zero targets need the robot model")
        o = self.o
        jr = self._read_q(phase)
        m = self._measure_zero(phase)
        target = self._zero_target(m.xyz)
        R, jr, m = self._zero_rotation(jr, m, phase)
        lam2 = o.zero_damping_mm**2
        last_step = 0.0  # the tip motion of the last correction, mm
        for _ in range(o.zero_max_iter):
            e = target - m.xyz
            tol = max(o.zero_tol_mm, o.zero_noise_k * float(np.linalg.norm(m.std)))
            if float(np.linalg.norm(e)) <= tol and last_step <= o.zero_confirm_step_mm:
                return jr, m
            J = R @ tool_jacobian(self.model, jr.q)
            dq = J.T @ np.linalg.solve(J @ J.T + lam2 * np.eye(3), e)
            last_step = float(np.linalg.norm(J @ dq))
            self._move_joints(jr.q + dq, phase)
            jr = self._read_q(phase)
            m = self._measure_zero(phase)
        raise ZeroNotReached(f"robot {getattr(self.robot, 'url', '')}", "zero",
                             f"tip {np.linalg.norm(target - m.xyz):.4f} mm from the target after "
                             f"{o.zero_max_iter} corrections")


def kabsch_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R (3x3) minimising sum |R a_i - b_i|^2 (a, b: (n, 3) displacements, mm)."""
    U, _, Vt = np.linalg.svd(np.asarray(b, float).T @ np.asarray(a, float))
    d = np.sign(np.linalg.det(U @ Vt)) or 1.0
    return U @ np.diag([1.0, 1.0, d]) @ Vt


class ZeroNotReached(DriverError):
    """The closed loop did not bring the tool tip onto the zero-point target."""
