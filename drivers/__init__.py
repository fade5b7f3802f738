"""Adapters for real hardware: robot controllers and laser trackers.

Open drivers by URL (:func:`open_robot`, :func:`open_tracker`); every driver
raises the errors of :mod:`drivers.errors`. The protocols and the driver classes are
imported lazily (``drivers.ModbusRobot`` loads pymodbus only when first used; a command
that opens no device never loads :mod:`drivers.protocols`).

Modules
    ``protocols``     what capture needs from a robot and a tracker (small protocols)
    ``errors``        one error hierarchy for every driver
    ``urls``          open drivers from URLs: a registry of schemes (``ur://``,
                      ``modbus+tcp://``...; ``sim://`` registered by the application)
    ``url_parts``     the parts of a driver URL (host, port, query), refused by name
    ``transport``     line I/O over any pyserial URL, with deadlines and typed errors
    ``settle``        waiting until a robot is settled, by polling its status
    ``line_robot``    a robot controller behind the ASCII line protocol
    ``line_tracker``  a laser tracker over TCP or serial, line protocol
    ``modbus_robot``  a PLC-style robot controller over Modbus TCP
    ``ur_rtde``       Universal Robots over ur-rtde
    ``leica/``        Leica laser trackers over the emScon TPI (see its package)

Logging: every driver logs its wire traffic decoded at DEBUG to its module's logger
(``drivers.line_robot``, ``drivers.leica.link``...), its connection, retries and errors at
INFO; the package configures no handler but a ``NullHandler`` (the application does).
"""

from __future__ import annotations

import importlib
import logging
from typing import Any

from drivers.errors import (
    BeamBroken,
    CommandRejected,
    CommandTimeout,
    ConnectionLost,
    DriverError,
    LimitError,
    NotReady,
    ProtectiveStop,
    ProtocolError,
)
from drivers.urls import open_robot, open_tracker, register_scheme, unregister_scheme

logging.getLogger(__name__).addHandler(logging.NullHandler())

#: names loaded at their first use: the protocols (a command that opens no device, such
#: as ``calibrate``, registers ``sim://`` in drivers.urls without loading them) and the
#: driver classes (a vendor library only when its driver is used)
_LAZY = {
    "CommandedPosition": "drivers.protocols",
    "DeviceIdentity": "drivers.protocols",
    "Environment": "drivers.protocols",
    "EnvironmentSensor": "drivers.protocols",
    "Identified": "drivers.protocols",
    "JointReading": "drivers.protocols",
    "Measurement": "drivers.protocols",
    "Readiness": "drivers.protocols",
    "ReadyGate": "drivers.protocols",
    "Reflector": "drivers.protocols",
    "ReflectorSelect": "drivers.protocols",
    "RobotDriver": "drivers.protocols",
    "RobotStatus": "drivers.protocols",
    "TrackerDriver": "drivers.protocols",
    "TrackerStatus": "drivers.protocols",
    "TwoFace": "drivers.protocols",
    "ModbusRobot": "drivers.modbus_robot",
    "RegisterMap": "drivers.modbus_robot",
    "SerialRobot": "drivers.line_robot",
    "LineTracker": "drivers.line_tracker",
    "EmsconTracker": "drivers.leica.driver",
    "UrRtdeRobot": "drivers.ur_rtde",
}

__all__ = [
    "BeamBroken",
    "CommandRejected",
    "CommandTimeout",
    "ConnectionLost",
    "DriverError",
    "LimitError",
    "NotReady",
    "ProtectiveStop",
    "ProtocolError",
    "open_robot",
    "open_tracker",
    "register_scheme",
    "unregister_scheme",
    *_LAZY,
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'drivers' has no attribute {name!r}")
