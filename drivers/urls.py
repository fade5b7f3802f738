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

The returned driver is not yet connected: call ``connect(timeout)``. Extra
keyword arguments go to the driver's constructor. A URL that cannot be
understood raises ``ValueError`` naming it (an unknown query parameter, a port
outside 1..65535, a Modbus unit outside 0..255 or a missing register map
included); :func:`check_url` runs the same checks without building a driver.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

#: scheme → factory(url, kind, **kw); kind is "robot" or "tracker"
_REGISTRY: dict[str, Callable[..., object]] = {}


def register_scheme(scheme: str, factory: Callable[..., object]) -> None:
    """Make ``scheme://...`` URLs open through ``factory(url, kind, **kw)``.

    ``kind`` is ``"robot"`` or ``"tracker"``. Used by :mod:`sim_drivers.inprocess`
    for ``sim://`` so this package never imports the simulator.
    """
    _REGISTRY[scheme] = factory


def unregister_scheme(scheme: str) -> None:
    """Forget a registered scheme (no error when absent)."""
    _REGISTRY.pop(scheme, None)


#: query parameters each built-in scheme takes
_PARAMS = {"modbus+tcp": {"unit", "map"}, "serial": {"baud"}, "socket": set(),
           "tracker+tcp": set(), "tracker+serial": {"baud"}, "emscon": {"reflector"}}


def _split(url: str):
    try:
        return urlsplit(url)
    except ValueError as e:  # e.g. "socket://[::1": an unclosed IPv6 bracket
        raise ValueError(f"bad URL {url!r}: {e}") from None


def _query(url: str) -> dict[str, str]:
    query = _split(url).query
    try:
        q = parse_qs(query, strict_parsing=False, keep_blank_values=True)
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from e
    return {k: v[-1] for k, v in q.items()}


def _known_params(url: str, scheme: str, q: dict[str, str]) -> None:
    known = _PARAMS.get(scheme)
    if known is None:
        return
    unknown = sorted(set(q) - known)
    if unknown:
        raise ValueError(f"bad URL {url!r}: unknown parameter(s) {unknown}"
                         + (f" (known: {', '.join(sorted(known))})" if known else
                            " (this scheme takes none)"))


def _host_port(url: str, default_port: int | None = None) -> tuple[str, int]:
    parts = _split(url)
    try:
        port = parts.port
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from e
    if not parts.hostname:
        raise ValueError(f"bad URL {url!r}: no host")
    if port is None:
        if default_port is None:
            raise ValueError(f"bad URL {url!r}: no port")
        port = default_port
    if not 1 <= port <= 65535:
        raise ValueError(f"bad URL {url!r}: port {port} is not 1..65535")
    return parts.hostname, port


def _int_param(url: str, q: dict[str, str], name: str, default: int, lo: int, hi: int) -> int:
    text = q.get(name)
    if text is None:
        return default
    try:
        v = int(text)
    except ValueError:
        raise ValueError(f"bad URL {url!r}: {name} must be an integer, got {text!r}") from None
    if not lo <= v <= hi:
        raise ValueError(f"bad URL {url!r}: {name} {v} is not {lo}..{hi}")
    return v


def _baud(url: str, q: dict[str, str]) -> int:
    return _int_param(url, q, "baud", 115200, 1, 10_000_000)


def _serial_path(url: str) -> str:
    path = _split(url).path
    if not path or path == "/":
        raise ValueError(f"bad URL {url!r}: no device path")
    return path


def _scheme(url: str) -> str:
    if not isinstance(url, str) or "://" not in url:
        raise ValueError(f"bad URL {url!r}: expected scheme://...")
    return url.split("://", 1)[0].lower()


def _map_file(url: str, q: dict[str, str]) -> str | None:
    m = q.get("map") or None
    if m is not None and not Path(m).is_file():
        raise ValueError(f"bad URL {url!r}: register map {m}: no such file")
    return m


def _robot_args(url: str) -> tuple[str, dict]:
    """(scheme, the driver's arguments) of a robot URL; ValueError naming what is wrong."""
    scheme = _scheme(url)
    q = _query(url)
    _known_params(url, scheme, q)
    if scheme == "modbus+tcp":
        host, port = _host_port(url, 502)
        unit = _int_param(url, q, "unit", 1, 0, 255)
        return scheme, {"host": host, "port": port, "unit": unit, "map_file": _map_file(url, q)}
    if scheme == "serial":
        return scheme, {"port": _serial_path(url), "baudrate": _baud(url, q)}
    if scheme == "socket":
        host, port = _host_port(url)
        return scheme, {"port": f"socket://{host}:{port}"}
    if scheme == "ur" or scheme in _REGISTRY:
        return scheme, {}
    raise ValueError(f"bad robot URL {url!r}: unknown scheme {scheme!r}")


def _tracker_args(url: str) -> tuple[str, dict]:
    """(scheme, the driver's arguments) of a tracker URL; ValueError naming what is wrong."""
    scheme = _scheme(url)
    q = _query(url)
    _known_params(url, scheme, q)
    if scheme == "tracker+tcp":
        host, port = _host_port(url)
        return scheme, {"port": f"socket://{host}:{port}"}
    if scheme == "tracker+serial":
        return scheme, {"port": _serial_path(url), "baudrate": _baud(url, q)}
    if scheme == "emscon":
        from drivers.leica.driver import DEFAULT_PORT

        host, port = _host_port(url, DEFAULT_PORT)
        return scheme, {"host": host, "port": port,
                        **({"reflector": q["reflector"]} if "reflector" in q else {})}
    if scheme in _REGISTRY:
        return scheme, {}
    raise ValueError(f"bad tracker URL {url!r}: unknown scheme {scheme!r}")


def check_url(url: str, kind: str) -> None:
    """Validate a robot (``kind="robot"``) or tracker URL without building a driver:
    ValueError naming the URL and what is wrong (a Modbus register map is read and
    checked too). ``ur://`` and registered schemes (``sim://``) are left to their
    factory."""
    if kind == "robot":
        scheme, a = _robot_args(url)
        if scheme == "modbus+tcp" and a["map_file"]:
            from drivers.modbus_robot import RegisterMap

            RegisterMap.from_yaml(a["map_file"])
    else:
        _tracker_args(url)


def open_robot(url: str, **kw):
    """A robot driver for ``url`` (not yet connected); see the module docstring."""
    scheme, a = _robot_args(url)
    if scheme == "modbus+tcp":
        from drivers.modbus_robot import ModbusRobot

        return ModbusRobot(url, a["host"], a["port"], unit=a["unit"], map_file=a["map_file"],
                           **kw)
    if scheme == "serial":
        from drivers.line_robot import SerialRobot

        return SerialRobot(url, a["port"], baudrate=a["baudrate"], **kw)
    if scheme == "socket":
        from drivers.line_robot import SerialRobot

        return SerialRobot(url, a["port"], **kw)
    if scheme == "ur":
        from drivers.ur_rtde import UrRtdeRobot  # written alongside; imported lazily

        return UrRtdeRobot.from_url(url, **kw)
    return _REGISTRY[scheme](url, "robot", **kw)


def open_tracker(url: str, **kw):
    """A tracker driver for ``url`` (not yet connected); see the module docstring."""
    scheme, a = _tracker_args(url)
    if scheme == "tracker+tcp":
        from drivers.line_tracker import LineTracker

        return LineTracker(url, a["port"], **kw)
    if scheme == "tracker+serial":
        from drivers.line_tracker import LineTracker

        return LineTracker(url, a["port"], baudrate=a["baudrate"], **kw)
    if scheme == "emscon":
        from drivers.leica.driver import EmsconTracker

        if "reflector" in a:
            kw.setdefault("reflector", a["reflector"])
        return EmsconTracker(url, a["host"], a["port"], **kw)
    return _REGISTRY[scheme](url, "tracker", **kw)
