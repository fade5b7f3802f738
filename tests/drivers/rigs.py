"""Every driver on the simulated cell, one entry each: what serves the cell to it, how it
is opened, and what it says.

:data:`ROBOTS` and :data:`TRACKERS` are the drivers the conformance suite
(``tests/drivers/conformance/``) runs through the same tests; a driver joins it with one
entry here. :func:`serve_robot` and :func:`serve_tracker` serve a cell to one driver
and yield a :class:`Rig` with the driver connected; the drivers' own test files use them
too (``tests/drivers/conftest.py``), so no file sets up a server of its own.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

from drivers.leica.driver import EmsconTracker
from drivers.line_robot import SerialRobot
from drivers.line_tracker import LineTracker
from drivers.modbus_robot import ModbusRobot
from drivers.ur_rtde import UrRtdeRobot
from drivers.urls import open_robot, open_tracker
from sim_drivers.cell import SimCell
from sim_drivers.emscon_server import EmsconServer
from sim_drivers.fake_rtde_control import FakeRTDEControl
from sim_drivers.inprocess import SimRobot, SimTracker
from sim_drivers.modbus_server import ModbusRobotServer
from sim_drivers.robot_server import RobotLineServer
from sim_drivers.rtde_server import RtdeSimServer
from sim_drivers.tracker_server import TrackerServer
from tests.sim_drivers.rtde_helpers import loopback_host

#: a server context manager (or None) and how to open a new, unconnected driver on it
Served = tuple[object, Callable[..., object]]


@dataclass
class Kind:
    """One driver in the suite.

    ``serve(cell, **kw)``: a context manager yielding ``(server, open)``, ``open(**kw)`` a
    new unconnected driver of the cell's controller (``kw``: the driver's own options).
    ``cls``: the driver class. ``words``: what the driver's errors say, by situation (a
    regular expression for ``pytest.raises(match=...)``). ``tol``: its numeric
    tolerances. ``second_client``: another client can connect to the same controller at
    once (else the observer of :meth:`Rig.observer` is a line-protocol TCP client).
    ``names_itself``: its ``identify`` says "simulator" (the RTDE simulator serves no
    dashboard, where a UR says its version). ``options(cell)``: the driver options the
    suite opens it with (ur-rtde: the joint limits, which a UR controller does not report).
    ``faults``: what the suite's wire-fault tests do to it (``drop``, ``slow``: the server
    drops the connection, holds a reply back, :mod:`sim_drivers.faults`; ``gone``: the
    server stops).
    """

    serve: Callable[..., contextlib.AbstractContextManager[Served]]
    cls: type
    words: dict[str, str] = field(default_factory=dict)
    tol: dict[str, float] = field(default_factory=dict)
    second_client: bool = True
    names_itself: bool = True
    options: Callable[[SimCell], dict] = lambda cell: {}
    faults: set[str] = field(default_factory=set)


def _wire(server_cls: type, open_fn: Callable, suffix: str = "", **fixed):
    """Serve the cell with ``server_cls(cell, **fixed, **server_kw)``; drivers open by its
    URL (plus ``suffix``)."""

    @contextlib.contextmanager
    def serve(cell: SimCell, **server_kw) -> Iterator[Served]:
        with server_cls(cell, **fixed, **server_kw) as srv:
            url = srv.url + suffix
            yield srv, lambda **kw: open_fn(url, **kw)

    return serve


def _in_process(cls: type, url: str):
    """No server: the driver acts on the cell itself."""

    @contextlib.contextmanager
    def serve(cell: SimCell) -> Iterator[Served]:
        yield None, lambda **kw: cls(url, cell, **kw)

    return serve


@contextlib.contextmanager
def _ur_robot(cell: SimCell, control_cls: type = FakeRTDEControl) -> Iterator[Served]:
    """The RTDE simulator (the real ur-rtde receive client reads it) and ``control_cls`` on
    the cell for the control side; joints as many as the cell's, streamed at 250 Hz.
    Every control interface made is in ``server.controls``."""
    server = RtdeSimServer(cell, host=loopback_host()).start()
    server.controls = []

    def control(host):
        ctrl = control_cls(cell, host, server=server)
        server.controls.append(ctrl)
        return ctrl

    def make(**kw):
        kw.setdefault("control_factory", control)
        return UrRtdeRobot.from_url(f"{server.url}?joints={cell.n_joints}&frequency=250",
                                    **kw)

    try:
        yield server, make
    finally:
        server.stop()


_LINE_ROBOT = {"words": {"limit": "LIMIT", "unreachable": "UNREACHABLE",
                         "pstop": "PROTECTIVE_STOP", "move": "MOVEJ", "read": "POS"},
               "tol": {"q": 1e-7, "tcp": 1e-3, "linear": 0.05, "temp": 0.006}}

#: every robot driver on the simulated cell
ROBOTS: dict[str, Kind] = {
    "line-tcp": Kind(_wire(RobotLineServer, open_robot), SerialRobot, **_LINE_ROBOT,
                     faults={"drop", "gone", "slow"}),
    "line-pty": Kind(_wire(RobotLineServer, open_robot, "?baud=57600", transport="pty"),
                     SerialRobot, **_LINE_ROBOT, second_client=False),
    "modbus": Kind(_wire(ModbusRobotServer, open_robot), ModbusRobot,
                   words={"limit": "ILLEGAL_DATA_VALUE.*LIMIT", "unreachable": "error code 21",
                          "pstop": "error code", "move": "move_joints", "read": "read_joints"},
                   tol={"q": 1e-6, "tcp": 1e-3, "linear": 0.01, "temp": 0.006},  # float32
                   faults={"drop", "gone", "slow"}),
    "ur-rtde": Kind(_ur_robot, UrRtdeRobot,
                    words={"limit": "joint\\(s\\) \\[1\\] outside limits",
                           "unreachable": "control script stopped", "pstop": "protective stop",
                           "move": "moveJ"},
                    tol={"q": 1e-9, "tcp": 1e-6, "linear": 0.05, "temp": 1e-9},
                    names_itself=False, options=lambda cell: {"limits": cell.truth.limits}),
    "sim": Kind(_in_process(SimRobot, "sim://robot"), SimRobot,
                words={"limit": "LIMIT", "unreachable": "UNREACHABLE", "pstop": "PROTECTIVE_STOP",
                       "move": "move_joints"},
                tol={"q": 1e-12, "tcp": 1e-9, "linear": 0.01, "temp": 1e-12}),
}

_LINE_TRACKER = {"words": {"beam": "MEAS: ERR", "warm": "NOT_WARMED_UP",
                           "bad_air": "BAD_ARGUMENT"},
                 "tol": {"n_per_s": 1000}}

#: every tracker driver on the simulated cell
TRACKERS: dict[str, Kind] = {
    "line-tcp": Kind(_wire(TrackerServer, open_tracker), LineTracker, **_LINE_TRACKER,
                     faults={"gone"}),
    "line-pty": Kind(_wire(TrackerServer, open_tracker, "?baud=115200", transport="pty"),
                     LineTracker, **_LINE_TRACKER, second_client=False),
    "emscon": Kind(_wire(EmsconServer, open_tracker), EmsconTracker,
                   words={"beam": "10009 ES_RS_NoStationary",
                          "warm": "10012 ES_RS_SensorNotWarmedUp",
                          "bad_air": "57 ES_RS_MeteoDataOutOfRange"},
                   tol={"n": 1}),
    "sim": Kind(_in_process(SimTracker, "sim://tracker"), SimTracker,
                words={"beam": "BEAM_BROKEN", "warm": "NOT_WARMED_UP", "bad_air": "BAD_ARGUMENT"},
                tol={"n_per_s": 1000}),
}


def having(table: dict[str, Kind], fault: str) -> list[str]:
    """The drivers of ``table`` whose simulator injects the wire fault ``fault``."""
    return [name for name, kind in table.items() if fault in kind.faults]


@dataclass
class Rig:
    """A cell served to one driver: ``driver`` connected, ``server`` (None in process),
    ``open(**kw)`` another unconnected driver of the same controller."""

    name: str
    kind: Kind
    table: dict[str, Kind]
    cell: SimCell
    server: object
    open: Callable[..., object]
    driver: object

    @property
    def words(self) -> dict[str, str]:
        return self.kind.words

    @property
    def tol(self) -> dict[str, float]:
        return self.kind.tol

    @contextlib.contextmanager
    def observer(self) -> Iterator[object]:
        """A second driver of the same controller, connected (to watch a call of
        :attr:`driver` from another thread); over line-protocol TCP when this transport
        takes one client only (a pty)."""
        if not self.kind.second_client:
            with _serve(self.table, "line-tcp", self.cell) as rig:
                yield rig.driver
            return
        other = self.open()
        other.connect(5.0)
        try:
            yield other
        finally:
            other.close()


@contextlib.contextmanager
def _serve(table: dict[str, Kind], name: str, cell: SimCell, serve_kw: dict | None = None,
           driver_kw: dict | None = None, connect: bool = True) -> Iterator[Rig]:
    kind = table[name]
    with kind.serve(cell, **(serve_kw or {})) as (server, make):
        driver = make(**(driver_kw or {}))
        try:
            if connect:
                driver.connect(5.0)
            yield Rig(name, kind, table, cell, server, make, driver)
        finally:
            driver.close()


def serve_robot(name: str, cell: SimCell, *, connect: bool = True, serve_kw: dict | None = None,
                **driver_kw) -> contextlib.AbstractContextManager[Rig]:
    """Serve ``cell`` to the robot driver ``name`` (of :data:`ROBOTS`; ``serve_kw`` to
    its server): a :class:`Rig` with the driver (built with ``driver_kw``) connected
    unless ``connect`` is false."""
    return _serve(ROBOTS, name, cell, serve_kw, driver_kw, connect)


def serve_tracker(name: str, cell: SimCell, *, connect: bool = True,
                  serve_kw: dict | None = None, **driver_kw
                  ) -> contextlib.AbstractContextManager[Rig]:
    """Serve ``cell`` to the tracker driver ``name`` (of :data:`TRACKERS`), as
    :func:`serve_robot`."""
    return _serve(TRACKERS, name, cell, serve_kw, driver_kw, connect)
