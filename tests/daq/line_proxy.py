"""A TCP proxy for the line protocols: what a bridge, a tunnel or a misbehaving device does.

Each client connection gets its own upstream connection; lines from the server pass
through ``transform(line) -> list[str]`` before they reach the client (return ``[line]``
to forward, ``[]`` to drop, anything else to replace). Fault injection decides by state
(the transform looks at the store or the simulated cell), never by counting lines.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
from collections.abc import Callable


class LineProxy:
    """Serve ``127.0.0.1:port``, forwarding to ``upstream`` (host, port)."""

    def __init__(self, upstream: tuple[str, int],
                 transform: Callable[[str], list[str]] | None = None) -> None:
        self.upstream = upstream
        self.transform = transform or (lambda line: [line])
        self._ls = socket.create_server(("127.0.0.1", 0))
        self.port = self._ls.getsockname()[1]
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._socks: list[socket.socket] = []
        self._lock = threading.Lock()

    def url(self, scheme: str) -> str:
        return f"{scheme}://127.0.0.1:{self.port}"

    def __enter__(self) -> LineProxy:
        self._spawn(self._accept)
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._ls.close()
        with self._lock:
            socks = list(self._socks)
        for s in socks:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()
        for t in self._threads:
            t.join(timeout=5)

    def _spawn(self, target, *args) -> None:
        t = threading.Thread(target=target, args=args, daemon=True, name="line-proxy")
        self._threads.append(t)
        t.start()

    def _accept(self) -> None:
        while not self._stop.is_set():
            try:
                r, _, _ = select.select([self._ls], [], [], 0.05)
                if not r:
                    continue
                client, _ = self._ls.accept()
                server = socket.create_connection(self.upstream, timeout=5)
            except (OSError, ValueError):
                return
            server.settimeout(None)
            with self._lock:
                self._socks += [client, server]
            self._spawn(self._pump, client, server, None)
            self._spawn(self._pump, server, client, self.transform)

    def _pump(self, src: socket.socket, dst: socket.socket, transform) -> None:
        buf = b""
        try:
            while not self._stop.is_set():
                r, _, _ = select.select([src], [], [], 0.05)
                if not r:
                    continue
                data = src.recv(4096)
                if not data:
                    break
                if transform is None:
                    dst.sendall(data)
                    continue
                buf += data
                *lines, buf = buf.split(b"\n")
                out = []
                for raw in lines:
                    out += transform(raw.decode("ascii", "replace").rstrip("\r"))
                if out:
                    dst.sendall("".join(f"{line}\n" for line in out).encode("ascii"))
        except (OSError, ValueError):
            pass
        finally:
            for s in (src, dst):
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)
