"""Test helpers: a simulated cell factory and a scripted line-protocol peer (transcript tests)."""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time

from drivers.protocols import SixDof
from drivers.urls import open_tracker
from sim_drivers.cell import SimCell
from sim_drivers.faults import FaultInjector
from sim_drivers.model_truth import ModelTruth
from sim_drivers.six_dof import SixDofTarget
from sim_drivers.truth import ToyArm

#: slack allowed on top of a timeout before a call counts as hanging (s). These bounds
#: tell a hang from an answer; they are not speed targets, so they are wide enough that a
#: loaded 2-core machine (CI with other jobs) cannot break them.
MARGIN = 5.0


def make_cell(seed: int = 1, faults: str | None = None, **kw) -> SimCell:
    """A ToyArm cell with a fault injector (no faults unless ``faults`` is a spec)."""
    return SimCell(ToyArm(), seed=seed, faults=FaultInjector(faults, seed=seed), **kw)


def tmac_cell(seed: int, **kw) -> SimCell:
    """A UR10e cell (hidden errors of ``seed``) with a T-Mac on the tool (6-DoF target)."""
    return SimCell(ModelTruth.from_spec("ur10e", None, seed), seed=seed,
                   six_dof=SixDofTarget.on_tool(seed=seed), **kw)


def measure_pose_at(url: str, duration_s: float):
    """Open the tracker at ``url``, connect, measure one pose (it must be SixDof), close."""
    trk = open_tracker(url)
    try:
        trk.connect(2.0)
        assert isinstance(trk, SixDof)
        return trk.measure_pose(duration_s, 2.0)
    finally:
        trk.close()


@contextlib.contextmanager
def elapsed_below(limit: float):
    """Assert the ``with`` body finishes (normally or by raising) within ``limit`` seconds."""
    t0 = time.monotonic()
    try:
        yield
    finally:
        dt = time.monotonic() - t0
        assert dt < limit, f"took {dt:.3f} s, limit {limit:.3f} s"


class ScriptedPeer:
    """A device stand-in on a real TCP socket that follows a transcript.

    ``exchanges`` is a list of ``(expected_request, [reply lines])``. The peer
    accepts one connection, and for each line received checks it against the
    next expected request. :meth:`check` fails when a line arrived that was not
    expected, or an expected exchange went unused (PyMeasure's
    ``expected_protocol`` style).
    """

    def __init__(self, exchanges: list[tuple[str, list[str]]]) -> None:
        self.exchanges = list(exchanges)
        self.errors: list[str] = []
        self.used = 0
        self._ls = socket.create_server(("127.0.0.1", 0))
        self.port = self._ls.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="scripted-peer", daemon=True)

    def __enter__(self) -> ScriptedPeer:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self._ls.close()

    def _run(self) -> None:
        conn = None
        try:
            while not self._stop.is_set():
                if select.select([self._ls], [], [], 0.05)[0]:
                    conn, _ = self._ls.accept()
                    break
            if conn is None:
                return
            split = self._splitter()
            while not self._stop.is_set():
                if not select.select([conn], [], [], 0.05)[0]:
                    continue
                data = conn.recv(4096)
                if not data:
                    return
                for line in split(data):
                    if self.used >= len(self.exchanges):
                        self.errors.append(f"unexpected line {line!r} after the transcript")
                        continue
                    want, replies = self.exchanges[self.used]
                    if line != want:
                        self.errors.append(f"exchange {self.used}: expected {want!r}, got {line!r}")
                    self.used += 1
                    conn.sendall(b"".join(self._encode(r) for r in replies))
        finally:
            if conn is not None:
                conn.close()

    def _splitter(self):
        """A per-connection ``feed(bytes) -> requests``: here stripped text lines."""
        buf = bytearray()

        def feed(data: bytes) -> list[str]:
            buf.extend(data)
            out = []
            while (nl := buf.find(b"\n")) >= 0:
                out.append(bytes(buf[:nl]).decode().strip())
                del buf[: nl + 1]
            return out

        return feed

    @staticmethod
    def _encode(reply) -> bytes:
        return reply.encode() + b"\n"

    def check(self) -> None:
        """Fail on unexpected lines or unused exchanges."""
        # give the peer a moment to read anything still in flight
        time.sleep(0.05)
        unused = self.exchanges[self.used :]
        assert not self.errors, self.errors
        assert not unused, f"expected exchanges never happened: {unused}"
