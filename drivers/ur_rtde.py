"""Universal Robots over ur-rtde: :class:`UrRtdeRobot` (RobotDriver + CommandedPosition).

ur-rtde speaks metres and radians and reports trouble by returning ``False``
or by quietly serving stale values; this adapter converts units at the edge
(mm and rad above it) and turns every quirk into a typed error:

========================================  =============================================
ur-rtde behaviour                         raised here
========================================  =============================================
``moveJ``/``moveL`` return ``False``,     :class:`ProtectiveStop` (protective, safeguard
safety bits show a stop                   or emergency stop, fault, violation)
``False``, safety normal, control         :class:`CommandRejected` (the script died on a
script no longer running                  bad target; it is re-uploaded on the next move)
``False`` otherwise                       :class:`CommandRejected`
``isConnected()`` false on either side    :class:`ConnectionLost`
``getTimestamp()`` stops advancing        :class:`ConnectionLost` (getters keep returning
                                          the last values after the link dies)
robot mode not RUNNING                    :class:`NotReady`
``RuntimeError`` from the C++ layer       :class:`ConnectionLost` / :class:`CommandRejected`
no arrival within ``timeout``             :class:`CommandTimeout` (after ``stopJ``)
========================================  =============================================

Moves are sent asynchronously (``asynchronous=True``) and then watched on the
receive side, so every call honours its ``timeout`` (a blocking ``moveJ``
cannot be interrupted from Python). Safety status bits, robot modes and
runtime states follow UR's RTDE guide.

Size: over 500 lines for one driver class, on purpose: each row of the table above is
handled beside the call it concerns, and split apart the quirks would read out of context.
"""

from __future__ import annotations

import contextlib
import logging
import math
import socket
import time
from collections.abc import Callable
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np
import numpy.typing as npt

from drivers.errors import (
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    LimitError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.protocols import DeviceIdentity, JointReading, RobotStatus

#: the ur-rtde calls with their arguments and results and the samples read, decoded, at
#: DEBUG (the polled predicates only when false); the connection and refusals at INFO
log = logging.getLogger(__name__)

RTDE_PORT = 30004
#: predicates polled in loops: logged only when they answer False
_POLLED = frozenset({"isConnected", "isProgramRunning", "isSteady"})

#: what the receive interface is asked to stream
RECEIVE_VARIABLES = [
    "timestamp", "actual_q", "actual_qd", "target_q", "actual_TCP_pose", "robot_mode",
    "safety_mode", "safety_status_bits", "runtime_state", "robot_status_bits",
    "joint_temperatures",
]

# safety_status_bits (RTDE guide)
BIT_NORMAL, BIT_REDUCED, BIT_PROTECTIVE, BIT_RECOVERY = 0, 1, 2, 3
BIT_SAFEGUARD, BIT_SYSTEM_ESTOP, BIT_ROBOT_ESTOP, BIT_ESTOP = 4, 5, 6, 7
BIT_VIOLATION, BIT_FAULT, BIT_STOPPED_BY_SAFETY = 8, 9, 10
ROBOT_MODES = {-1: "NO_CONTROLLER", 0: "DISCONNECTED", 1: "CONFIRM_SAFETY", 2: "BOOTING",
               3: "POWER_OFF", 4: "POWER_ON", 5: "IDLE", 6: "BACKDRIVE", 7: "RUNNING",
               8: "UPDATING_FIRMWARE"}
ROBOT_MODE_RUNNING = 7
RUNTIME_STATES = {0: "STOPPING", 1: "STOPPED", 2: "PLAYING", 3: "PAUSING", 4: "PAUSED",
                  5: "RESUMING"}


# the ur-rtde interfaces are an untyped library's objects: typed Any here
def _default_receive(host: str, frequency: float, variables: list[str]) -> Any:
    import rtde_receive

    return rtde_receive.RTDEReceiveInterface(host, frequency, variables)


def _default_control(host: str) -> Any:
    import rtde_control

    return rtde_control.RTDEControlInterface(host)


def _default_dashboard(host: str) -> Any:
    import dashboard_client

    return dashboard_client.DashboardClient(host)


class _State:
    """One fresh receive-side sample, in our units (rad, mm)."""

    __slots__ = ("q", "qd", "target_q", "tcp_m", "bits", "safety_mode", "robot_mode",
                 "runtime", "rtde_time")
    q: np.ndarray
    qd: np.ndarray
    target_q: np.ndarray
    tcp_m: np.ndarray
    bits: int
    safety_mode: int
    robot_mode: int
    runtime: int
    rtde_time: float

    def __init__(self, **kw: Any) -> None:
        for k, v in kw.items():
            setattr(self, k, v)

    @property
    def tcp_mm(self) -> np.ndarray:
        return np.asarray(self.tcp_m[:3], float) * 1000.0

    def __str__(self) -> str:
        """The sample in one line (the log's: formatted only when a record is written)."""
        return (f"t={self.rtde_time:.3f} q={np.round(self.q, 6).tolist()} rad "
                f"qd_max={float(np.max(np.abs(self.qd), initial=0.0)):.2g} "
                f"tcp={np.round(self.tcp_mm, 3).tolist()} mm robot_mode="
                f"{ROBOT_MODES.get(self.robot_mode, self.robot_mode)} safety_mode="
                f"{self.safety_mode} bits=0x{self.bits:03x} "
                f"runtime={RUNTIME_STATES.get(self.runtime, self.runtime)}")

    def bit(self, i: int) -> bool:
        return bool((self.bits >> i) & 1)

    @property
    def protective_stop(self) -> bool:
        return self.bit(BIT_PROTECTIVE) or self.bit(BIT_SAFEGUARD)

    @property
    def emergency_stop(self) -> bool:
        return self.bit(BIT_ESTOP) or self.bit(BIT_ROBOT_ESTOP) or self.bit(BIT_SYSTEM_ESTOP)

    @property
    def fault(self) -> bool:
        return self.bit(BIT_FAULT) or self.bit(BIT_VIOLATION)

    def stop_reason(self) -> str:
        """Why the robot is stopped by its safety system, or ``""``."""
        names = [n for i, n in ((BIT_PROTECTIVE, "protective stop"),
                                (BIT_SAFEGUARD, "safeguard stop"),
                                (BIT_SYSTEM_ESTOP, "system emergency stop"),
                                (BIT_ROBOT_ESTOP, "robot emergency stop"),
                                (BIT_ESTOP, "emergency stop"), (BIT_VIOLATION, "violation"),
                                (BIT_FAULT, "fault")) if self.bit(i)]
        if not names:
            return ""
        return (f"{', '.join(names)} (safety mode {self.safety_mode}, "
                f"safety status bits 0x{self.bits:03x})")


class UrRtdeRobot:
    """A UR robot driven through ur-rtde; joints in rad, positions in mm.

    Parameters
    ----------
    url : str
        ``ur://host[?frequency=500&joints=6&read_only=1&stale=0.25]``; see :meth:`from_url`.
    host : str
        Controller address (the RTDE port is always 30004).
    control_factory : callable, optional
        ``control_factory(host)`` -> an ``RTDEControlInterface``-like object
        (default ``rtde_control.RTDEControlInterface``; inject
        ``sim_drivers.fake_rtde_control.FakeRTDEControl`` for the simulator).
    receive_factory : callable, optional
        ``receive_factory(host, frequency, variables)`` -> an
        ``RTDEReceiveInterface``-like object (default ``rtde_receive.RTDEReceiveInterface``).
    dashboard_factory : callable, optional
        ``dashboard_factory(host)`` -> a ``DashboardClient``-like object, asked for the
        robot's model, serial number and PolyScope version by :meth:`identify` (default
        ur-rtde's ``dashboard_client.DashboardClient``, port 29999).
    frequency : float
        Receive streaming frequency, Hz; -1 lets ur-rtde choose (125 CB3, 500 e-Series).
    n_joints : int
        Joints exposed above the driver (a UR has 6; fewer drops the trailing ones and pads
        commands with zeros, for simulated arms).
    read_only : bool
        Connect the receive side only; moves and stops raise :class:`NotReady`.
    limits : array-like, shape (n_joints, 2), optional
        Joint limits (rad) checked before any move (:class:`LimitError`).
    acceleration : float
        Joint acceleration for ``moveJ`` (rad/s²).
    linear_acceleration : float
        Tool acceleration for ``moveL`` (mm/s²).
    joint_tol : float
        In-position tolerance per joint (rad).
    tcp_tol : float
        In-position tolerance of the TCP after a linear move (mm).
    velocity_tol : float
        Largest joint speed (rad/s) that still counts as standing still.
    stale_after : float
        Seconds without a new controller timestamp after which the link counts as lost.
    auto_reupload : bool
        Re-upload the control script before a move when it is not running (it stops
        after every protective stop) and the robot is otherwise ready.
    """

    def __init__(
        self,
        url: str,
        host: str,
        *,
        control_factory: Callable | None = None,
        receive_factory: Callable | None = None,
        dashboard_factory: Callable | None = None,
        frequency: float = -1.0,
        n_joints: int = 6,
        read_only: bool = False,
        limits: npt.ArrayLike | None = None,
        acceleration: float = 1.4,
        linear_acceleration: float = 1200.0,
        joint_tol: float = 1e-3,
        tcp_tol: float = 0.1,
        velocity_tol: float = 1e-3,
        stale_after: float = 0.25,
        auto_reupload: bool = True,
    ) -> None:
        if not 1 <= n_joints <= 6:
            raise ValueError(f"n_joints must be 1..6, got {n_joints}")
        self.url = url
        self.host = host
        self.control_factory = control_factory or _default_control
        self.receive_factory = receive_factory or _default_receive
        self.dashboard_factory = dashboard_factory or _default_dashboard
        self.frequency = float(frequency)
        self.n_joints = int(n_joints)
        self.read_only = bool(read_only)
        self.limits = None if limits is None else np.asarray(limits, float)
        if self.limits is not None and self.limits.shape != (self.n_joints, 2):
            raise ValueError(f"limits must have shape ({self.n_joints}, 2)")
        self.acceleration = float(acceleration)
        self.linear_acceleration = float(linear_acceleration)
        self.joint_tol = float(joint_tol)
        self.tcp_tol = float(tcp_tol)
        self.velocity_tol = float(velocity_tol)
        self.stale_after = float(stale_after)
        self.auto_reupload = bool(auto_reupload)
        self.poll_s = 0.002
        self.refusal_grace_s = 0.2
        self._rx: Any = None
        self._ctrl: Any = None
        self._last_ts: float | None = None
        self._last_ts_seen = 0.0
        self._target_q: np.ndarray | None = None
        self._target_tcp: np.ndarray | None = None

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> UrRtdeRobot:
        """Build a driver from ``ur://host[?frequency=..&joints=..&read_only=1&stale=..]``.

        Keyword arguments override the query (and pass factories through).
        """
        parts = urlsplit(url)
        if parts.scheme != "ur" or not parts.hostname:
            raise ValueError(f"bad UR URL {url!r}: expected ur://host")
        if parts.port not in (None, RTDE_PORT):
            raise ValueError(f"bad UR URL {url!r}: ur-rtde always uses port {RTDE_PORT}")
        q = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        opts: dict = {}
        try:
            if "frequency" in q:
                opts["frequency"] = float(q["frequency"])
            if "joints" in q:
                opts["n_joints"] = int(q["joints"])
            if "stale" in q:
                opts["stale_after"] = float(q["stale"])
        except ValueError as e:
            raise ValueError(f"bad UR URL {url!r}: {e}") from None
        if "read_only" in q:
            opts["read_only"] = q["read_only"].lower() in ("1", "true", "yes")
        opts.update(kw)
        return cls(url, parts.hostname, **opts)

    # -- connection ------------------------------------------------------------------------

    def connect(self, timeout: float = 5.0) -> None:
        """Open the receive (and unless read-only, control) interfaces; wait for fresh data.

        The port is probed first with ``timeout`` so a dead address fails fast; the
        ur-rtde constructors themselves cannot be interrupted.
        """
        deadline = time.monotonic() + timeout
        if self._rx is not None:
            return
        self._probe(timeout)
        try:
            self._rx = self.receive_factory(self.host, self.frequency, list(RECEIVE_VARIABLES))
        except RuntimeError as e:
            log.info("%s: RTDE receive: %s", self.url, e)
            raise ConnectionLost(self.url, "connect", f"RTDE receive: {e}") from e
        if not self.read_only:
            try:
                self._ctrl = self.control_factory(self.host)
            except RuntimeError as e:
                log.info("%s: RTDE control: %s", self.url, e)
                self.close()
                raise ConnectionLost(self.url, "connect", f"RTDE control: {e}") from e
        self._last_ts = None
        try:
            st = self._sample("connect", max(0.0, deadline - time.monotonic()))
        except DriverError:
            self.close()
            raise
        log.info("%s: connected (%s)", self.url, "receive only" if self.read_only
                 else "receive and control")
        log.debug("%s: < connect: %s", self.url, st)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """Model, serial number and PolyScope version from the dashboard server (RTDE
        itself does not say); unknown ("") when it cannot be reached. A PolyScope version
        naming ``cellcal sim`` declares a simulator."""
        model = serial = version = ""
        dash = None
        try:
            dash = self.dashboard_factory(self.host)
            dash.connect(int(max(timeout, 0.01) * 1000))
            model = str(dash.getRobotModel()).strip()
            serial = str(dash.getSerialNumber()).strip()
            version = str(dash.polyscopeVersion()).strip()
        except (ImportError, RuntimeError, OSError, TypeError) as e:
            log.info("%s: dashboard server: %s", self.url, e)
        finally:
            if dash is not None:
                with contextlib.suppress(RuntimeError, OSError, AttributeError):
                    dash.disconnect()
        log.debug("%s: < dashboard: model %r, serial %r, PolyScope %r", self.url, model,
                  serial, version)
        return DeviceIdentity("robot", model, serial, version,
                              simulator="cellcal sim" in version, n_joints=self.n_joints)

    def _probe(self, timeout: float) -> None:
        try:
            with socket.create_connection((self.host, RTDE_PORT), timeout=max(timeout, 0.01)):
                pass
        except OSError as e:
            log.info("%s: no RTDE server at port %d: %s", self.url, RTDE_PORT, e)
            raise ConnectionLost(self.url, "connect", f"no RTDE server at port {RTDE_PORT}: {e}") \
                from e

    def close(self) -> None:
        """Disconnect both interfaces (idempotent)."""
        ctrl, rx, self._ctrl, self._rx = self._ctrl, self._rx, None, None
        if ctrl is not None or rx is not None:
            log.info("%s: disconnected", self.url)
        for iface in (ctrl, rx):
            if iface is not None:
                with contextlib.suppress(RuntimeError):
                    iface.disconnect()

    def __enter__(self) -> UrRtdeRobot:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- reading ---------------------------------------------------------------------------

    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """Actual joint positions (rad, shape (n_joints,)) from ``getActualQ()``."""
        st = self._sample("getActualQ", timeout)
        log.debug("%s: < getActualQ: %s", self.url, st)
        return JointReading(q=st.q, timestamp=time.time())

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """The controller's TCP position (mm, base frame) from ``getActualTCPPose()``."""
        st = self._sample("getActualTCPPose", timeout)
        log.debug("%s: < getActualTCPPose: %s", self.url, st)
        return st.tcp_mm

    def joint_temperatures(self, timeout: float = 1.0) -> tuple[float, ...]:
        """Each joint's temperature (°C, n_joints values) from ``getJointTemperatures()``
        (the RTDE output ``joint_temperatures``), read from a fresh sample."""
        rx = self._receive("getJointTemperatures")
        self._sample("getJointTemperatures", timeout)
        try:
            temps = np.asarray(rx.getJointTemperatures(), float)[: self.n_joints]
        except RuntimeError as e:  # the recipe lacks the variable: the controller has none
            raise CommandRejected(self.url, "getJointTemperatures", f"RTDE receive: {e}") from e
        log.debug("%s: < getJointTemperatures: %s °C", self.url, temps)
        if temps.shape != (self.n_joints,) or not np.all(np.isfinite(temps)):
            raise ProtocolError(self.url, "getJointTemperatures",
                                f"expected {self.n_joints} temperatures, got {temps.tolist()}")
        return tuple(float(v) for v in temps)

    def status(self, timeout: float = 1.0) -> RobotStatus:
        """Controller state; ``error_code`` is the safety mode when it is not NORMAL (1)."""
        st = self._sample("status", timeout)
        log.debug("%s: < status: %s", self.url, st)
        moving = self._moving(st)
        reason = st.stop_reason()
        mode = ROBOT_MODES.get(st.robot_mode, str(st.robot_mode))
        message = reason or (f"robot mode {mode}, program {RUNTIME_STATES.get(st.runtime, '?')}")
        return RobotStatus(
            connected=True,
            moving=moving,
            in_position=not moving and self._in_position(st),
            fault=st.fault,
            protective_stop=st.protective_stop,
            emergency_stop=st.emergency_stop,
            error_code=0 if st.safety_mode == 1 else int(st.safety_mode),
            message=message,
            timestamp=time.time(),
        )

    def _receive(self, command: str) -> Any:
        if self._rx is None:
            raise ConnectionLost(self.url, command, "not connected (call connect() first)")
        return self._rx

    def _sample(self, command: str, timeout: float) -> _State:
        """The next sample with a new controller timestamp (waits at most one streaming period).

        If none arrives within ``timeout``, the last one is used when it is younger than
        ``stale_after``; otherwise, or when ``isConnected()`` is false, ConnectionLost.
        """
        rx = self._receive(command)
        deadline = time.monotonic() + timeout
        while True:
            try:
                if not rx.isConnected():
                    raise ConnectionLost(self.url, command, "RTDE receive link is down")
                ts = float(rx.getTimestamp())
            except RuntimeError as e:
                raise ConnectionLost(self.url, command, f"RTDE receive: {e}") from e
            now = time.monotonic()
            if ts != self._last_ts:  # a sample newer than any seen before: fresh
                self._last_ts, self._last_ts_seen = ts, now
                break
            if now >= deadline:
                if now - self._last_ts_seen <= self.stale_after:
                    break  # nothing newer within the timeout, but the last one is recent
                log.info("%s: %s: controller timestamp stuck at %.3f s (stale data)", self.url,
                         command, ts)
                raise ConnectionLost(
                    self.url, command,
                    f"controller timestamp stuck at {ts:.3f} s for {now - self._last_ts_seen:.2f} s"
                    " (stale data)")
            time.sleep(self.poll_s)
        try:
            n = self.n_joints
            return _State(
                q=np.asarray(rx.getActualQ(), float)[:n],
                qd=np.asarray(rx.getActualQd(), float)[:n],
                target_q=np.asarray(rx.getTargetQ(), float)[:n],
                tcp_m=np.asarray(rx.getActualTCPPose(), float),
                bits=int(rx.getSafetyStatusBits()),
                safety_mode=int(rx.getSafetyMode()),
                robot_mode=int(rx.getRobotMode()),
                runtime=int(rx.getRuntimeState()),
                rtde_time=ts,
            )
        except RuntimeError as e:
            raise ProtocolError(self.url, command, f"RTDE receive: {e}") from e

    def _moving(self, st: _State) -> bool:
        return bool(np.max(np.abs(st.qd), initial=0.0) > self.velocity_tol)

    def _in_position(self, st: _State) -> bool:
        if self._target_q is not None:
            return bool(np.max(np.abs(st.q - self._target_q)) <= self.joint_tol)
        if self._target_tcp is not None:
            return bool(np.linalg.norm(st.tcp_mm - self._target_tcp) <= self.tcp_tol)
        return bool(np.max(np.abs(st.q - st.target_q), initial=0.0) <= self.joint_tol)

    def _raise_if_stopped(self, st: _State, command: str) -> None:
        reason = st.stop_reason()
        if reason:
            log.info("%s: %s: %s", self.url, command, reason)
            raise ProtectiveStop(self.url, command, reason)

    # -- motion ----------------------------------------------------------------------------

    def move_joints(self, q: npt.ArrayLike, speed: float = 0.5, timeout: float = 60.0) -> None:
        """Joint move to ``q`` (rad); returns once arrived and settled (:meth:`wait_settled`'s
        condition). ``speed`` of the leading joint, rad/s."""
        deadline = time.monotonic() + timeout
        q = self._check_joints(q, "moveJ")
        _check_speed(self.url, "moveJ", speed)
        ctrl = self._ready("moveJ", deadline)
        wire = np.zeros(6)  # a UR has 6 joints; a smaller simulated arm ignores the padding
        wire[: self.n_joints] = q
        ok = self._call("moveJ", ctrl.moveJ, wire.tolist(), float(speed), self.acceleration, True)
        self._target_q, self._target_tcp = q, None
        if not ok:
            self._refused("moveJ", deadline)
        self._await_arrival("moveJ", deadline, ctrl)

    def move_linear(self, xyz: npt.ArrayLike, speed: float = 100.0, timeout: float = 60.0) -> None:
        """Linear TCP move to ``xyz`` (mm, base frame), orientation kept; ``speed`` in mm/s;
        returns once arrived and settled."""
        deadline = time.monotonic() + timeout
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
            raise CommandRejected(self.url, "moveL", f"expected finite x y z (mm), got {xyz}")
        _check_speed(self.url, "moveL", speed)
        ctrl = self._ready("moveL", deadline)
        pose = self._sample("moveL", max(0.0, deadline - time.monotonic())).tcp_m.copy()
        pose[:3] = xyz / 1000.0
        ok = self._call("moveL", ctrl.moveL, pose.tolist(), speed / 1000.0,
                        self.linear_acceleration / 1000.0, True)
        self._target_q, self._target_tcp = None, xyz
        if not ok:
            self._refused("moveL", deadline)
        self._await_arrival("moveL", deadline, ctrl)

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Return once in position, joint speeds ≈ 0 and (control side) ``isSteady()``."""
        deadline = time.monotonic() + timeout
        ctrl = self._ctrl
        streak = 0
        while True:
            st = self._sample("wait_settled", max(0.0, deadline - time.monotonic()))
            self._raise_if_stopped(st, "wait_settled")
            if self._settled(st, ctrl):
                streak += 1
                if streak >= 2:
                    return
            else:
                streak = 0
            if time.monotonic() >= deadline:
                raise CommandTimeout(self.url, "wait_settled",
                                     f"not settled within {timeout} s (q={st.q.round(5).tolist()})")
            time.sleep(self.poll_s)

    def stop(self, timeout: float = 2.0) -> None:
        """Decelerate to standstill (``stopJ``) and wait until the joints are still."""
        deadline = time.monotonic() + timeout
        ctrl = self._control("stopJ")
        self._call("stopJ", ctrl.stopJ, 2.0, False)
        self._target_q = self._target_tcp = None
        while True:
            st = self._sample("stopJ", max(0.0, deadline - time.monotonic()))
            if not self._moving(st):
                return
            if time.monotonic() >= deadline:
                raise CommandTimeout(self.url, "stopJ", f"still moving after {timeout} s")
            time.sleep(self.poll_s)

    # -- helpers ---------------------------------------------------------------------------

    def _check_joints(self, q: npt.ArrayLike, command: str) -> np.ndarray:
        q = np.asarray(q, float)
        if q.shape != (self.n_joints,) or not np.all(np.isfinite(q)):
            raise CommandRejected(self.url, command,
                                  f"expected {self.n_joints} finite joint values (rad), got {q}")
        if self.limits is not None:
            bad = np.nonzero((q < self.limits[:, 0]) | (q > self.limits[:, 1]))[0]
            if bad.size:
                raise LimitError(self.url, command,
                                 f"joint(s) {(bad + 1).tolist()} outside limits: {q.tolist()}")
        return q

    def _control(self, command: str) -> Any:
        if self.read_only:
            raise NotReady(self.url, command, "opened read-only (no RTDE control interface)")
        if self._ctrl is None:
            raise ConnectionLost(self.url, command, "not connected (call connect() first)")
        if not self._call("isConnected", self._ctrl.isConnected):
            raise ConnectionLost(self.url, command, "RTDE control link is down")
        return self._ctrl

    def _call(self, command: str, fn: Callable[..., Any], *args: Any) -> Any:
        polled = command in _POLLED
        if not polled and log.isEnabledFor(logging.DEBUG):
            log.debug("%s: > %s%s", self.url, command, _args(args))
        try:
            out = fn(*args)
        except RuntimeError as e:
            links = [i for i in (self._ctrl, self._rx) if i is not None]
            try:
                down = any(not i.isConnected() for i in links)
            except RuntimeError:
                down = True
            cls = ConnectionLost if down else CommandRejected
            log.info("%s: %s: ur-rtde: %s", self.url, command, e)
            raise cls(self.url, command, f"ur-rtde: {e}") from e
        if not polled or not out:
            log.debug("%s: < %s: %r", self.url, command, out)
        return out

    def _ready(self, command: str, deadline: float) -> Any:
        """The control interface, once the robot can take a move (or a typed error)."""
        ctrl = self._control(command)
        st = self._sample(command, max(0.0, deadline - time.monotonic()))
        self._raise_if_stopped(st, command)
        if st.robot_mode != ROBOT_MODE_RUNNING:
            mode = ROBOT_MODES.get(st.robot_mode, str(st.robot_mode))
            raise NotReady(self.url, command, f"robot mode {mode}, not RUNNING")
        if not self._call("isProgramRunning", ctrl.isProgramRunning):
            if not self.auto_reupload:
                raise NotReady(self.url, command, "RTDE control script is not running")
            log.info("%s: the RTDE control script is not running: uploading it again", self.url)
            self._call("reuploadScript", ctrl.reuploadScript)
            while not self._call("isProgramRunning", ctrl.isProgramRunning):
                if time.monotonic() >= deadline:
                    raise NotReady(self.url, command, "RTDE control script did not restart")
                time.sleep(self.poll_s)
        return ctrl

    def _refused(self, command: str, deadline: float) -> None:
        """``moveJ``/``moveL`` returned False: find out why and raise the matching error."""
        log.info("%s: %s refused (returned False or the script stopped)", self.url, command)
        end = min(deadline, time.monotonic() + self.refusal_grace_s)
        while True:
            if self._ctrl is not None and not self._call("isConnected", self._ctrl.isConnected):
                raise ConnectionLost(self.url, command, "RTDE control link is down")
            st = self._sample(command, max(0.0, deadline - time.monotonic()))
            self._raise_if_stopped(st, command)  # the receive side may lag by a cycle
            if time.monotonic() >= end:
                break
            time.sleep(self.poll_s)
        if self._ctrl is not None and not self._call("isProgramRunning",
                                                     self._ctrl.isProgramRunning):
            raise CommandRejected(self.url, command,
                                  "refused: the RTDE control script stopped (target unreachable "
                                  "or outside limits?)")
        raise CommandRejected(self.url, command, "refused by the controller (returned False)")

    def _settled(self, st: _State, ctrl: Any) -> bool:
        """In position, joint speeds ≈ 0 and (control side) ``isSteady()``."""
        steady = ctrl is None or self._call("isSteady", ctrl.isSteady)
        return bool(steady) and not self._moving(st) and self._in_position(st)

    def _await_arrival(self, command: str, deadline: float, ctrl: Any) -> None:
        """Until settled over two fresh samples (as :meth:`wait_settled`); a stop, a refusal
        (the script died) or the deadline (``stopJ`` first) raise."""
        streak = 0
        while True:
            st = self._sample(command, max(0.0, deadline - time.monotonic()))
            self._raise_if_stopped(st, command)
            if self._settled(st, ctrl):
                streak += 1
                if streak >= 2:
                    log.debug("%s: < %s arrived: %s", self.url, command, st)
                    return
            else:
                streak = 0
                if not self._call("isProgramRunning", ctrl.isProgramRunning):
                    self._refused(command, deadline)
            if time.monotonic() >= deadline:
                log.info("%s: %s: target not reached in time: stopping (%s)", self.url, command,
                         st)
                with contextlib.suppress(DriverError):
                    self._call("stopJ", ctrl.stopJ, 2.0, False)
                self._target_q = self._target_tcp = None  # stopped short: no target now
                raise CommandTimeout(self.url, command,
                                     "target not reached within timeout; robot stopped")
            time.sleep(self.poll_s)


def _args(args: tuple[Any, ...]) -> str:
    """A call's arguments as the log shows them (lists rounded)."""
    def one(a: Any) -> Any:
        return [round(float(v), 6) for v in a] if isinstance(a, list | tuple) else a
    return "(" + ", ".join(repr(one(a)) for a in args) + ")"


def _check_speed(url: str, command: str, speed: float) -> None:
    if not (math.isfinite(speed) and speed > 0):
        raise CommandRejected(url, command, f"speed must be > 0, got {speed}")
