"""Helpers for RTDE tests: loopback addresses, a scripted RTDE client (transcript tests)."""

from __future__ import annotations

import contextlib
import itertools
import os
import select
import socket
import struct
import time

from sim_drivers import rtde_wire as w

_counter = itertools.count(1)


@contextlib.contextmanager
def receive_client(host: str, *args):
    """The real ``rtde_receive.RTDEReceiveInterface``, disconnected on exit."""
    import rtde_receive

    rx = rtde_receive.RTDEReceiveInterface(host, *args)
    try:
        yield rx
    finally:
        rx.disconnect()


def loopback_host() -> str:
    """A fresh 127.x.y.z per call (per process), so parallel servers on 30004 rarely clash."""
    k = next(_counter)
    return f"127.{50 + os.getpid() % 150}.{k // 250}.{1 + k % 250}"


def recv_message(sock: socket.socket, timeout: float) -> tuple[int, bytes]:
    """Read one RTDE message; raise TimeoutError when none arrives within ``timeout``."""
    deadline = time.monotonic() + timeout
    buf = b""

    def need(n: int) -> bytes:
        nonlocal buf
        while len(buf) < n:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([sock], [], [], left)[0]:
                raise TimeoutError("no RTDE reply")
            chunk = sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("server closed the connection")
            buf += chunk
        out, buf = buf[:n], buf[n:]
        return out

    size, kind = w.HEADER.unpack(need(3))
    return kind, need(size - 3)


class RtdeTranscript:
    """Plays scripted requests against an RTDE server and checks each reply.

    ``exchanges`` is a list of ``(type, payload, expected_type, expected_payload)``;
    ``expected_payload`` may be bytes or a predicate. Data packages that arrive
    while a control reply is awaited are collected in :attr:`data` (streaming is
    not part of the dialogue). :meth:`play` raises ``AssertionError`` naming the
    first exchange left unused (no reply, or a different one) and when the
    server says anything unexpected after the last exchange.
    """

    def __init__(self, host: str, exchanges, timeout: float = 1.0) -> None:
        self.host = host
        self.exchanges = list(exchanges)
        self.timeout = timeout
        self.data: list[bytes] = []
        self.used = 0

    def play(self) -> None:
        with socket.create_connection((self.host, w.RTDE_PORT), timeout=self.timeout) as sock:
            for i, (kind, payload, want_kind, want) in enumerate(self.exchanges):
                sock.sendall(w.message(kind, payload))
                try:
                    got_kind, got = self._reply(sock)
                except (TimeoutError, ConnectionError) as e:
                    raise AssertionError(f"exchange {i} ({chr(kind)!r}) unused: {e}") from None
                assert got_kind == want_kind, (
                    f"exchange {i}: expected {chr(want_kind)!r}, got {chr(got_kind)!r} {got!r}")
                ok = want(got) if callable(want) else got == want
                assert ok, f"exchange {i} ({chr(kind)!r}): unexpected reply {got!r}"
                self.used += 1
            self._expect_silence(sock)

    def _reply(self, sock):
        while True:
            kind, payload = recv_message(sock, self.timeout)
            if kind != w.DATA_PACKAGE:
                return kind, payload
            self.data.append(payload)

    def _expect_silence(self, sock) -> None:
        end = time.monotonic() + 0.1
        while (left := end - time.monotonic()) > 0:
            try:
                kind, payload = recv_message(sock, left)
            except TimeoutError:
                return
            if kind != w.DATA_PACKAGE:
                raise AssertionError(f"unexpected {chr(kind)!r} {payload!r} after the transcript")
            self.data.append(payload)


def setup_outputs(frequency: float, names: list[str]) -> bytes:
    """SETUP_OUTPUTS payload as ur-rtde sends it (trailing comma included)."""
    return struct.pack(">d", frequency) + "".join(n + "," for n in names).encode()
