"""Open drivers from URLs, so a capture script runs unchanged on the simulator or the cell.

Robots (:func:`open_robot`)::

    modbus+tcp://host:port?unit=1&map=file.yaml   ModbusRobot (register map YAML optional)
    serial:///dev/ttyUSB0?baud=115200             SerialRobot over a serial port
    socket://host:port                            SerialRobot over TCP
    ur://host                                     drivers.ur_rtde.UrRtdeRobot.from_url(url)
    sim://...                                     whatever registered the ``sim`` scheme

Trackers (:func:`open_tracker`)::

    tracker+tcp://host:port                       LineTracker over TCP
    tracker+serial:///dev/ttyUSB1?baud=115200     LineTracker over a serial port
    emscon://host[:700]?reflector=NAME            EmsconTracker (Leica emScon TPI, port 700)
    sim://...                                     registered scheme

Every scheme is an entry of one registry (:func:`register_scheme`): this module registers
the real cell's schemes above; the application registers ``sim`` (the simulated cell,
:mod:`cellcal.url_schemes`), so this package never imports the simulator and a capture on
the real cell never loads it.

The returned driver is not yet connected: call ``connect(timeout)``. Extra
keyword arguments go to the driver's constructor. A URL that cannot be
understood raises ``ValueError`` naming it (an unknown scheme or query parameter, a port
outside 1..65535, a Modbus unit outside 0..255 or a missing register map
included); :func:`check_url` runs the same checks without building a driver.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

from drivers import url_parts as parts

if TYPE_CHECKING:  # the driver modules load when their URL is opened
    from drivers.leica.driver import EmsconTracker
    from drivers.line_robot import SerialRobot
    from drivers.line_tracker import LineTracker
    from drivers.modbus_robot import ModbusRobot
    from drivers.protocols import RobotDriver, TrackerDriver
    from drivers.ur_rtde import UrRtdeRobot

#: what a URL opens
Kind = Literal["robot", "tracker"]


class Opener(Protocol):
    """Builds the driver of a URL (not yet connected); ``kw`` go to its constructor."""

    def __call__(self, url: str, kind: Kind, /, **kw: Any) -> Any: ...


@dataclass(frozen=True)
class Scheme:
    """How the URLs of one scheme open drivers.

    Attributes
    ----------
    opener : Opener
        ``opener(url, kind, **kw)`` builds the driver.
    kinds : frozenset of str
        What it opens: ``"robot"``, ``"tracker"`` or both.
    params : frozenset of str or None
        The query parameters it takes (another is refused before the opener runs); None
        leaves them to the opener.
    check : callable or None
        ``check(url)`` validates a URL without building a driver (:func:`check_url`); None
        leaves that to the opener.
    """

    opener: Opener
    kinds: frozenset[str]
    params: frozenset[str] | None = None
    check: Callable[[str], object] | None = None


_REGISTRY: dict[str, Scheme] = {}


def register_scheme(scheme: str, opener: Opener, *,
                    kinds: Collection[str] = ("robot", "tracker"),
                    params: Collection[str] | None = None,
                    check: Callable[[str], object] | None = None) -> None:
    """Make ``scheme://...`` URLs open through ``opener(url, kind, **kw)`` (see
    :class:`Scheme` for the rest); registering a scheme again replaces it."""
    _REGISTRY[scheme.lower()] = Scheme(opener, frozenset(kinds),
                                       None if params is None else frozenset(params), check)


def unregister_scheme(scheme: str) -> None:
    """Forget a registered scheme (no error when absent)."""
    _REGISTRY.pop(scheme.lower(), None)


def _lookup(url: str, kind: Kind) -> Scheme:
    """The scheme of ``url`` for a ``kind``; ValueError naming the URL when none fits."""
    name = parts.scheme_of(url)
    q = parts.query(url)
    scheme = _REGISTRY.get(name)
    if scheme is None or kind not in scheme.kinds:
        raise ValueError(f"bad {kind} URL {url!r}: unknown scheme {name!r}")
    if scheme.params is not None:
        parts.check_params(url, q, scheme.params)
    return scheme


def check_url(url: str, kind: str) -> None:
    """Validate a robot (``kind="robot"``) or tracker URL without building a driver:
    ValueError naming the URL and what is wrong (a Modbus register map is read and
    checked too). ``ur://`` and registered schemes (``sim://``) are left to their
    opener."""
    scheme = _lookup(url, "robot" if kind == "robot" else "tracker")
    if scheme.check is not None:
        scheme.check(url)


def open_robot(url: str, **kw: Any) -> RobotDriver:
    """A robot driver for ``url`` (not yet connected); see the module docstring."""
    return _lookup(url, "robot").opener(url, "robot", **kw)


def open_tracker(url: str, **kw: Any) -> TrackerDriver:
    """A tracker driver for ``url`` (not yet connected); see the module docstring."""
    return _lookup(url, "tracker").opener(url, "tracker", **kw)


# -- the real cell's schemes (driver modules are imported when their URL is opened, so
# -- pymodbus or ur-rtde load only for the cell that needs them)

def _modbus(url: str) -> dict[str, Any]:
    q = parts.query(url)
    host, port = parts.host_port(url, 502)
    return {"host": host, "port": port, "unit": parts.int_param(url, q, "unit", 1, 0, 255),
            "map_file": parts.map_file(url, q)}


def _check_modbus(url: str) -> None:
    a = _modbus(url)
    if a["map_file"]:
        from drivers.modbus_robot import RegisterMap

        RegisterMap.from_yaml(a["map_file"])


def _open_modbus(url: str, kind: Kind, /, **kw: Any) -> ModbusRobot:
    a = _modbus(url)
    from drivers.modbus_robot import ModbusRobot

    return ModbusRobot(url, a["host"], a["port"], unit=a["unit"], map_file=a["map_file"], **kw)


def _serial(url: str) -> dict[str, Any]:
    return {"port": parts.serial_path(url), "baudrate": parts.baud(url, parts.query(url))}


def _socket(url: str) -> dict[str, Any]:
    host, port = parts.host_port(url)
    return {"port": f"socket://{host}:{port}"}


def _open_line_robot(args: Callable[[str], dict[str, Any]]) -> Opener:
    def opener(url: str, kind: Kind, /, **kw: Any) -> SerialRobot:
        a = args(url)
        from drivers.line_robot import SerialRobot

        return SerialRobot(url, a.pop("port"), **a, **kw)

    return opener


def _open_line_tracker(args: Callable[[str], dict[str, Any]]) -> Opener:
    def opener(url: str, kind: Kind, /, **kw: Any) -> LineTracker:
        a = args(url)
        from drivers.line_tracker import LineTracker

        return LineTracker(url, a.pop("port"), **a, **kw)

    return opener


def _open_ur(url: str, kind: Kind, /, **kw: Any) -> UrRtdeRobot:
    from drivers.ur_rtde import UrRtdeRobot

    return UrRtdeRobot.from_url(url, **kw)


def _emscon(url: str) -> dict[str, Any]:
    from drivers.leica.driver import DEFAULT_PORT

    q = parts.query(url)
    host, port = parts.host_port(url, DEFAULT_PORT)
    return {"host": host, "port": port,
            **({"reflector": q["reflector"]} if "reflector" in q else {})}


def _open_emscon(url: str, kind: Kind, /, **kw: Any) -> EmsconTracker:
    a = _emscon(url)
    from drivers.leica.driver import EmsconTracker

    if "reflector" in a:
        kw.setdefault("reflector", a["reflector"])
    return EmsconTracker(url, a["host"], a["port"], **kw)


register_scheme("modbus+tcp", _open_modbus, kinds=("robot",), params=("unit", "map"),
                check=_check_modbus)
register_scheme("serial", _open_line_robot(_serial), kinds=("robot",), params=("baud",),
                check=_serial)
register_scheme("socket", _open_line_robot(_socket), kinds=("robot",), params=(),
                check=_socket)
register_scheme("ur", _open_ur, kinds=("robot",))
register_scheme("tracker+tcp", _open_line_tracker(_socket), kinds=("tracker",), params=(),
                check=_socket)
register_scheme("tracker+serial", _open_line_tracker(_serial), kinds=("tracker",),
                params=("baud",), check=_serial)
register_scheme("emscon", _open_emscon, kinds=("tracker",), params=("reflector",),
                check=_emscon)
