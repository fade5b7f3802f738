"""The RTDE server's child process: accepts clients on port 30004 and streams robot state.

It runs in its own process because the ur-rtde constructors hold the GIL while
they wait for the first data package: a server thread in the same interpreter
would never get to send it. It is started as ``python -m sim_drivers.rtde_child``
(standard library only, so it starts in tens of milliseconds, and no
``if __name__ == "__main__"`` guard is needed in the caller's script).

Parent and child share one :class:`SharedBlock` (an unlinked temporary file,
memory-mapped by both, its descriptor passed to the child):

``ctl`` doubles (flags and counters)
    ``STOP`` asks the child to exit; ``FREEZE`` keeps streaming but with a
    frozen timestamp and frozen values (a hung controller); ``SILENT`` stops
    data packages while keeping the connections (a dead link). The child
    writes ``CLIENTS`` (connected clients), ``PACKAGES`` (data-package rounds
    sent) and ``FREQUENCY`` (the frequency the last client asked for, Hz).
``state`` doubles (written by the parent, read by the child under a sequence lock)
    Element 0 is even when the block is consistent: the writer makes it odd,
    writes, and makes it even again. The rest follows :data:`STATE_FIELDS`, in
    controller units (rad, m, rad/s, m/s).

On start the child prints one line to stdout, ``ok <host>`` or ``error <why>``,
and then never writes to stdout again. It exits when ``STOP`` is set or when
its parent dies.
"""

from __future__ import annotations

import argparse
import contextlib
import mmap
import os
import selectors
import socket
import struct
import sys
import tempfile
import time

from sim_drivers import rtde_wire as w

#: layout of the shared state block: name -> (offset, length), offsets in doubles
STATE_FIELDS: dict[str, tuple[int, int]] = {}
_offset = 1
for _name, _n in (
    ("robot_mode", 1), ("safety_mode", 1), ("safety_status_bits", 1), ("runtime_state", 1),
    ("robot_status_bits", 1), ("speed_scaling", 1), ("actual_q", 6), ("actual_qd", 6),
    ("target_q", 6), ("actual_TCP_pose", 6), ("target_TCP_pose", 6), ("actual_TCP_speed", 6),
    ("joint_temperatures", 6),
):
    STATE_FIELDS[_name] = (_offset, _n)
    _offset += _n
STATE_SIZE = _offset

STOP, FREEZE, SILENT, CLIENTS, PACKAGES, FREQUENCY = range(6)
CTL_SIZE = 8

#: largest backlog (bytes) kept for a client that stops reading before it is dropped
MAX_BACKLOG = 1 << 20


class SharedBlock:
    """``CTL_SIZE`` control doubles then ``STATE_SIZE`` state doubles in shared memory.

    Parameters
    ----------
    fd : int, optional
        Descriptor of an existing block (in the child); without it a new
        block is created (in the parent) and :meth:`fileno` is passed on.
    """

    SIZE = 8 * (CTL_SIZE + STATE_SIZE)
    _STATE = struct.Struct(f"<{STATE_SIZE}d")

    def __init__(self, fd: int | None = None) -> None:
        self._file = None
        if fd is None:
            self._file = tempfile.TemporaryFile()  # noqa: SIM115 - lives as long as the block
            self._file.truncate(self.SIZE)
            fd = self._file.fileno()
        self._mm = mmap.mmap(fd, self.SIZE)

    def fileno(self) -> int:
        return self._file.fileno()

    def close(self) -> None:
        self._mm.close()
        if self._file is not None:
            self._file.close()

    def ctl(self, i: int) -> float:
        return struct.unpack_from("<d", self._mm, 8 * i)[0]

    def set_ctl(self, i: int, value: float) -> None:
        struct.pack_into("<d", self._mm, 8 * i, float(value))

    def _seq(self) -> float:
        return struct.unpack_from("<d", self._mm, 8 * CTL_SIZE)[0]

    def read_state(self) -> dict[str, object]:
        """A consistent snapshot of the state (sequence lock; the writer is another process)."""
        for _ in range(10000):
            vals = self._STATE.unpack_from(self._mm, 8 * CTL_SIZE)
            if int(vals[0]) % 2 == 0 and self._seq() == vals[0]:
                break
            time.sleep(0)
        out: dict[str, object] = {}
        for name, (off, n) in STATE_FIELDS.items():
            out[name] = vals[off] if n == 1 else list(vals[off:off + n])
        return out

    def write_state(self, fields: dict[str, object]) -> None:
        """Write some state fields (one writer at a time: the caller serialises writers)."""
        base = 8 * CTL_SIZE
        seq = self._seq()
        struct.pack_into("<d", self._mm, base, seq + 1)
        for name, value in fields.items():
            off, n = STATE_FIELDS[name]
            vals = [float(value)] if n == 1 else [float(x) for x in value]
            struct.pack_into(f"<{n}d", self._mm, base + 8 * off, *vals)
        struct.pack_into("<d", self._mm, base, seq + 2)


def variable_value(name: str, kind: str, st: dict, timestamp: float):
    """The value the simulated controller reports for one output variable."""
    if name == "timestamp":
        return timestamp
    if name in st:
        value = st[name]
        return int(value) if kind in ("INT32", "UINT32", "UINT64", "UINT8") else value
    zeros6 = [0.0] * 6
    derived = {
        "target_qd": st["actual_qd"],
        "target_TCP_speed": st["actual_TCP_speed"],
        "target_qdd": zeros6,
        "actual_joint_voltage": [48.0] * 6,
        "actual_main_voltage": 48.0,
        "actual_robot_voltage": 48.0,
        "actual_robot_current": 0.5,
        "actual_execution_time": 0.2,
        "target_speed_fraction": 1.0,
        "safety_status": int(st["safety_mode"]),
        "joint_mode": [253] * 6,  # JOINT_RUNNING_MODE
        "actual_tool_accelerometer": [0.0, 0.0, -9.81],
    }
    if name in derived:
        return derived[name]
    if kind == "VECTOR3D":
        return [0.0] * 3
    if kind == "VECTOR6D":
        return zeros6
    if kind in ("VECTOR6INT32", "VECTOR6UINT32"):
        return [0] * 6
    if kind == "BOOL":
        return False
    return 0.0 if kind == "DOUBLE" else 0


class Client:
    """One connected RTDE client: its buffers, recipes and streaming schedule."""

    def __init__(self, sock: socket.socket, max_frequency: float) -> None:
        self.sock = sock
        self.inbuf = bytearray()
        self.outbuf = bytearray()
        self.max_frequency = max_frequency
        self.outputs: dict[int, list[tuple[str, str]]] = {}
        self.inputs: dict[int, list[str]] = {}
        self.period = 1.0 / max_frequency
        self.started = False
        self.next_due = 0.0
        self.next_recipe = 1
        self.frequency = 0.0

    def send(self, data: bytes) -> None:
        self.outbuf += data

    def handle(self, kind: int, payload: bytes, version: tuple[int, int, int, int]) -> None:
        """Answer one client message (control packages) or absorb it (input data)."""
        if kind == w.REQUEST_PROTOCOL_VERSION:
            asked = struct.unpack(">H", payload[:2])[0] if len(payload) >= 2 else 0
            self.send(w.message(kind, bytes([asked == w.PROTOCOL_VERSION])))
        elif kind == w.GET_URCONTROL_VERSION:
            self.send(w.message(kind, struct.pack(">IIII", *version)))
        elif kind == w.CONTROL_PACKAGE_SETUP_OUTPUTS:
            self._setup_outputs(payload)
        elif kind == w.CONTROL_PACKAGE_SETUP_INPUTS:
            names = w.parse_names(payload)
            types = [w.INPUT_TYPES.get(n, "NOT_FOUND") for n in names]
            rid = 0
            if names and "NOT_FOUND" not in types:
                rid = self.next_recipe
                self.next_recipe += 1
                self.inputs[rid] = types
            self.send(w.message(kind, bytes([rid]) + ",".join(types).encode()))
        elif kind == w.CONTROL_PACKAGE_START:
            ok = bool(self.outputs or self.inputs)
            self.send(w.message(kind, bytes([ok])))
            if ok and not self.started:
                self.started = True
                self.next_due = time.monotonic()
        elif kind == w.CONTROL_PACKAGE_PAUSE:
            self.started = False
            self.send(w.message(kind, b"\x01"))
        elif kind == w.DATA_PACKAGE:
            rid = payload[0] if payload else 0
            if rid not in self.inputs:
                self.send(w.text_message(f"data package for unknown input recipe {rid}"))
        elif kind == w.TEXT_MESSAGE:
            pass
        else:
            self.send(w.text_message(f"unknown RTDE package type {kind}"))

    def _setup_outputs(self, payload: bytes) -> None:
        if len(payload) < 8:
            self.send(w.text_message("SETUP_OUTPUTS without frequency"))
            self.send(w.message(w.CONTROL_PACKAGE_SETUP_OUTPUTS, b"\x00"))
            return
        frequency = struct.unpack(">d", payload[:8])[0]
        names = w.parse_names(payload[8:])
        types = [w.OUTPUT_TYPES.get(n, "NOT_FOUND") for n in names]
        rid = 0
        if names and "NOT_FOUND" not in types and 0 < frequency <= self.max_frequency:
            rid = self.next_recipe
            self.next_recipe += 1
            self.outputs[rid] = list(zip(names, types, strict=True))
            self.period = 1.0 / frequency
        elif not 0 < frequency <= self.max_frequency:
            self.send(w.text_message(f"frequency {frequency} Hz outside (0, {self.max_frequency}]"))
        self.frequency = frequency
        reply = bytes([rid]) + ",".join(types).encode()
        self.send(w.message(w.CONTROL_PACKAGE_SETUP_OUTPUTS, reply))

    def data_packages(self, st: dict, timestamp: float) -> bytes:
        out = bytearray()
        for rid, recipe in self.outputs.items():
            body = bytearray([rid])
            for name, kind in recipe:
                body += w.pack_value(kind, variable_value(name, kind, st, timestamp))
            out += w.message(w.DATA_PACKAGE, bytes(body))
        return bytes(out)


def bind_first(hosts, port: int) -> socket.socket:
    """Listen on the first of ``hosts`` where ``port`` is free; raise OSError naming them all."""
    errors = []
    for host in hosts:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind((host, port))
            sock.listen(8)
            sock.setblocking(False)
            return sock
        except OSError as e:
            sock.close()
            errors.append(f"{host}: {e.strerror or e}")
    raise OSError(f"RTDE simulator: port {port} unavailable on " + "; ".join(errors))


def serve(hosts, port, block: SharedBlock, max_frequency=500.0, version=(5, 11, 1, 0)) -> int:
    """Bind, report ``ok <host>`` / ``error <why>`` on stdout, then serve until told to stop.

    Returns the process exit status: 0 after a stop, 2 when no address was free.
    """
    try:
        listener = bind_first(hosts, port)
    except OSError as e:
        print("error", e, flush=True)
        return 2
    print("ok", listener.getsockname()[0], flush=True)
    parent = os.getppid()
    sel = selectors.DefaultSelector()
    sel.register(listener, selectors.EVENT_READ, None)
    clients: dict[socket.socket, Client] = {}
    t0 = time.monotonic()
    frozen: tuple[dict, float] | None = None

    def drop(sock: socket.socket) -> None:
        with contextlib.suppress(KeyError, ValueError):
            sel.unregister(sock)
        clients.pop(sock, None)
        sock.close()
        block.set_ctl(CLIENTS, len(clients))

    try:
        while not block.ctl(STOP) and os.getppid() == parent:
            now = time.monotonic()
            due = [c.next_due for c in clients.values() if c.started]
            wait = min([0.01] + [max(0.0, d - now) for d in due])
            for key, _ in sel.select(wait):
                if key.data is None:
                    with contextlib.suppress(BlockingIOError):
                        sock, _addr = listener.accept()
                        sock.setblocking(False)
                        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                        clients[sock] = Client(sock, max_frequency)
                        sel.register(sock, selectors.EVENT_READ, "client")
                        block.set_ctl(CLIENTS, len(clients))
                    continue
                _read(key.fileobj, clients, version, drop, block)
            now = time.monotonic()
            if block.ctl(FREEZE):
                if frozen is None:
                    frozen = (block.read_state(), now - t0)
            else:
                frozen = None
            snapshot = None
            silent = block.ctl(SILENT)
            for sock, c in list(clients.items()):
                if c.started and now >= c.next_due and not silent and c.outputs:
                    if snapshot is None:
                        snapshot = frozen or (block.read_state(), now - t0)
                    c.send(c.data_packages(*snapshot))
                    block.set_ctl(PACKAGES, block.ctl(PACKAGES) + 1)
                    c.next_due += c.period
                    if c.next_due < now - c.period:  # fell behind: do not burst
                        c.next_due = now + c.period
                if c.outbuf and not _flush(c):
                    drop(sock)
    finally:
        for sock in list(clients):
            drop(sock)
        sel.close()
        listener.close()
    return 0


def _read(sock, clients, version, drop, block: SharedBlock) -> None:
    c = clients.get(sock)
    if c is None:
        return
    try:
        data = sock.recv(65536)
    except BlockingIOError:
        return
    except OSError:
        drop(sock)
        return
    if not data:
        drop(sock)
        return
    c.inbuf += data
    try:
        for kind, payload in w.split_messages(c.inbuf):
            c.handle(kind, payload, version)
            if kind == w.CONTROL_PACKAGE_SETUP_OUTPUTS and len(payload) >= 8:
                block.set_ctl(FREQUENCY, struct.unpack(">d", payload[:8])[0])
    except (ValueError, struct.error) as e:
        c.send(w.text_message(f"bad RTDE message: {e}", level=w.EXCEPTION_MESSAGE))
        _flush(c)
        drop(sock)


def _flush(c: Client) -> bool:
    """Send what the socket takes now; False when the client is gone or too far behind."""
    try:
        n = c.sock.send(c.outbuf)
        del c.outbuf[:n]
    except BlockingIOError:
        pass
    except OSError:
        return False
    return len(c.outbuf) <= MAX_BACKLOG


def main(argv=None) -> int:
    """``python -m sim_drivers.rtde_child --fd N --hosts a,b [--port P] ...``"""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fd", type=int, required=True, help="shared block descriptor")
    ap.add_argument("--hosts", required=True, help="comma-separated addresses to try")
    ap.add_argument("--port", type=int, default=w.RTDE_PORT)
    ap.add_argument("--max-frequency", type=float, default=500.0)
    ap.add_argument("--version", default="5.11.1.0", help="controller version a.b.c.d")
    a = ap.parse_args(argv)
    block = SharedBlock(a.fd)
    os.close(a.fd)
    version = tuple(int(x) for x in a.version.split("."))
    try:
        return serve(a.hosts.split(","), a.port, block, a.max_frequency, version)
    finally:
        block.close()


if __name__ == "__main__":
    sys.exit(main())
