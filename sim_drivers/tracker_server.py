"""The simulated laser tracker behind the line protocol (docs/tracker-protocol.md).

:class:`TrackerServer` serves a :class:`~sim_drivers.cell.SimCell`'s tracker over
loopback TCP or a pty. One session per connection; the stationary averaging
time (``SET MODE STATIONARY time_ms=N``) belongs to the session. ``MEAS6D`` measures
the cell's 6-DoF target (position and orientation), when it has one.
"""

from __future__ import annotations

import threading

from sim_drivers.cell import CellRefused, SimCell
from sim_drivers.faults import FaultInjector
from sim_drivers.line_server import LineServer

#: ERR name → code on the wire
TRACKER_ERROR_CODES = {
    "BAD_COMMAND": 10,
    "BAD_ARGUMENT": 11,
    "BUSY": 12,
    "NOT_INITIALISED": 13,
    "BEAM_BROKEN": 14,
    "NOT_WARMED_UP": 15,
    "NOT_STABLE": 16,
    "NO_STATIONARY_RESULT": 17,
    "NO_TARGET": 18,
    "OUT_OF_RANGE": 19,
    "NO_6DOF_TARGET": 20,
    "FACE2_6D": 21,
}

#: what the simulated tracker says in HELLO (its serial number is the cell's,
#: :meth:`SimCell.serial`; ``sim=1`` declares it a simulator)
MODEL, FIRMWARE = "SIMTRACK-1", "1.0.0"


def err(name: str, detail: str = "") -> str:
    """``ERR <code> <NAME> [detail]``."""
    code = TRACKER_ERROR_CODES.get(name, 99)
    return f"ERR {code} {name}" + (f" {detail}" if detail else "")


class TrackerSession:
    """Protocol state of one tracker connection."""

    def __init__(self, cell: SimCell, faults: FaultInjector, busy: threading.Lock) -> None:
        self.cell = cell
        self.faults = faults
        self.busy = busy
        self.time_ms = 500
        self.server: LineServer | None = None

    def bind(self, server: LineServer, conn) -> None:
        self.server = server

    def _event(self, text: str) -> None:
        if self.server is not None:
            self.server.broadcast(f"EVT {text}")

    def handle(self, line: str) -> list[str]:
        words = line.split()
        cmd = words[0].upper()
        if cmd == "HELLO" and len(words) == 1:
            return [f"OK HELLO {MODEL} {self.cell.serial('tracker')} {FIRMWARE} sim=1"]
        if cmd == "STATUS?" and len(words) == 1:
            c = self.cell
            return [
                f"OK STATUS init={int(c.tracker_initialised)} warm={int(c.tracker_warmed_up())} "
                f"beam={int(c.beam_ok)} target={int(c.tracker_target_visible())} "
                f"busy={int(self.busy.locked())} ws={int(c.weather_station)} "
                f"face={c.tracker_face} {self._env()}"
            ]
        if cmd == "ENV?" and len(words) == 1:
            return [f"OK ENV {self._env()}"]
        if cmd == "FACE?" and len(words) == 1:
            return [f"OK FACE face={self.cell.tracker_face}"]
        if cmd == "CHANGE" and len(words) == 2 and words[1].upper() == "FACE":
            try:
                face = self.cell.tracker_change_face()
            except CellRefused as e:
                return [err(e.name, e.detail)]
            return [f"OK FACE face={face}"]
        if cmd == "INIT" and len(words) == 1:
            self.cell.tracker_init()
            return ["OK INIT"]
        if cmd == "SET":
            return self._set(words)
        if cmd == "MEAS" and len(words) == 1:
            return self._meas()
        if cmd == "MEAS6D" and len(words) == 1:
            return self._meas(six_dof=True)
        return [err("BAD_COMMAND", f"unknown command {line[:40]!r}")]

    def _env(self) -> str:
        t, p, h, source = self.cell.tracker_environment()
        return f"T={t:.2f} P={p:.2f} H={h:.1f} src={source}"

    def _set_env(self, words: list[str]) -> list[str]:
        try:
            kv = dict(w.split("=", 1) for w in words[2:])
            t, p, h = float(kv.pop("T")), float(kv.pop("P")), float(kv.pop("H"))
        except (ValueError, KeyError):
            kv = {"bad": ""}
        if kv or len(words) != 5:
            return [err("BAD_ARGUMENT", "expected SET ENV T=<degC> P=<hPa> H=<%>")]
        try:
            self.cell.set_tracker_environment(t, p, h)
        except CellRefused as e:
            return [err("BAD_ARGUMENT", e.detail)]
        return [f"OK ENV {self._env()}"]

    def _set(self, words: list[str]) -> list[str]:
        if len(words) >= 2 and words[1].upper() == "ENV":
            return self._set_env(words)
        if len(words) != 4 or words[1].upper() != "MODE" or words[2].upper() != "STATIONARY":
            return [err("BAD_COMMAND", "expected SET MODE STATIONARY time_ms=N")]
        key, _, val = words[3].partition("=")
        try:
            ms = int(val)
        except ValueError:
            ms = -1
        if key != "time_ms" or not 1 <= ms <= 60000:
            return [err("BAD_ARGUMENT", "time_ms must be an integer 1..60000")]
        self.time_ms = ms
        return [f"OK MODE STATIONARY time_ms={ms}"]

    def _meas(self, six_dof: bool = False) -> list[str]:
        if not self.busy.acquire(blocking=False):
            return [err("BUSY", "a measurement is running")]
        try:
            if self.faults.fires("beam"):
                self._event("BEAM_LOST")
                self._event("BEAM_RESTORED")
                return [err("BEAM_BROKEN", "beam interrupted during measurement")]
            try:
                measure = self.cell.tracker_measure_pose if six_dof else self.cell.tracker_measure
                pose = r = measure(self.time_ms / 1000.0)
            except CellRefused as e:
                return [err(e.name, e.detail)]
        finally:
            self.busy.release()
        if six_dof:
            r = pose.reading
        x, y, z = r.xyz
        sx, sy, sz = r.std
        if six_dof:
            qw, qx, qy, qz = pose.quat
            dx, dy, dz = pose.std_deg
            return [
                f"OK MEAS6D x={x:.5f} y={y:.5f} z={z:.5f} sx={sx:.5f} sy={sy:.5f} sz={sz:.5f} "
                f"qw={qw:.10f} qx={qx:.10f} qy={qy:.10f} qz={qz:.10f} "
                f"sdx={dx:.6f} sdy={dy:.6f} sdz={dz:.6f} target={pose.target.replace(' ', '_')} "
                f"n={r.n} T={r.temp_c:.2f} P={r.pressure_hpa:.2f} H={r.humidity_pct:.1f} "
                f"face={r.face} t={r.timestamp:.6f} seq={r.seq}"
            ]
        return [
            f"OK MEAS x={x:.5f} y={y:.5f} z={z:.5f} sx={sx:.5f} sy={sy:.5f} sz={sz:.5f} "
            f"n={r.n} T={r.temp_c:.2f} P={r.pressure_hpa:.2f} H={r.humidity_pct:.1f} "
            f"face={r.face} t={r.timestamp:.6f} seq={r.seq}"
        ]


class TrackerServer(LineServer):
    """Line-protocol tracker server for ``cell`` (TCP or pty).

    Parameters
    ----------
    cell : SimCell
    faults : FaultInjector or None
        Defaults to the cell's injector (or none).
    transport : {"tcp", "pty"}
    host, port : str, int
        TCP address (port 0: a free one).

    Examples
    --------
    >>> with TrackerServer(cell) as srv:          # doctest: +SKIP
    ...     trk = open_tracker(srv.url)
    """

    def __init__(
        self,
        cell: SimCell,
        *,
        faults: FaultInjector | None = None,
        transport: str = "tcp",
        host: str = "127.0.0.1",
        port: int = 0,
    ) -> None:
        faults = faults if faults is not None else (cell.faults or FaultInjector())
        self.cell = cell
        busy = threading.Lock()
        super().__init__(
            lambda: TrackerSession(cell, faults, busy),
            faults=faults,
            host=host,
            port=port,
            transport=transport,
            name="sim-tracker",
        )

    @property
    def url(self) -> str:
        """The driver URL: ``tracker+tcp://host:port`` or ``tracker+serial:///dev/pts/N``."""
        if self.transport == "tcp":
            return f"tracker+tcp://{self.host}:{self.port}"
        return f"tracker+serial://{self.pty_path}"

    def event(self, text: str) -> None:
        """Send ``EVT <text>`` to every client (e.g. ``"TEMP 20.4"``)."""
        self.broadcast(f"EVT {text}")
