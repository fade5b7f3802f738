"""A robot controller behind a simple ASCII line protocol (docs/line-robot-protocol.md).

:class:`SerialRobot` is a RobotDriver with the CommandedPosition (``TCP?``) and
JointTemperatures (``TEMPS?``) capabilities.

Over :func:`serial.serial_for_url`, so ``socket://host:port``, ``loop://``, a pty
and real ports all work. Degrees and millimetres on the wire, radians and
millimetres at the Python boundary.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from drivers.errors import (
    CommandRejected,
    DriverError,
    LimitError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.protocols import DeviceIdentity, JointReading, RobotStatus
from drivers.settle import poll_until_settled, poll_until_still, settle_move
from drivers.transport import LineSession, LineTransport, parse_kv

log = logging.getLogger(__name__)  # the wire at DEBUG (drivers.transport)

#: ERR name → error class
ROBOT_ERRORS: dict[str, type[DriverError]] = {
    "BAD_COMMAND": CommandRejected,
    "BAD_ARGUMENT": CommandRejected,
    "LIMIT": LimitError,
    "UNREACHABLE": CommandRejected,
    "PROTECTIVE_STOP": ProtectiveStop,
    "EMERGENCY_STOP": ProtectiveStop,
    "FAULT": CommandRejected,
    "BUSY": NotReady,
}


class SerialRobot:
    """RobotDriver (+ ``read_tcp``) for the line-protocol controller.

    Parameters
    ----------
    url : str
        Driver URL for messages (``socket://host:port``, ``serial:///dev/ttyUSB0``).
    port_url : str
        What pyserial opens.
    baudrate : int
        Serial speed (ignored on sockets).
    poll_s : float
        Status polling period of :meth:`wait_settled` (s).
    """

    def __init__(
        self, url: str, port_url: str, *, baudrate: int = 115200, poll_s: float = 0.01
    ) -> None:
        self.url = url
        self.poll_s = poll_s
        self.model = self.serial = self.firmware = ""
        self.n_joints = 0
        self._hello_kv: dict[str, str] = {}
        self._transport = LineTransport(port_url, device=f"robot {url}", baudrate=baudrate,
                                        logger=log)
        self._session = LineSession(self._transport, ROBOT_ERRORS, handshake=self._hello)

    @property
    def _dev(self) -> str:
        return self._transport.device

    def _hello(self, deadline: float) -> None:
        tok = self._session.exchange("HELLO", "HELLO", deadline)
        if len(tok) < 4:
            raise ProtocolError(self._dev, "HELLO", f"short reply {tok}")
        self.model, self.serial, self.firmware = tok[:3]
        kv = parse_kv(tok[3:], self._dev, "HELLO")
        try:
            self.n_joints = int(kv["joints"])
        except (KeyError, ValueError) as e:
            raise ProtocolError(self._dev, "HELLO", f"no joints=N in {tok}") from e
        self._hello_kv = kv
        log.info("%s: controller %s, serial %s, firmware %s, %d joints", self._dev, self.model,
                 self.serial, self.firmware, self.n_joints)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """Who the controller said it is in ``HELLO`` (``sim=1 kinematics=NAME`` from a
        simulator)."""
        kv = self._hello_kv
        return DeviceIdentity("robot", self.model, self.serial, self.firmware,
                              simulator=kv.get("sim") == "1",
                              kinematics=kv.get("kinematics", ""), n_joints=self.n_joints)

    # ----------------------------------------------------------- connection
    def connect(self, timeout: float = 5.0) -> None:
        """Open the link and greet the controller (learns the number of joints)."""
        self._session.connect(timeout)

    def close(self) -> None:
        """Close the link (idempotent)."""
        self._transport.close()

    def __enter__(self) -> SerialRobot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --------------------------------------------------------------- queries
    def _floats(self, tok: list[str], n: int, command: str) -> np.ndarray:
        try:
            v = np.array([float(t) for t in tok])
        except ValueError as e:
            raise ProtocolError(self._dev, command, f"bad numbers {tok}") from e
        if v.shape != (n,) or not np.all(np.isfinite(v)):
            raise ProtocolError(self._dev, command, f"expected {n} numbers, got {tok}")
        return v

    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """``POS?``: joint positions (rad) with the time they were read (epoch s)."""
        tok = self._session.exchange("POS?", "POS", time.monotonic() + timeout, retry=True)
        q = np.deg2rad(self._floats(tok, self.n_joints, "POS?"))
        return JointReading(q=q, timestamp=time.time())

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """``TCP?``: the controller's nominal TCP position (mm, base frame), shape (3,)."""
        tok = self._session.exchange("TCP?", "TCP", time.monotonic() + timeout, retry=True)
        return self._floats(tok, 3, "TCP?")

    def joint_temperatures(self, timeout: float = 1.0) -> tuple[float, ...]:
        """``TEMPS?``: each joint's temperature (°C); CommandRejected (``BAD_COMMAND``) from
        a controller that reports none."""
        tok = self._session.exchange("TEMPS?", "TEMPS", time.monotonic() + timeout, retry=True)
        return tuple(float(v) for v in self._floats(tok, self.n_joints, "TEMPS?"))

    def status(self, timeout: float = 1.0) -> RobotStatus:
        """``STATUS?``: motion and safety state."""
        tok = self._session.exchange("STATUS?", "STATUS", time.monotonic() + timeout, retry=True)
        kv = parse_kv(tok, self._dev, "STATUS?")
        try:
            return RobotStatus(
                connected=True,
                moving=kv["moving"] == "1",
                in_position=kv["inpos"] == "1" and kv.get("steady", "1") == "1",
                fault=kv["fault"] == "1",
                protective_stop=kv["pstop"] == "1",
                emergency_stop=kv.get("estop", "0") == "1",
                error_code=int(kv.get("err", "0")),
                message=" ".join(tok),
                timestamp=float(kv.get("t", time.time())),
            )
        except (KeyError, ValueError) as e:
            raise ProtocolError(self._dev, "STATUS?", f"bad status reply {tok}: {e}") from e

    # --------------------------------------------------------------- motion
    def move_joints(self, q: np.ndarray, speed: float = 0.5, timeout: float = 60.0) -> None:
        """``MOVEJ`` to ``q`` (rad, shape (n_joints,)) at ``speed`` rad/s, then ``STATUS?``
        until settled: returns once the robot has arrived and settled within ``timeout``
        (else ``STOP`` and CommandTimeout)."""
        deadline = time.monotonic() + timeout
        q = np.asarray(q, float)
        if q.shape != (self.n_joints,):
            raise CommandRejected(self._dev, "MOVEJ", f"expected {self.n_joints} joints, got {q}")
        args = " ".join(f"{v:.6f}" for v in np.rad2deg(q))
        cmd = f"MOVEJ {args} {np.rad2deg(speed):.6f}"
        self._session.exchange(cmd, "MOVEJ", min(deadline, time.monotonic() + 5.0))
        settle_move(self.wait_settled, self.stop, self._dev, "MOVEJ", deadline)

    def move_linear(self, xyz: np.ndarray, speed: float = 100.0, timeout: float = 60.0) -> None:
        """``MOVEL`` to ``xyz`` (mm, base frame) at ``speed`` mm/s, then ``STATUS?`` until
        settled (as :meth:`move_joints`)."""
        deadline = time.monotonic() + timeout
        xyz = np.asarray(xyz, float)
        if xyz.shape != (3,):
            raise CommandRejected(self._dev, "MOVEL", f"expected x y z, got {xyz}")
        cmd = "MOVEL " + " ".join(f"{v:.4f}" for v in xyz) + f" {speed:.4f}"
        self._session.exchange(cmd, "MOVEL", min(deadline, time.monotonic() + 5.0))
        settle_move(self.wait_settled, self.stop, self._dev, "MOVEL", deadline)

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Poll ``STATUS?`` until in position and steady.

        Raises ProtectiveStop on a protective/emergency stop, CommandRejected on
        a controller fault, CommandTimeout when ``timeout`` passes first.
        """
        poll_until_settled(lambda t: self.status(timeout=t), self._dev, timeout, self.poll_s)

    def stop(self, timeout: float = 2.0) -> None:
        """``STOP``: halt any motion, then ``STATUS?`` until the robot stands still."""
        deadline = time.monotonic() + timeout
        self._session.exchange("STOP", "STOP", deadline, retry=True)
        poll_until_still(lambda t: self.status(timeout=t), self._dev, "STOP", deadline,
                         self.poll_s)

    def clear_protective_stop(self, timeout: float = 2.0) -> None:
        """``RESET``: clear a protective stop or fault (after the cause is removed)."""
        self._session.exchange("RESET", "RESET", time.monotonic() + timeout)
