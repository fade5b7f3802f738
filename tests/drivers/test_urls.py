"""URL dispatch of drivers.urls."""

from __future__ import annotations

import pytest

from drivers import urls
from drivers.abb.driver import AbbRwsRobot
from drivers.line_robot import SerialRobot
from drivers.line_tracker import LineTracker
from drivers.modbus_robot import ModbusRobot


def test_dispatch():
    r = urls.open_robot("modbus+tcp://10.0.0.5:1502?unit=7")
    assert isinstance(r, ModbusRobot) and (r.host, r.port, r.unit) == ("10.0.0.5", 1502, 7)
    assert urls.open_robot("modbus+tcp://plc").port == 502
    s = urls.open_robot("serial:///dev/ttyUSB0?baud=9600")
    assert isinstance(s, SerialRobot) and s._transport.port_url == "/dev/ttyUSB0"
    assert s._transport.baudrate == 9600
    s = urls.open_robot("socket://127.0.0.1:15021")
    assert s._transport.port_url == "socket://127.0.0.1:15021"
    t = urls.open_tracker("tracker+tcp://127.0.0.1:15700")
    assert isinstance(t, LineTracker) and t._transport.port_url == "socket://127.0.0.1:15700"
    t = urls.open_tracker("tracker+serial:///dev/ttyUSB1?baud=57600")
    assert t._transport.port_url == "/dev/ttyUSB1" and t._transport.baudrate == 57600
    a = urls.open_robot("abb://10.0.0.9?joints=6")
    assert isinstance(a, AbbRwsRobot) and (a._link.host, a._link.port) == ("10.0.0.9", 80)


def test_registered_scheme():
    seen = []
    urls.register_scheme("fake", lambda url, kind, **kw: seen.append((url, kind, kw)) or "drv")
    try:
        assert urls.open_robot("fake://x", poll_s=1) == "drv"
        assert urls.open_tracker("fake://y") == "drv"
        assert seen == [("fake://x", "robot", {"poll_s": 1}), ("fake://y", "tracker", {})]
    finally:
        urls.unregister_scheme("fake")


@pytest.mark.parametrize(
    "url",
    [
        "nonsense",
        "http://example.com",
        "modbus+tcp://:502",
        "modbus+tcp://plc:notaport",
        "modbus+tcp://plc?unit=x",
        "serial://",
        "serial:///dev/ttyUSB0?baud=fast",
        "socket://host",
        "tracker+tcp://127.0.0.1:1",
    ],
)
def test_bad_robot_urls_name_the_url(url):
    with pytest.raises(ValueError, match="bad (robot )?URL"):
        urls.open_robot(url)


@pytest.mark.parametrize("url", ["tracker+tcp://host", "tracker+serial://", "modbus+tcp://x:1"])
def test_bad_tracker_urls_name_the_url(url):
    with pytest.raises(ValueError, match="bad (tracker )?URL"):
        urls.open_tracker(url)
