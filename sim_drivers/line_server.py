"""A line-protocol server on a background thread, over TCP or a pseudo-terminal.

Shared by the tracker and the line-robot simulators. The protocol itself is a
*session* object built per connection: ``session.handle(line) -> list[str]``
returns the reply lines. This module adds transport and faults: per command
it consults the :class:`~sim_drivers.faults.FaultInjector` for ``drop`` (close
the connection, TCP only), ``slow`` (hold the reply back) and ``garbage``
(random bytes instead of the reply).

A binary protocol reuses the transport by overriding :meth:`LineServer._framer`
(what cuts the byte stream into requests) and :attr:`LineServer.GARBAGE`; its
sessions return ``bytes`` replies, sent as they are. ``chunk_bytes`` > 0
sends every reply in pieces of that many bytes (a slow or fragmenting link).

``start()``/``stop()`` (or ``with``) leave no thread, socket or fd behind.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import socket
import threading
import tty
from collections.abc import Callable

import numpy as np

from sim_drivers.faults import FaultInjector

log = logging.getLogger(__name__)

#: the bytes a ``garbage`` fault sends (no newline inside, one at the end)
GARBAGE = bytes([0x8F, 0x00, 0xFF, 0x1B, 0x23, 0x40, 0xC3, 0x28, 0x07, 0xFE]) + b"\n"


class _Conn:
    """One client link: a socket or the pty master fd."""

    def __init__(self, sock: socket.socket | None = None, fd: int | None = None) -> None:
        self.sock, self.fd = sock, fd
        self.wlock = threading.Lock()
        self.closed = False

    def fileno(self) -> int:
        return self.sock.fileno() if self.sock is not None else int(self.fd)

    def recv(self) -> bytes:
        if self.sock is not None:
            return self.sock.recv(4096)
        return os.read(self.fd, 4096)

    def send(self, data: bytes) -> None:
        with self.wlock:
            if self.closed:
                return
            if self.sock is not None:
                self.sock.sendall(data)
            else:
                view = memoryview(data)
                while view:
                    n = os.write(self.fd, view)
                    view = view[n:]

    def close(self) -> None:
        with self.wlock:
            if self.closed:
                return
            self.closed = True
            if self.sock is not None:
                with contextlib.suppress(OSError):
                    self.sock.shutdown(socket.SHUT_RDWR)
                self.sock.close()


class LineFramer:
    """Cuts a byte stream into stripped, non-empty ASCII lines."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[str]:
        self._buf.extend(data)
        out = []
        while (nl := self._buf.find(b"\n")) >= 0:
            raw = bytes(self._buf[:nl])
            del self._buf[: nl + 1]
            line = raw.decode("ascii", "replace").strip()
            if line:
                out.append(line)
        return out


class LineServer:
    """Serve a line protocol on loopback TCP (``transport="tcp"``) or a pty (``"pty"``).

    Parameters
    ----------
    session_factory : callable() -> session
        Builds the per-connection protocol state; ``session.handle(line)``
        returns reply lines (without newlines).
    faults : FaultInjector or None
        Consulted once per command.
    host, port : str, int
        TCP address; port 0 picks a free one (see :attr:`port`).
    transport : {"tcp", "pty"}
    name : str
        Thread-name prefix.
    """

    #: what a ``garbage`` fault sends instead of the reply
    GARBAGE = GARBAGE

    def __init__(
        self,
        session_factory: Callable[[], object],
        *,
        faults: FaultInjector | None = None,
        host: str = "127.0.0.1",
        port: int = 0,
        transport: str = "tcp",
        name: str = "line-server",
    ) -> None:
        if transport not in ("tcp", "pty"):
            raise ValueError(f"transport must be 'tcp' or 'pty', got {transport!r}")
        self.session_factory = session_factory
        self.faults = faults if faults is not None else FaultInjector()
        self.host, self.port = host, port
        self.transport = transport
        self.name = name
        self.pty_path = ""
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._conns: list[_Conn] = []
        self._lock = threading.Lock()
        self._listener: socket.socket | None = None
        self._master = self._slave = -1
        self._rng = np.random.default_rng(0)
        #: > 0: send replies in pieces of this many bytes (tests of reassembly)
        self.chunk_bytes = 0

    # ------------------------------------------------------------- lifecycle
    def start(self) -> LineServer:
        """Bind and start serving; returns self."""
        self._stop.clear()
        if self.transport == "tcp":
            ls = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            ls.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                ls.bind((self.host, self.port))
            except OSError:
                ls.close()
                raise
            ls.listen(8)
            self._listener = ls
            self.port = ls.getsockname()[1]
            self._spawn(self._accept_loop, "accept")
        else:
            self._master, self._slave = os.openpty()
            tty.setraw(self._slave)
            self.pty_path = os.ttyname(self._slave)
            conn = _Conn(fd=self._master)
            self._conns.append(conn)
            self._spawn(lambda: self._serve(conn), "pty")
        return self

    def stop(self) -> None:
        """Stop serving, close every connection and join every thread."""
        self._stop.set()
        if self._listener is not None:
            self._listener.close()
            self._listener = None
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            if c.sock is not None:
                c.close()
        for t in self._threads:
            t.join(timeout=5.0)
        self._threads.clear()
        with self._lock:
            self._conns.clear()
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    def __enter__(self) -> LineServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()

    @property
    def address(self) -> str:
        """``host:port`` for TCP, the slave device path for a pty."""
        return f"{self.host}:{self.port}" if self.transport == "tcp" else self.pty_path

    def _spawn(self, target, what: str) -> None:
        t = threading.Thread(target=target, name=f"{self.name}-{what}", daemon=True)
        self._threads.append(t)
        t.start()

    # ---------------------------------------------------------------- events
    def broadcast(self, line: str) -> None:
        """Send an unsolicited line (``EVT ...``) to every connected client."""
        with self._lock:
            conns = list(self._conns)
        for c in conns:
            with contextlib.suppress(OSError):
                self.send(c, [line])

    def drop_all(self) -> None:
        """Close every client connection now (TCP), as a crashing server would."""
        with self._lock:
            conns = [c for c in self._conns if c.sock is not None]
        for c in conns:
            c.close()

    # ----------------------------------------------------------------- loops
    def _accept_loop(self) -> None:
        ls = self._listener
        while not self._stop.is_set() and ls is not None:
            try:
                r, _, _ = select.select([ls], [], [], 0.05)
                if not r:
                    continue
                sock, addr = ls.accept()
            except (OSError, ValueError):
                return
            log.info("%s: a client connected from %s", type(self).__name__, addr)
            # replies may go out in several sends (an answer, then a result): no Nagle delay
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            conn = _Conn(sock=sock)
            with self._lock:
                self._conns = [c for c in self._conns if not c.closed]
                self._conns.append(conn)
                self._threads = [t for t in self._threads if t.is_alive()]
            self._spawn(lambda c=conn: self._serve(c), "conn")

    def _serve(self, conn: _Conn) -> None:
        session = self.session_factory()
        if hasattr(session, "bind"):
            session.bind(self, conn)
        framer = self._framer()
        try:
            while not self._stop.is_set() and not conn.closed:
                try:
                    r, _, _ = select.select([conn], [], [], 0.05)
                except (OSError, ValueError):
                    return
                if not r:
                    continue
                try:
                    data = conn.recv()
                except OSError:
                    if conn.sock is None:  # pty: no client has the slave open yet
                        self._stop.wait(0.05)
                        continue
                    return
                if not data:
                    if conn.sock is None:
                        self._stop.wait(0.05)
                        continue
                    return
                try:
                    requests = framer.feed(data)
                except ValueError:  # the client's stream cannot be cut into requests
                    return
                for request in requests:
                    if not self._command(conn, session, request):
                        return
        finally:
            if conn.sock is not None:
                conn.close()

    def _framer(self):
        """A fresh per-connection object whose ``feed(bytes)`` returns whole requests."""
        return LineFramer()

    def send(self, conn: _Conn, replies: list) -> None:
        """Send replies (str lines get a newline, bytes go as they are) as one buffer,
        in ``chunk_bytes`` pieces when set. Raises OSError when the link is gone."""
        data = b"".join(r if isinstance(r, bytes) else r.encode("ascii", "replace") + b"\n"
                        for r in replies)
        if self.chunk_bytes <= 0:
            conn.send(data)
            return
        for k in range(0, len(data), self.chunk_bytes):
            conn.send(data[k:k + self.chunk_bytes])
            if self._stop.wait(0.001):
                return

    def _command(self, conn: _Conn, session, line) -> bool:
        """Handle one request; False when the connection must end."""
        f = self.faults
        f.begin_command()
        if conn.sock is not None and f.fires("drop"):
            conn.close()
            return False
        if f.fires("slow") and self._stop.wait(f.delay_s):
            return False
        if f.fires("garbage"):
            conn.send(self.GARBAGE)
            return True
        try:
            replies = session.handle(line)
        except Exception as e:  # a bug in a session must not kill the server silently
            replies = [self._internal_error(line, e)]
        try:
            self.send(conn, replies)
        except OSError:
            return False
        return True

    def _internal_error(self, request, e: Exception):
        """The reply to a request whose handling raised (a simulator bug)."""
        return f"ERR 99 INTERNAL {type(e).__name__}: {e}"
