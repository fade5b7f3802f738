"""Laser tracker over TCP or serial, speaking the line protocol of docs/tracker-protocol.md.

``HELLO`` → ``OK HELLO <model> <serial> <fw>``, ``STATUS?``, ``INIT``,
``SET MODE STATIONARY time_ms=N``, ``MEAS`` → ``OK MEAS x=… y=… z=… sx=… sy=…
sz=… n=… T=… P=… H=… t=…`` (mm, °C, hPa, %, epoch s). Errors
``ERR <code> <NAME> [text]`` become typed errors; unsolicited ``EVT …`` lines
are queued apart (:meth:`LineTracker.events`).

Capabilities (:mod:`drivers.protocols`): a ready gate from ``STATUS?``
(:class:`~drivers.protocols.ReadyGate`), the air with ``ENV?`` / ``SET ENV``
(:class:`~drivers.protocols.EnvironmentSensor`), two-face measurement with
``FACE?`` / ``CHANGE FACE`` (:class:`~drivers.protocols.TwoFace`), a 6-DoF target's
pose with ``MEAS6D`` (:class:`~drivers.protocols.SixDof`).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from drivers.errors import (
    BeamBroken,
    CommandRejected,
    DriverError,
    NotReady,
    ProtocolError,
)
from drivers.protocols import (
    DeviceIdentity,
    Environment,
    Measurement,
    PoseMeasurement,
    Readiness,
    TrackerStatus,
    measure_both_faces,
)
from drivers.transport import LineSession, LineTransport, parse_kv

log = logging.getLogger(__name__)  # the wire at DEBUG (drivers.transport)

#: ERR name → error class
TRACKER_ERRORS: dict[str, type[DriverError]] = {
    "BAD_COMMAND": CommandRejected,
    "BAD_ARGUMENT": CommandRejected,
    "BUSY": NotReady,
    "NOT_INITIALISED": NotReady,
    "NOT_WARMED_UP": NotReady,
    "NOT_STABLE": NotReady,
    "NO_STATIONARY_RESULT": NotReady,
    "BEAM_BROKEN": BeamBroken,
    "NO_TARGET": BeamBroken,
    "OUT_OF_RANGE": CommandRejected,
    "NO_6DOF_TARGET": CommandRejected,
    "FACE2_6D": CommandRejected,
}

#: largest accepted | |q| - 1 | of a MEAS6D quaternion (written with 10 decimals)
QUAT_TOLERANCE = 1e-6


class LineTracker:
    """A laser tracker behind the line protocol.

    Parameters
    ----------
    url : str
        The driver URL, used in messages (``tracker+tcp://host:port``).
    port_url : str
        What pyserial opens: ``socket://host:port`` or a device path.
    baudrate : int
        Serial speed (ignored on sockets).
    auto_init : bool
        On :meth:`connect`, send ``INIT`` when the tracker reports it is not initialised.
    """

    def __init__(
        self, url: str, port_url: str, *, baudrate: int = 115200, auto_init: bool = True
    ) -> None:
        self.url = url
        self.auto_init = auto_init
        self.model = self.serial = self.firmware = ""
        self._hello_kv: dict[str, str] = {}
        self._mode_ms: int | None = None
        #: the last measurement's time and sequence number: a reply not after them is stale
        self._last_t: float | None = None
        self._last_seq: int | None = None
        self._transport = LineTransport(port_url, device=f"tracker {url}", baudrate=baudrate,
                                        logger=log)
        self._session = LineSession(self._transport, TRACKER_ERRORS, handshake=self._hello)

    # ----------------------------------------------------------- connection
    def _hello(self, deadline: float) -> None:
        tok = self._session.exchange("HELLO", "HELLO", deadline)
        if len(tok) < 3:
            raise ProtocolError(self._transport.device, "HELLO", f"short reply {tok}")
        self.model, self.serial, self.firmware = tok[:3]
        self._hello_kv = dict(t.split("=", 1) for t in tok[3:] if "=" in t)
        self._mode_ms = None
        log.info("%s: tracker %s, serial %s, firmware %s", self._transport.device, self.model,
                 self.serial, self.firmware)

    def identify(self, timeout: float = 2.0) -> DeviceIdentity:
        """Who the tracker said it is in ``HELLO`` (``sim=1`` from a simulator)."""
        return DeviceIdentity("tracker", self.model, self.serial, self.firmware,
                              simulator=self._hello_kv.get("sim") == "1")

    def connect(self, timeout: float = 5.0) -> None:
        """Open the link, greet the tracker and initialise it if needed (``auto_init``)."""
        deadline = time.monotonic() + timeout
        self._session.connect(timeout)
        if self.auto_init:
            st = self.status(timeout=max(deadline - time.monotonic(), 0.01))
            if not st.initialised:
                log.info("%s: not initialised: initialising", self._transport.device)
                self.initialise(timeout=max(deadline - time.monotonic(), 0.01))

    def close(self) -> None:
        """Close the link (idempotent)."""
        self._transport.close()

    def __enter__(self) -> LineTracker:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        """Whether the link is open."""
        return self._transport.is_open

    # ------------------------------------------------------------- commands
    def status(self, timeout: float = 1.0) -> TrackerStatus:
        """``STATUS?``: initialised, warmed up, beam and target (retried once after a reconnect)."""
        deadline = time.monotonic() + timeout
        tok = self._session.exchange("STATUS?", "STATUS", deadline, retry=True)
        kv = parse_kv(tok, self._transport.device, "STATUS?")
        try:
            return TrackerStatus(
                connected=True,
                initialised=kv["init"] == "1",
                warmed_up=kv["warm"] == "1",
                beam_ok=kv["beam"] == "1",
                target_present=kv.get("target", "1") == "1",
                message=" ".join(tok),
                timestamp=time.time(),
            )
        except KeyError as e:
            raise ProtocolError(self._transport.device, "STATUS?", f"missing {e}") from e

    def initialise(self, timeout: float = 30.0) -> None:
        """``INIT``: home the tracker and find the target."""
        self._session.exchange("INIT", "INIT", time.monotonic() + timeout)

    def set_stationary_time(self, time_ms: int, timeout: float = 1.0) -> None:
        """``SET MODE STATIONARY time_ms=N``: averaging time of ``MEAS`` (ms)."""
        time_ms = int(time_ms)
        self._session.exchange(
            f"SET MODE STATIONARY time_ms={time_ms}", "MODE", time.monotonic() + timeout, retry=True
        )
        self._mode_ms = time_ms

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement:
        """Measure the stationary target, averaging ``duration_s`` s.

        Returns a :class:`~drivers.protocols.Measurement` (xyz, std in mm, tracker
        frame; env with ``temp_c``, ``pressure_hpa``, ``humidity_pct``). Retried
        once after a lost connection (the target is stationary, so it is safe).
        """
        return self._parse_meas(self._measure_line("MEAS", duration_s, timeout))

    def measure_pose(self, duration_s: float = 0.5, timeout: float = 10.0) -> PoseMeasurement:
        """``MEAS6D``: the 6-DoF target's position (mm) and orientation (unit quaternion
        w, x, y, z of the target frame in the tracker frame; per-axis std in deg), as
        :meth:`measure` (retried once after a lost connection)."""
        tok = self._measure_line("MEAS6D", duration_s, timeout)
        m = self._parse_meas(tok, "MEAS6D")
        kv = parse_kv(tok, self._transport.device, "MEAS6D")
        try:
            quat = np.array([float(kv[k]) for k in ("qw", "qx", "qy", "qz")])
            std_deg = np.array([float(kv[k]) for k in ("sdx", "sdy", "sdz")])
        except (KeyError, ValueError) as e:
            raise ProtocolError(self._transport.device, "MEAS6D", f"bad 6D reply: {e}") from e
        norm = float(np.linalg.norm(quat))
        if not (np.all(np.isfinite(std_deg)) and abs(norm - 1.0) <= QUAT_TOLERANCE):
            raise ProtocolError(self._transport.device, "MEAS6D",
                                f"quaternion of length {norm:.9g} or non-finite std")
        fields = {k: getattr(m, k) for k in ("xyz", "std", "n", "timestamp", "env", "face")}
        return PoseMeasurement(**fields, quat=quat / norm, std_deg=std_deg,
                               sigma_deg=float(np.sqrt(np.mean(std_deg**2))),
                               target=kv.get("target", ""))

    def _measure_line(self, request: str, duration_s: float, timeout: float) -> list[str]:
        """``request`` (MEAS or MEAS6D) after the averaging time is set: its reply tokens."""
        deadline = time.monotonic() + timeout
        time_ms = max(1, int(round(duration_s * 1000.0)))
        for attempt in range(2):
            if self._mode_ms != time_ms:
                self._session.exchange(
                    f"SET MODE STATIONARY time_ms={time_ms}", "MODE", deadline, retry=True
                )
                self._mode_ms = time_ms
            mode_before = self._mode_ms
            tok = self._session.exchange(request, request, deadline, retry=True)
            if self._mode_ms == mode_before or attempt:
                break
            # a reconnect reset the mode before MEAS: measure again with the right time
        return tok

    def _parse_meas(self, tok: list[str], command: str = "MEAS") -> Measurement:
        dev = self._transport.device
        kv = parse_kv(tok, dev, command)
        try:
            xyz = np.array([float(kv["x"]), float(kv["y"]), float(kv["z"])])
            std = np.array([float(kv["sx"]), float(kv["sy"]), float(kv["sz"])])
            n = int(kv["n"])
            ts = float(kv["t"])
            face = int(kv.get("face", "0"))
            env = {}
            for key, name in (("T", "temp_c"), ("P", "pressure_hpa"), ("H", "humidity_pct")):
                if key in kv:
                    env[name] = float(kv[key])
        except (KeyError, ValueError) as e:
            raise ProtocolError(dev, command, f"bad measurement reply: {e}") from e
        if not (np.all(np.isfinite(xyz)) and np.all(np.isfinite(std))):
            raise ProtocolError(dev, command, "non-finite values")
        self._check_fresh(kv, ts)
        return Measurement(xyz=xyz, std=std, n=n, timestamp=ts, env=env, face=face)

    def _check_fresh(self, kv: dict[str, str], ts: float) -> None:
        """A measurement must be newer than the last one: its ``t`` later and, when the
        tracker numbers its replies (``seq=``), its number higher. A repeated or older
        reply is a ProtocolError (transient: the point is measured again)."""
        dev = self._transport.device
        seq = None
        if "seq" in kv:
            try:
                seq = int(kv["seq"])
            except ValueError as e:
                raise ProtocolError(dev, "MEAS", f"bad seq {kv['seq']!r}") from e
        if self._last_t is not None and ts <= self._last_t:
            raise ProtocolError(dev, "MEAS", f"stale measurement: t={ts:.3f} is not after the "
                                f"previous reply's t={self._last_t:.3f} (a repeated reply?)")
        if seq is not None and self._last_seq is not None and seq <= self._last_seq:
            raise ProtocolError(dev, "MEAS", f"stale measurement: seq={seq} is not after the "
                                f"previous reply's seq={self._last_seq} (a repeated reply?)")
        self._last_t = ts
        if seq is not None:
            self._last_seq = seq

    # ------------------------------------------------------- capabilities
    def ready(self, timeout: float = 2.0) -> Readiness:
        """The ready gate from ``STATUS?``: ``init``, ``warm``, ``ws`` (weather station;
        assumed present when the tracker reports ``T`` without ``ws``), ``target``."""
        deadline = time.monotonic() + timeout
        tok = self._session.exchange("STATUS?", "STATUS", deadline, retry=True)
        kv = parse_kv(tok, self._transport.device, "STATUS?")
        station = kv.get("ws", "1" if "T" in kv else "0") == "1"
        return Readiness.of(
            initialised=kv.get("init") == "1", warmed_up=kv.get("warm") == "1",
            weather_station=station,
            target=kv.get("beam") == "1" and kv.get("target", "1") == "1",
        )

    def check_ready(self, timeout: float = 2.0) -> Readiness:
        """:meth:`ready`, raising NotReady naming every failed check."""
        return self.ready(timeout).raise_if_not_ok(self._transport.device)

    def _environment(self, tok: list[str], command: str) -> Environment:
        kv = parse_kv(tok, self._transport.device, command)
        try:
            return Environment(float(kv["T"]), float(kv["P"]), float(kv["H"]),
                               "station" if kv.get("src") == "station" else "manual")
        except (KeyError, ValueError) as e:
            raise ProtocolError(self._transport.device, command, f"bad ENV reply: {e}") from e

    def environment(self, timeout: float = 2.0) -> Environment:
        """``ENV?``: the air the tracker corrects with (°C, hPa, %RH) and its source."""
        tok = self._session.exchange("ENV?", "ENV", time.monotonic() + timeout, retry=True)
        return self._environment(tok, "ENV?")

    def set_environment(self, temp_c: float, pressure_hpa: float, humidity_pct: float,
                        timeout: float = 2.0) -> None:
        """``SET ENV T=… P=… H=…``: the air by hand (used while no weather station reports)."""
        vals = np.array([temp_c, pressure_hpa, humidity_pct], float)
        if not np.all(np.isfinite(vals)):
            raise CommandRejected(self._transport.device, "SET ENV", "non-finite value")
        line = f"SET ENV T={vals[0]:.3f} P={vals[1]:.3f} H={vals[2]:.2f}"
        self._session.exchange(line, "ENV", time.monotonic() + timeout, retry=True)

    def face(self, timeout: float = 2.0) -> int:
        """``FACE?``: 1 or 2."""
        tok = self._session.exchange("FACE?", "FACE", time.monotonic() + timeout, retry=True)
        return self._face(tok, "FACE?")

    def _face(self, tok: list[str], command: str) -> int:
        kv = parse_kv(tok, self._transport.device, command)
        if kv.get("face") not in ("1", "2"):
            raise ProtocolError(self._transport.device, command, f"bad face {kv.get('face')!r}")
        return int(kv["face"])

    def change_face(self, timeout: float = 30.0) -> int:
        """``CHANGE FACE``: turn to the other face; returns the new one (not retried)."""
        tok = self._session.exchange("CHANGE FACE", "FACE", time.monotonic() + timeout)
        return self._face(tok, "CHANGE FACE")

    def measure_faces(self, duration_s: float = 0.5,
                      timeout: float = 60.0) -> tuple[Measurement, Measurement]:
        """Measure, ``CHANGE FACE``, measure: ``(face 1, face 2)``."""
        return measure_both_faces(self, duration_s, timeout)

    # --------------------------------------------------------------- events
    def events(self, poll_s: float = 0.0) -> list[tuple[float, str]]:
        """Unsolicited events received so far, oldest first, as (epoch s, text); clears the queue.

        ``poll_s`` > 0 first reads the link for that long to collect new ones.
        """
        if poll_s > 0 and self._transport.is_open:
            self._transport.poll_events(poll_s)
        out = list(self._transport.events)
        self._transport.events.clear()
        return out
