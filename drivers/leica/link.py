"""A TCP link to an emScon server: packets out, decoded packets in, every read with a deadline.

:class:`PacketLink` owns the socket and a :class:`~drivers.leica.framing.FrameReader`.
It turns socket trouble into the driver errors: a refused or closed connection
is :class:`~drivers.errors.ConnectionLost`, bytes that are not emScon
:class:`~drivers.errors.ProtocolError`, nothing in time ``None`` from
:meth:`PacketLink.read` (the caller raises the timeout it means). After a
ProtocolError the stream has lost its alignment: the link closes itself.

Logging (``drivers.leica.link``): every packet sent and received at DEBUG, decoded (its
struct's name and fields; command, status and status change by their header names:
``> SetUnitsCT(command=ES_C_SetUnits, lenUnitType=0, ...)``); the link opened, closed
and lost and bytes that are not emScon at INFO.
"""

from __future__ import annotations

import collections
import contextlib
import logging
import socket
import time

from drivers.errors import ConnectionLost, ProtocolError
from drivers.leica.codec import DecodeError, Packet, UnknownPacket, decode
from drivers.leica.enums import ES_Command, ES_ResultStatus, ES_SystemStatusChange, name_of
from drivers.leica.framing import FrameReader, FramingError

log = logging.getLogger(__name__)

#: packet fields shown by their enum's names in the log
_NAMED = {"command": ES_Command, "status": ES_ResultStatus,
          "systemStatusChange": ES_SystemStatusChange}


class Shown:
    """A packet as the log shows it, formatted only when a record is written."""

    __slots__ = ("packet",)

    def __init__(self, packet: object) -> None:
        self.packet = packet

    def __str__(self) -> str:
        p = self.packet
        if not isinstance(p, Packet):
            return repr(p)
        parts = []
        for k, v in p.fields().items():
            if k in ("lPacketSize", "type"):
                continue
            if k in _NAMED and isinstance(v, int):
                v = name_of(_NAMED[k], v)
            elif isinstance(v, bytes):
                v = repr(v.decode("utf-16-le", "replace").split("\0", 1)[0])
            elif isinstance(v, float):
                v = f"{v:.10g}"
            parts.append(f"{k}={v}")
        return f"{type(p).__name__}({', '.join(parts)})"


class PacketLink:
    """One connection to ``host:port``; ``device`` names it in errors."""

    def __init__(self, host: str, port: int, device: str) -> None:
        self.host, self.port, self.device = host, int(port), device
        self._sock: socket.socket | None = None
        self._frames = FrameReader()
        self._ready: collections.deque[Packet | UnknownPacket] = collections.deque()

    @property
    def is_open(self) -> bool:
        return self._sock is not None

    def open(self, timeout: float) -> None:
        """(Re)connect within ``timeout`` s; ConnectionLost when that fails."""
        self.close()
        try:
            sock = socket.create_connection((self.host, self.port), timeout=max(timeout, 1e-3))
        except OSError as e:
            log.info("%s: cannot connect to %s:%d: %s", self.device, self.host, self.port, e)
            raise ConnectionLost(self.device, "connect", str(e)) from e
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock
        log.info("%s: link open (%s:%d)", self.device, self.host, self.port)

    def close(self) -> None:
        """Close the socket and forget buffered bytes (idempotent)."""
        sock, self._sock = self._sock, None
        self._frames.clear()
        self._ready.clear()
        if sock is not None:
            log.info("%s: link closed", self.device)
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()

    def _require(self, command: str) -> socket.socket:
        if self._sock is None:
            raise ConnectionLost(self.device, command, "not connected")
        return self._sock

    def send(self, packet: Packet, command: str, deadline: float) -> None:
        """Send one packet before ``deadline`` (a ``time.monotonic`` value)."""
        sock = self._require(command)
        log.debug("%s: > %s", self.device, Shown(packet))
        try:
            sock.settimeout(max(deadline - time.monotonic(), 1e-3))
            sock.sendall(packet.pack())
        except OSError as e:  # socket.timeout is an OSError too: the peer does not read
            log.info("%s: %s: send failed: %s", self.device, command, e)
            self.close()
            raise ConnectionLost(self.device, command, f"send failed: {e}") from e

    def read(self, deadline: float, command: str) -> Packet | UnknownPacket | None:
        """The next packet, or None when ``deadline`` passes first."""
        while not self._ready:
            sock = self._require(command)
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            try:
                sock.settimeout(left)
                data = sock.recv(65536)
            except TimeoutError:
                return None
            except OSError as e:
                log.info("%s: %s: link lost: %s", self.device, command, e)
                self.close()
                raise ConnectionLost(self.device, command, f"link closed: {e}") from e
            if not data:
                log.info("%s: %s: the server closed the connection", self.device, command)
                self.close()
                raise ConnectionLost(self.device, command, "the server closed the connection")
            try:
                self._ready.extend(decode(f, "client") for f in self._frames.feed(data))
            except (FramingError, DecodeError) as e:
                log.info("%s: %s: not emScon: %s", self.device, command, e)
                self.close()
                raise ProtocolError(self.device, command, f"not emScon: {e}") from e
        packet = self._ready.popleft()
        log.debug("%s: < %s", self.device, Shown(packet))
        return packet
