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
understood raises ``ValueError`` naming it.
"""

from __future__ import annotations

from collections.abc import Callable
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


def _query(url: str) -> dict[str, str]:
    try:
        q = parse_qs(urlsplit(url).query, strict_parsing=False, keep_blank_values=True)
    except ValueError as e:
        raise ValueError(f"bad URL {url!r}: {e}") from e
    return {k: v[-1] for k, v in q.items()}


def _host_port(url: str, default_port: int | None = None) -> tuple[str, int]:
    parts = urlsplit(url)
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
    return parts.hostname, port


def _baud(url: str, q: dict[str, str]) -> int:
    try:
        return int(q.get("baud", "115200"))
    except ValueError:
        raise ValueError(f"bad URL {url!r}: baud must be an integer") from None


def _serial_path(url: str) -> str:
    path = urlsplit(url).path
    if not path or path == "/":
        raise ValueError(f"bad URL {url!r}: no device path")
    return path


def _scheme(url: str) -> str:
    if not isinstance(url, str) or "://" not in url:
        raise ValueError(f"bad URL {url!r}: expected scheme://...")
    return url.split("://", 1)[0].lower()


def open_robot(url: str, **kw):
    """A robot driver for ``url`` (not yet connected); see the module docstring."""
    scheme = _scheme(url)
    q = _query(url)
    if scheme == "modbus+tcp":
        from drivers.modbus_robot import ModbusRobot

        host, port = _host_port(url, 502)
        try:
            unit = int(q.get("unit", "1"))
        except ValueError:
            raise ValueError(f"bad URL {url!r}: unit must be an integer") from None
        return ModbusRobot(url, host, port, unit=unit, map_file=q.get("map") or None, **kw)
    if scheme == "serial":
        from drivers.line_robot import SerialRobot

        return SerialRobot(url, _serial_path(url), baudrate=_baud(url, q), **kw)
    if scheme == "socket":
        from drivers.line_robot import SerialRobot

        host, port = _host_port(url)
        return SerialRobot(url, f"socket://{host}:{port}", **kw)
    if scheme == "ur":
        from drivers.ur_rtde import UrRtdeRobot  # written alongside; imported lazily

        return UrRtdeRobot.from_url(url, **kw)
    if scheme in _REGISTRY:
        return _REGISTRY[scheme](url, "robot", **kw)
    raise ValueError(f"bad robot URL {url!r}: unknown scheme {scheme!r}")


def open_tracker(url: str, **kw):
    """A tracker driver for ``url`` (not yet connected); see the module docstring."""
    scheme = _scheme(url)
    q = _query(url)
    if scheme == "tracker+tcp":
        from drivers.line_tracker import LineTracker

        host, port = _host_port(url)
        return LineTracker(url, f"socket://{host}:{port}", **kw)
    if scheme == "tracker+serial":
        from drivers.line_tracker import LineTracker

        return LineTracker(url, _serial_path(url), baudrate=_baud(url, q), **kw)
    if scheme == "emscon":
        from drivers.leica.driver import DEFAULT_PORT, EmsconTracker

        host, port = _host_port(url, DEFAULT_PORT)
        unknown = set(q) - {"reflector"}
        if unknown:
            raise ValueError(f"bad URL {url!r}: unknown parameter(s) {sorted(unknown)}")
        if "reflector" in q:
            kw.setdefault("reflector", q["reflector"])
        return EmsconTracker(url, host, port, **kw)
    if scheme in _REGISTRY:
        return _REGISTRY[scheme](url, "tracker", **kw)
    raise ValueError(f"bad tracker URL {url!r}: unknown scheme {scheme!r}")
