"""A TCP link to an emScon server: packets out, decoded packets in, every read with a deadline.

:class:`PacketLink` owns the socket and a :class:`~drivers.leica.framing.FrameReader`.
It turns socket trouble into the driver errors: a refused or closed connection
is :class:`~drivers.errors.ConnectionLost`, bytes that are not emScon
:class:`~drivers.errors.ProtocolError`, nothing in time ``None`` from
:meth:`PacketLink.read` (the caller raises the timeout it means). After a
ProtocolError the stream has lost its alignment: the link closes itself.
"""

from __future__ import annotations

import collections
import contextlib
import socket
import time

from drivers.errors import ConnectionLost, ProtocolError
from drivers.leica.codec import DecodeError, Packet, UnknownPacket, decode
from drivers.leica.framing import FrameReader, FramingError


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
            raise ConnectionLost(self.device, "connect", str(e)) from e
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock = sock

    def close(self) -> None:
        """Close the socket and forget buffered bytes (idempotent)."""
        sock, self._sock = self._sock, None
        self._frames.clear()
        self._ready.clear()
        if sock is not None:
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
        try:
            sock.settimeout(max(deadline - time.monotonic(), 1e-3))
            sock.sendall(packet.pack())
        except OSError as e:  # socket.timeout is an OSError too: the peer does not read
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
                self.close()
                raise ConnectionLost(self.device, command, f"link closed: {e}") from e
            if not data:
                self.close()
                raise ConnectionLost(self.device, command, "the server closed the connection")
            try:
                self._ready.extend(decode(f, "client") for f in self._frames.feed(data))
            except (FramingError, DecodeError) as e:
                self.close()
                raise ProtocolError(self.device, command, f"not emScon: {e}") from e
        return self._ready.popleft()
