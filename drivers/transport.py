"""Line I/O over any pyserial URL, with deadlines and typed errors.

:class:`LineTransport` opens ``socket://host:port``, ``loop://``, a pty or a
real port through :func:`serial.serial_for_url`, writes ASCII lines terminated
by ``\\n`` and reads lines until a deadline measured with
:func:`time.monotonic`. Lines starting with ``EVT `` are unsolicited events:
they go to :attr:`LineTransport.events`, never to a reply. Failures become the
driver errors: a closed link is :class:`~drivers.errors.ConnectionLost`, a
missing reply :class:`~drivers.errors.CommandTimeout`, undecodable bytes
:class:`~drivers.errors.ProtocolError`.

Logging: the wire at DEBUG (``robot socket://...: > MOVEJ ...`` each request,
``< OK MOVEJ`` each line read, events included), the link opened and closed, an
error reply, a timeout, garbage, a resynchronisation and a reconnect at INFO, through
the logger the driver passes (``logger``: its module's, so ``drivers.line_robot``
shows one driver's wire), else this module's.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import socket
import threading
import time
from collections.abc import Callable

import serial

from drivers.errors import CommandTimeout, ConnectionLost, DriverError, ProtocolError

log = logging.getLogger(__name__)

#: longest line accepted before the peer is declared to speak garbage
MAX_LINE = 4096


class LineTransport:
    """A line-oriented link to one device.

    Parameters
    ----------
    port_url : str
        Anything :func:`serial.serial_for_url` opens (``socket://h:p``, ``/dev/pts/3``...).
    device : str
        Name used in error messages (usually the driver URL).
    baudrate : int
        For real serial ports; ignored by sockets.
    max_events : int
        How many unread events are kept (oldest dropped first).
    logger : logging.Logger, optional
        Where the wire and the link's events are logged (default: this module's).
    """

    def __init__(
        self, port_url: str, *, device: str = "", baudrate: int = 115200, max_events: int = 1000,
        logger: logging.Logger | None = None,
    ) -> None:
        self.log = logger or log
        self.port_url = port_url
        self.device = device or port_url
        self.baudrate = baudrate
        self.events: collections.deque[tuple[float, str]] = collections.deque(maxlen=max_events)
        self._ser: serial.SerialBase | None = None
        self._buf = bytearray()
        self._lock = threading.RLock()

    @property
    def is_open(self) -> bool:
        """Whether the link is open."""
        return self._ser is not None

    @property
    def is_socket(self) -> bool:
        """Whether the link is a TCP socket (a reconnect discards stale replies)."""
        return self.port_url.startswith("socket://")

    def open(self, timeout: float = 5.0) -> None:
        """Open (or reopen) the link; raise ConnectionLost when that fails."""
        with self._lock:
            self.close()
            try:
                ser = serial.serial_for_url(self.port_url, do_not_open=True)
                ser.baudrate = self.baudrate
                ser.timeout = timeout
                ser.write_timeout = timeout
                ser.open()
            except (serial.SerialException, OSError, ValueError) as e:
                self.log.info("%s: cannot open %s: %s", self.device, self.port_url, e)
                raise ConnectionLost(self.device, "connect", str(e)) from e
            self._ser = ser
            self._buf.clear()
            self.log.info("%s: link open (%s)", self.device, self.port_url)

    def close(self) -> None:
        """Close the link (idempotent)."""
        with self._lock:
            ser, self._ser = self._ser, None
            self._buf.clear()
            if ser is not None:
                self.log.info("%s: link closed", self.device)
                # pyserial's socket:// handler skips close() when shutdown() fails
                # (peer already gone) and then sleeps 0.3 s "for quick reconnects":
                # close its socket ourselves and mark it closed first.
                sock = getattr(ser, "_socket", None)
                if sock is not None:
                    with contextlib.suppress(OSError):
                        sock.shutdown(socket.SHUT_RDWR)
                    sock.close()
                    ser._socket = None  # type: ignore[attr-defined]  # socket:// handler's
                    ser.is_open = False
                with contextlib.suppress(serial.SerialException, OSError):
                    ser.close()

    def _require(self, command: str) -> serial.SerialBase:
        if self._ser is None:
            raise ConnectionLost(self.device, command, "not connected")
        return self._ser

    def write_line(self, line: str, command: str, timeout: float = 1.0) -> None:
        """Send ``line`` + ``\\n``; ``command`` names the request in errors."""
        with self._lock:
            ser = self._require(command)
            self.log.debug("%s: > %s", self.device, line)
            try:
                ser.write_timeout = max(timeout, 1e-3)
                ser.write(line.encode("ascii") + b"\n")
                ser.flush()
            except serial.SerialTimeoutException as e:
                self.log.info("%s: %s: write timed out: %s", self.device, command, e)
                raise CommandTimeout(self.device, command, f"write timed out: {e}") from e
            except (serial.SerialException, OSError) as e:
                self.log.info("%s: %s: write failed: %s", self.device, command, e)
                self.close()
                raise ConnectionLost(self.device, command, f"write failed: {e}") from e

    def _read_raw(self, deadline: float, command: str) -> str | None:
        """One line (any kind) or None when the deadline passes first."""
        ser = self._require(command)
        while True:
            nl = self._buf.find(b"\n")
            if nl >= 0:
                raw = bytes(self._buf[:nl])
                del self._buf[: nl + 1]
                try:
                    text = raw.decode("ascii").strip("\r").strip()
                except UnicodeDecodeError as e:
                    self.log.info("%s: %s: garbage %r", self.device, command, raw[:80])
                    raise ProtocolError(self.device, command, f"garbage reply {raw[:40]!r}") from e
                if any(ord(c) < 32 for c in text):
                    self.log.info("%s: %s: garbage %r", self.device, command, raw[:80])
                    raise ProtocolError(self.device, command, f"garbage reply {raw[:40]!r}")
                self.log.debug("%s: < %s", self.device, text)
                return text
            if len(self._buf) > MAX_LINE:
                self._buf.clear()
                self.log.info("%s: %s: line longer than %d bytes", self.device, command,
                              MAX_LINE)
                raise ProtocolError(self.device, command, f"line longer than {MAX_LINE} bytes")
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            try:
                # wait for one byte, then take everything that has arrived without waiting
                # (pyserial's socket:// in_waiting says 1 for "some", not how many)
                ser.timeout = min(left, 0.5)
                chunk = ser.read(1)
                if chunk:
                    ser.timeout = 0
                    chunk += ser.read(MAX_LINE)
            except (serial.SerialException, OSError) as e:
                self.log.info("%s: %s: link lost: %s", self.device, command, e)
                self.close()
                raise ConnectionLost(self.device, command, f"link closed: {e}") from e
            self._buf.extend(chunk)

    def read_reply(self, deadline: float, command: str) -> str:
        """Next line that is not an event; events are queued with their arrival time.

        Raises CommandTimeout at ``deadline`` (a ``time.monotonic`` value).
        """
        with self._lock:
            while True:
                line = self._read_raw(deadline, command)
                if line is None:
                    self.log.info("%s: %s: no reply in time", self.device, command)
                    raise CommandTimeout(self.device, command, "no reply in time")
                if line.startswith("EVT"):
                    self.events.append((time.time(), line[3:].strip()))
                    continue
                if line:
                    return line

    def poll_events(self, timeout: float = 0.0) -> None:
        """Read pending lines for up to ``timeout`` s, queueing events.

        A reply that arrives while nothing was asked is stale and dropped.
        """
        deadline = time.monotonic() + timeout
        with self._lock:
            while True:
                line = self._read_raw(deadline, "poll")
                if line is None:
                    return
                if line.startswith("EVT"):
                    self.events.append((time.time(), line[3:].strip()))

    def discard_input(self, settle_s: float = 0.02) -> None:
        """Throw away replies the device sent but nobody read (after a timeout).

        Reads for ``settle_s``; events among them are still queued.
        """
        deadline = time.monotonic() + settle_s
        with self._lock:
            while self._ser is not None:
                try:
                    line = self._read_raw(deadline, "resync")
                except ProtocolError:
                    continue
                except ConnectionLost:
                    return
                if line is None:
                    break
                if line.startswith("EVT"):
                    self.events.append((time.time(), line[3:].strip()))
            self._buf.clear()


def parse_kv(tokens: list[str], device: str, command: str) -> dict[str, str]:
    """``["x=1.0", "n=5"]`` → ``{"x": "1.0", "n": "5"}``; anything else is a ProtocolError."""
    out = {}
    for tok in tokens:
        key, sep, val = tok.partition("=")
        if not sep or not key:
            raise ProtocolError(device, command, f"expected key=value, got {tok!r}")
        out[key] = val
    return out


class LineSession:
    """Request/reply over a :class:`LineTransport` for ``OK <KW> ...`` / ``ERR <code> <NAME>``
    protocols.

    Every reply echoes its command's keyword (``MEAS`` → ``OK MEAS ...``), so a
    late reply to an earlier, timed-out command is recognised and dropped.
    After a timeout or garbage the session resynchronises before the next
    command: a socket is reopened, a serial line drained. Idempotent queries
    are retried once after a lost connection (reconnect + handshake) when time
    is left.

    Parameters
    ----------
    transport : LineTransport
    error_map : dict
        ERR name → error class; unknown names raise ``default_error``.
    handshake : callable(deadline) or None
        Called after every (re)connect, e.g. to send ``HELLO``.
    default_error : type
        Error class for ERR names missing from ``error_map``.
    """

    def __init__(
        self, transport: LineTransport, error_map: dict[str, type[DriverError]],
        handshake: Callable[[float], None] | None = None,
        default_error: type[DriverError] | None = None,
    ) -> None:
        self.t = transport
        self.error_map = error_map
        self.handshake = handshake
        self.default_error = default_error or DriverError
        self._dirty = False
        self._lock = threading.RLock()

    @property
    def device(self) -> str:
        return self.t.device

    def connect(self, timeout: float) -> None:
        """Open the link and run the handshake, all within ``timeout`` s."""
        deadline = time.monotonic() + timeout
        with self._lock:
            self.t.open(timeout)
            self._dirty = False
            if self.handshake is not None:
                try:
                    self.handshake(deadline)
                except BaseException:
                    self.t.close()
                    raise

    @property
    def log(self) -> logging.Logger:
        return self.t.log

    def _resync(self, deadline: float) -> None:
        if not self._dirty:
            return
        self.log.info("%s: resynchronising after a timeout or garbage (%s)", self.device,
                      "reconnecting" if self.t.is_socket else "draining the line")
        if self.t.is_socket:
            self.connect(max(deadline - time.monotonic(), 0.05))
        else:
            self.t.discard_input()
        self._dirty = False

    def exchange(
        self, line: str, keyword: str, deadline: float, *, retry: bool = False
    ) -> list[str]:
        """Send ``line``, return the tokens after ``OK <keyword>``.

        Parameters
        ----------
        line : str
            The request.
        keyword : str
            The keyword its ``OK`` reply echoes.
        deadline : float
            ``time.monotonic()`` value by which the reply must be in.
        retry : bool
            Idempotent query: after a lost connection reconnect once and retry.
        """
        command = line.split(" ", 1)[0]
        with self._lock:
            was_open = self.t.is_open  # never reopen a link the caller closed
            try:
                return self._exchange_once(line, keyword, command, deadline)
            except ConnectionLost:
                if not (retry and was_open) or time.monotonic() >= deadline:
                    raise
            # one automatic reconnect for idempotent queries
            self.log.info("%s: %s: connection lost, reconnecting to retry once", self.device,
                          command)
            self.connect(max(deadline - time.monotonic(), 0.05))
            return self._exchange_once(line, keyword, command, deadline)

    def _exchange_once(self, line: str, keyword: str, command: str, deadline: float) -> list[str]:
        if not self.t.is_open:
            raise ConnectionLost(self.device, command, "not connected")
        self._resync(deadline)
        self.t.write_line(line, command, max(deadline - time.monotonic(), 0.01))
        while True:
            try:
                reply = self.t.read_reply(deadline, command)
            except (CommandTimeout, ProtocolError):
                self._dirty = True
                raise
            tokens = reply.split()
            if tokens[0] == "OK":
                if len(tokens) >= 2 and tokens[1] == keyword:
                    return tokens[2:]
                self.log.debug("%s: late reply to an earlier command dropped", self.device)
                continue  # a late reply to an earlier command
            if tokens[0] == "ERR":
                self.log.info("%s: %s refused: %s", self.device, command, reply)
                raise self._error(tokens, reply, command)
            self._dirty = True
            self.log.info("%s: %s: unexpected reply %r", self.device, command, reply[:80])
            raise ProtocolError(self.device, command, f"unexpected reply {reply[:80]!r}")

    def _error(self, tokens: list[str], reply: str, command: str) -> Exception:
        if len(tokens) < 3 or not tokens[1].isdigit():
            self._dirty = True
            return ProtocolError(self.device, command, f"malformed error reply {reply[:80]!r}")
        cls = self.error_map.get(tokens[2], self.default_error)
        return cls(self.device, command, reply)
