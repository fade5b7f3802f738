"""ABB IRC5 (RobotWare 6) over Robot Web Services 1.0: :class:`AbbRwsRobot`.

A RobotDriver with the CommandedPosition (the robtarget of the tool) and Identified
(serial number, RobotWare version, robot type) capabilities; not JointTemperatures: RWS
reports no motor or gearbox temperature (docs/abb.md). RWS has no call that moves the
robot: the RAPID server module ``drivers/abb/rapid/CellcalServer.mod``, running in the
controller's motion task, moves it to the targets this driver writes into its persistent
variables (the protocol: :mod:`drivers.abb.codec`, docs/abb.md).

==========================================  ============================================
the controller                              raised here
==========================================  ============================================
``ctrlstate`` guardstop, emergencystop,     :class:`ProtectiveStop` (before or during a
emergencystopreset                          move)
``ctrlstate`` motoroff or init, opmode not  :class:`NotReady` (moves only: reads go on)
AUTO, mastership held by another client
``ctrlstate`` sysfail                       :class:`CommandRejected`
the module refuses the target               :class:`LimitError` (LIMIT),
                                            :class:`CommandRejected` (UNREACHABLE...)
RAPID stops during a move                   :class:`CommandRejected` with the newest
                                            error of the event log
no acknowledgement within ``timeout``       :class:`CommandTimeout`, after RAPID's stop
HTTP 400/404 (a bad value, the module not   :class:`CommandRejected`
loaded), 401 (user or password)
HTTP 403/409/503                            :class:`NotReady`
refused, dropped or silent connection       :class:`ConnectionLost`, :class:`CommandTimeout`
==========================================  ============================================

The driver owns the robot while it is connected: it requests the mastership of the
controller's domains (RAPID, motion, configuration) on :meth:`connect` and releases it
on :meth:`close`, which the capture service calls on every error. A read that loses its
connection is asked once more; a move never is (a move's lost connection leaves the
driver closed until :meth:`connect`).

Size: over 300 lines on purpose: the move's protocol (ready, write, acknowledge, stop)
reads in one place.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Iterator
from typing import Any

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
from drivers.protocols import STOP_AFTER_TIMEOUT_S, DeviceIdentity, JointReading, RobotStatus
from drivers.settle import poll_until_settled, poll_until_still

from . import codec as C
from .link import RwsLink

log = logging.getLogger(__name__)

#: controller states that are a stop of the safety system, and what they are called
STOPS = {"guardstop": "guard stop (the safety circuit opened: a protective stop)",
         "emergencystop": "emergency stop", "emergencystopreset": "emergency stop (reset "
         "pending)"}
#: the shortest ``\T`` the driver gives MoveAbsJ (s)
MIN_MOVE_S = 0.05
#: status error codes of those states (the simulated cell's numbers)
STOP_CODES = {"guardstop": 30, "emergencystop": 31, "emergencystopreset": 31, "sysfail": 32}


class AbbRwsRobot:
    """An ABB robot through RWS 1.0 and the RAPID server module; joints in rad, mm.

    Parameters
    ----------
    url : str
        ``abb://[user:password@]host[:port][?joints=6&task=..&module=..&mechunit=..&tool=..
        &wobj=..&read_only=1]`` (:meth:`from_url`).
    host, port : str, int
    user, password : str
        RWS user (default the factory's ``Default User`` / ``robotics``).
    n_joints : int
        Robot axes used above the driver (an ABB arm has 6; fewer, for a simulated arm,
        uses the first ones and writes 0 for the others).
    task, module, mechunit : str
        Where the RAPID server module runs and which mechanical unit it moves.
    tool, wobj : str
        The tooldata and wobjdata of the robtarget read (:meth:`read_tcp`) and of MoveL.
    read_only : bool
        Read only: no mastership requested; moves and stops raise :class:`NotReady`.
    restart_rapid : bool
        Before a move, restart the module from its ``main`` when RAPID is stopped (after a
        protective stop the operator cleared, or :meth:`stop`), as the ur-rtde driver
        uploads its script again; else :class:`NotReady`.
    limits : array-like (n_joints, 2), optional
        Joint limits (rad) checked before a move; the module checks the controller's own
        (its MOC configuration) too.
    poll_s : float
        How often a move's acknowledgement and the status are polled (s; RWS is served at
        a low priority, so faster only loads the controller).
    """

    def __init__(self, url: str, host: str, port: int = C.DEFAULT_PORT, *,
                 user: str = C.DEFAULT_USER, password: str = C.DEFAULT_PASSWORD,
                 n_joints: int = 6, task: str = C.TASK, module: str = C.MODULE,
                 mechunit: str = C.MECHUNIT, tool: str = "tool0", wobj: str = "wobj0",
                 read_only: bool = False, restart_rapid: bool = True,
                 limits: npt.ArrayLike | None = None,
                 poll_s: float = 0.02) -> None:
        if not 1 <= n_joints <= 6:
            raise ValueError(f"n_joints must be 1..6, got {n_joints}")
        self.url = url
        self.n_joints = int(n_joints)
        self.task, self.module, self.mechunit = task, module, mechunit
        self.tool, self.wobj = tool, wobj
        self.read_only = bool(read_only)
        self.restart_rapid = bool(restart_rapid)
        self.limits = None if limits is None else np.asarray(limits, float)
        if self.limits is not None and self.limits.shape != (self.n_joints, 2):
            raise ValueError(f"limits must have shape ({self.n_joints}, 2)")
        self.poll_s = float(poll_s)
        self.model = self.serial = self.firmware = ""
        self._identity: DeviceIdentity | None = None
        self._link = RwsLink(url, host, port, user, password)
        self._connected = False
        self._master = False
        self._in_move = False  # a move's requests are never asked twice
        self._refused = ""  # why the last connect failed, until one succeeds

    @classmethod
    def from_url(cls, url: str, **kw: Any) -> AbbRwsRobot:
        """The driver of an ``abb://`` URL (query: ``joints``, ``task``, ``module``,
        ``mechunit``, ``tool``, ``wobj``, ``read_only``); keyword arguments override it."""
        from urllib.parse import unquote

        from drivers import url_parts as parts

        q = parts.query(url)
        host, port = parts.host_port(url, C.DEFAULT_PORT)
        split = parts.split(url)
        opts: dict = {"n_joints": parts.int_param(url, q, "joints", 6, 1, 6)}
        if split.username is not None:
            opts["user"] = unquote(split.username)
            opts["password"] = unquote(split.password or "")
        for name in ("task", "module", "mechunit", "tool", "wobj"):
            if name in q:
                if not q[name].replace("_", "").isalnum():
                    raise ValueError(f"bad URL {url!r}: {name} must be a RAPID name, "
                                     f"got {q[name]!r}")
                opts[name] = q[name]
        if "read_only" in q:
            opts["read_only"] = q["read_only"].lower() in ("1", "true", "yes")
        opts.update(kw)
        return cls(url, host, port, **opts)

    # -- requests ---------------------------------------------------------------------------

    def _request(self, method: str, path: str, form: dict | None, timeout: float,
                 command: str) -> dict | None:
        if not self._connected:
            why = f"; the last connect failed: {self._refused}" if self._refused else ""
            raise ConnectionLost(self.url, command, f"not connected (call connect() first{why})")
        status, doc = self._link.request(method, path, form, timeout=max(timeout, 0.01),
                                         command=command)
        if status < 400:
            return doc
        code, msg = C.status_of(doc)
        words = f"HTTP {status}" + (f", RWS {code}" if code else "") + (f": {msg}" if msg else "")
        log.info("robot %s: %s refused: %s", self.url, command, words)
        if status in (403, 409, 503):
            raise NotReady(self.url, command, words)
        if status in (400, 401, 404):
            raise CommandRejected(self.url, command, words)
        raise ProtocolError(self.url, command, words)

    def _get(self, path: str, timeout: float, command: str = "",
             retry: bool = False) -> dict | None:
        command = command or "GET " + path.split("?")[0]
        try:
            return self._request("GET", path, None, timeout, command)
        except ConnectionLost:
            if not retry or self._in_move or not self._connected:
                raise
            return self._request("GET", path, None, timeout, command)  # once more

    def _post(self, path: str, form: dict | None, timeout: float,
              command: str = "") -> dict | None:
        return self._request("POST", path, form or {}, timeout,
                             command or "POST " + path.split("?")[0])

    def _field(self, doc: dict | None, key: str, command: str) -> str:
        try:
            return C.field(doc, key)
        except KeyError as e:
            raise ProtocolError(self.url, command, f"answer without {key!r}: {doc}") from e

    def _symbol(self, name: str, timeout: float, retry: bool = False) -> str:
        path = C.symbol_path(self.task, self.module, name)
        return self._field(self._get(path, timeout, retry=retry), "value", f"GET {name}")

    def _num(self, name: str, timeout: float, retry: bool = False) -> float:
        text = self._symbol(name, timeout, retry)
        try:
            return C.parse_num(text)
        except ValueError as e:
            raise ProtocolError(self.url, f"GET {name}", str(e)) from e

    def _set(self, name: str, text: str, deadline: float) -> None:
        self._post(C.symbol_set_path(self.task, self.module, name), {"value": text},
                   _left(deadline), f"set {name}")

    # -- connection -------------------------------------------------------------------------

    def connect(self, timeout: float = 5.0) -> None:
        """Open the link, authenticate, take the mastership (unless read-only), check the
        server module is there and learn who the controller is. Connected already with
        the link open: nothing to do; a link lost since is opened again."""
        if self._connected and self._link.is_open:
            return
        deadline = time.monotonic() + timeout
        self._link.open(timeout)
        self._connected = True
        try:
            self._get(C.CTRLSTATE, _left(deadline), "connect")
            if not self.read_only:
                self._post(C.MASTERSHIP_REQUEST, None, _left(deadline), "request mastership")
                self._master = True
                try:
                    self._num(C.VAR_ACK, _left(deadline))  # the module is loaded
                except CommandRejected as e:
                    raise CommandRejected(self.url, "connect", f"{e.detail} (is the RAPID "
                                          f"module {self.module} loaded in task {self.task}? "
                                          "drivers/abb/rapid/CellcalServer.mod, docs/abb.md)"
                                          ) from e
            self._identity = self._read_identity(_left(deadline))
        except DriverError as e:
            self.close()
            self._refused = f"{e.command}: {e.detail}"
            raise
        self._refused = ""
        self._check_speed_ratio(_left(deadline))
        ident = self._identity
        log.info("robot %s: link open%s; controller %s, serial %s, RobotWare %s%s, %d joints",
                 self.url, "" if self.read_only else ", mastership taken",
                 ident.model or "?", ident.serial or "?", ident.firmware or "?",
                 " (virtual)" if ident.simulator else "", self.n_joints)

    def _check_speed_ratio(self, timeout: float) -> None:
        """Warn when the pendant's speed override is below 100 %: every move then takes
        longer than the driver asks (its timeout may run out)."""
        try:
            ratio = float(self._field(self._get(C.SPEEDRATIO, timeout, retry=True),
                                      "speedratio", "GET speedratio"))
        except (DriverError, ValueError):
            return
        if ratio < 100:
            log.warning("robot %s: speed ratio %g %% at the controller: moves take %.3gx "
                        "longer than asked", self.url, ratio, 100 / max(ratio, 1e-3))

    def close(self) -> None:
        """Release the mastership, log out, close the link; idempotent, never raises. A
        session whose link was lost during a move is ended too (its mastership would
        otherwise bar the next session)."""
        if self._link.has_session:
            with contextlib.suppress(DriverError):
                if self._master:
                    self._link.request("POST", C.MASTERSHIP_RELEASE, {}, timeout=0.5,
                                       command="release mastership")
            with contextlib.suppress(DriverError):
                self._link.request("GET", C.LOGOUT, None, timeout=0.5, command="logout")
        if self._connected or self._master:
            log.info("robot %s: link closed%s", self.url,
                     ", mastership released" if self._master else "")
        self._connected = self._master = False
        self._link.drop()
        self._link.forget_session()

    def __enter__(self) -> AbbRwsRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _lost(self) -> None:
        """The link died during a move: closed until :meth:`connect` (the session, and the
        mastership it holds, kept for it)."""
        self._connected = False
        self._link.drop()

    # -- identity ---------------------------------------------------------------------------

    def _read_identity(self, timeout: float) -> DeviceIdentity:
        deadline = time.monotonic() + timeout
        ident = self._get(C.IDENTITY, _left(deadline), retry=True)
        system = self._get(C.SYSTEM, _left(deadline), retry=True)
        rtype = self._get(C.ROBOTTYPE, _left(deadline), retry=True)
        ctrl_type = _maybe(ident, "ctrl-type")
        self.serial = _maybe(ident, "ctrl-id")
        self.firmware = _maybe(system, "rwversion")
        self.model = _maybe(rtype, "robot-type")
        ours = "cellcal sim" in _maybe(system, "rwversionname")
        return DeviceIdentity("robot", self.model, self.serial, self.firmware,
                              simulator="virtual" in ctrl_type.lower(),
                              kinematics=self.model if ours else "", n_joints=self.n_joints)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """Robot type (``rw/system/robottype``), serial number (``ctrl/identity``
        ``ctrl-id``) and RobotWare version (``rw/system``); a virtual controller
        (``ctrl-type``) is a simulator, and cellcal's own names the model it moves."""
        if self._identity is None:
            self._identity = self._read_identity(timeout)
        return self._identity

    # -- reading ----------------------------------------------------------------------------

    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """The joints now (``jointtarget`` of the mechanical unit, deg → rad)."""
        doc = self._get(C.jointtarget_path(self.mechunit), timeout, retry=True)
        command = "GET jointtarget"
        try:
            deg = [float(self._field(doc, f"rax_{i + 1}", command)) for i in range(self.n_joints)]
        except ValueError as e:
            raise ProtocolError(self.url, command, f"bad joint value: {e}") from e
        return JointReading(q=np.deg2rad(np.array(deg)), timestamp=time.time())

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """The controller's TCP position (mm, base frame) for the URL's tool and wobj
        (``robtarget``)."""
        doc = self._get(C.robtarget_path(self.mechunit, self.tool, self.wobj), timeout,
                        retry=True)
        try:
            return np.array([float(self._field(doc, k, "GET robtarget")) for k in "xyz"])
        except ValueError as e:
            raise ProtocolError(self.url, "GET robtarget", f"bad position: {e}") from e

    def _states(self, timeout: float) -> tuple[str, str, str]:
        """(controller state, operating mode, RAPID execution state)."""
        deadline = time.monotonic() + timeout
        ctrl = self._field(self._get(C.CTRLSTATE, _left(deadline), retry=True), "ctrlstate",
                           "GET ctrlstate")
        mode = self._field(self._get(C.OPMODE, _left(deadline), retry=True), "opmode",
                           "GET opmode")
        execution = self._field(self._get(C.EXECUTION, _left(deadline), retry=True),
                                "ctrlexecstate", "GET execution")
        return ctrl, mode, execution

    def status(self, timeout: float = 1.0) -> RobotStatus:
        """The controller's state; moving while the server module runs a move (RAPID
        running, ``cc_busy`` 1)."""
        deadline = time.monotonic() + timeout
        ctrl, mode, execution = self._states(timeout)
        running = execution == "running"
        moving = running and self._num(C.VAR_BUSY, _left(deadline), retry=True) == 1
        stop = ctrl in STOPS
        return RobotStatus(
            connected=True, moving=moving, in_position=not moving and not stop,
            fault=ctrl == "sysfail", protective_stop=ctrl == "guardstop",
            emergency_stop=ctrl.startswith("emergencystop"),
            error_code=STOP_CODES.get(ctrl, 0),
            message=f"controller {ctrl}, {mode}, RAPID {execution}", timestamp=time.time())

    # -- motion -----------------------------------------------------------------------------

    @contextlib.contextmanager
    def _as(self, command: str) -> Iterator[None]:
        """Errors of a move's requests named after the move; a lost link closes the
        driver."""
        self._in_move = True
        try:
            yield
        except DriverError as e:
            if isinstance(e, ConnectionLost):
                self._lost()
            if e.command == command:
                raise
            detail = f"{e.command}: {e.detail}" if e.command else e.detail
            raise type(e)(self.url, command, detail) from e
        finally:
            self._in_move = False

    def move_joints(self, q: np.ndarray, speed: float = 0.5, timeout: float = 60.0) -> None:
        """MoveAbsJ to ``q`` (rad) through the server module, the leading joint at ``speed``
        rad/s (its ``\\T`` time), zone fine; returns once the module acknowledged it in
        position."""
        deadline = time.monotonic() + timeout
        command = "MoveAbsJ"
        q = np.asarray(q, float)
        if q.shape != (self.n_joints,) or not np.all(np.isfinite(q)):
            raise CommandRejected(self.url, command,
                                  f"expected {self.n_joints} finite joint values (rad), got {q}")
        _check_speed(self.url, command, speed)
        if self.limits is not None:
            bad = np.nonzero((q < self.limits[:, 0]) | (q > self.limits[:, 1]))[0]
            if bad.size:
                raise LimitError(self.url, command,
                                 f"LIMIT: joint(s) {(bad + 1).tolist()} outside limits")
        with self._as(command):
            ack = self._ready(command, deadline)
            q_now = self.read_joints(_left(deadline)).q
            # \T of at least 50 ms: a target where the robot stands is a move of no length
            seconds = max(float(np.max(np.abs(q - q_now))) / speed, MIN_MOVE_S)
            self._set(C.VAR_JOINTS, C.jointtarget_text(np.rad2deg(q).tolist()), deadline)
            self._set(C.VAR_TIME, C.rapid_num(seconds), deadline)
            self._set(C.VAR_ZONE, C.ZONE_FINE, deadline)
            self._set(C.VAR_KIND, C.rapid_num(C.KIND_JOINTS), deadline)
            self._go(command, C.next_seq(ack), deadline)

    def move_linear(self, xyz: np.ndarray, speed: float = 100.0, timeout: float = 60.0) -> None:
        """MoveL of the tool to ``xyz`` (mm, base frame = wobj0), orientation kept, at
        ``speed`` mm/s, zone fine; returns once the module acknowledged it in position."""
        deadline = time.monotonic() + timeout
        command = "MoveL"
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
            raise CommandRejected(self.url, command, f"expected finite x y z (mm), got {xyz}")
        _check_speed(self.url, command, speed)
        with self._as(command):
            ack = self._ready(command, deadline)
            self._set(C.VAR_XYZ, C.pos_text(xyz.tolist()), deadline)
            self._set(C.VAR_SPEED, C.speeddata_text(speed), deadline)
            self._set(C.VAR_ZONE, C.ZONE_FINE, deadline)
            self._set(C.VAR_TOOL, C.string_text(self.tool), deadline)
            self._set(C.VAR_KIND, C.rapid_num(C.KIND_LINEAR), deadline)
            self._go(command, C.next_seq(ack), deadline)

    def _ready(self, command: str, deadline: float) -> int:
        """Check the controller can move (else the typed error), restart the module when
        RAPID is stopped, wait until it is idle; returns its last request number."""
        if self.read_only:
            raise NotReady(self.url, command, "opened read-only (no mastership)")
        ctrl, mode, execution = self._states(_left(deadline))
        _raise_if_stopped(self.url, command, ctrl)
        if ctrl != "motoron":
            raise NotReady(self.url, command, f"controller {ctrl}: switch the motors on")
        if mode != "AUTO":
            raise NotReady(self.url, command, f"operating mode {mode}: RWS starts and runs "
                           "RAPID in AUTO only")
        if execution != "running":
            if not self.restart_rapid:
                raise NotReady(self.url, command, "RAPID is stopped: start the module")
            log.info("%s: RAPID stopped: restarting %s from main", self.url, self.module)
            self._post(C.EXEC_RESETPP, None, _left(deadline), "resetpp")
            self._post(C.EXEC_START, dict(C.START_FORM), _left(deadline), "start RAPID")
        while True:
            seq = int(self._num(C.VAR_SEQ, _left(deadline)))
            ack = int(self._num(C.VAR_ACK, _left(deadline)))
            if seq == ack:
                return ack
            if time.monotonic() >= deadline:
                raise NotReady(self.url, command, f"the module is busy with request {seq}")
            time.sleep(self.poll_s)

    def _go(self, command: str, seq: int, deadline: float) -> None:
        """Write the request number; wait for its acknowledgement (in position), watching
        the controller; out of time: stop RAPID, CommandTimeout."""
        self._set(C.VAR_SEQ, C.rapid_num(seq), deadline)
        while True:
            if int(self._num(C.VAR_ACK, _left(deadline))) == seq:
                err = int(self._num(C.VAR_ERR, _left(deadline)))
                if err == C.ERR_NONE:
                    return
                msg = C.parse_string(self._symbol(C.VAR_MSG, _left(deadline)))
                cls = LimitError if err == C.ERR_LIMIT else CommandRejected
                raise cls(self.url, command, msg or f"refused: {C.ERR_NAMES.get(err, err)}")
            ctrl, _mode, execution = self._states(_left(deadline))
            _raise_if_stopped(self.url, command, ctrl)
            if ctrl != "motoron":
                raise NotReady(self.url, command, f"controller {ctrl} during the move (the "
                               "motors went off): switch them on")
            if execution != "running":
                raise CommandRejected(self.url, command,
                                      f"RAPID stopped during the move: {self._last_error()}")
            if time.monotonic() >= deadline:
                with contextlib.suppress(DriverError):
                    self.stop(STOP_AFTER_TIMEOUT_S)
                raise CommandTimeout(self.url, command,
                                     "target not reached within timeout; robot stopped")
            time.sleep(self.poll_s)

    def _last_error(self) -> str:
        """The newest error (else warning) of the event log, in words."""
        try:
            items = C.states(self._get(C.ELOG + "?lang=en", 1.0, "GET elog"))
        except DriverError as e:
            return f"(event log unreadable: {e})"
        items = sorted(items, key=lambda i: int(str(i.get("_title", "0")).split("/")[-1]
                                                or 0), reverse=True)
        for kind in ("3", "2"):
            for i in items:
                if str(i.get("msgtype")) == kind:
                    return f"event {i.get('code')} {i.get('title', '')}".strip()
        return "no error in the event log"

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Poll the status until in position and not moving (ProtectiveStop on a stop,
        CommandRejected on a system failure, CommandTimeout)."""
        poll_until_settled(lambda t: self.status(timeout=t), self.url, timeout, self.poll_s)

    def stop(self, timeout: float = 2.0) -> None:
        """Stop RAPID (``rw/rapid/execution?action=stop``: the robot stops on its path);
        return once it stands still."""
        deadline = time.monotonic() + timeout
        if self.read_only:
            raise NotReady(self.url, "stop", "opened read-only (no mastership)")
        self._post(C.EXEC_STOP, dict(C.STOP_FORM), _left(deadline), "stop RAPID")
        poll_until_still(lambda t: self.status(timeout=t), self.url, "stop", deadline,
                         self.poll_s)


def _left(deadline: float) -> float:
    return max(deadline - time.monotonic(), 0.01)


def _maybe(doc: dict | None, key: str) -> str:
    try:
        return C.field(doc, key)
    except KeyError:
        return ""


def _raise_if_stopped(url: str, command: str, ctrl: str) -> None:
    if ctrl in STOPS:
        raise ProtectiveStop(url, command, f"controller {ctrl}: {STOPS[ctrl]}")
    if ctrl == "sysfail":
        raise CommandRejected(url, command, "controller sysfail: a system failure, restart "
                              "the controller")


def _check_speed(url: str, command: str, speed: float) -> None:
    if not (math.isfinite(speed) and speed > 0):
        raise CommandRejected(url, command, f"speed must be > 0, got {speed}")
