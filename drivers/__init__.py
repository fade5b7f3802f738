"""Adapters for real hardware: robot controllers and laser trackers.

Open drivers by URL (:func:`open_robot`, :func:`open_tracker`); every driver
raises the errors of :mod:`drivers.errors`. Driver classes are imported
lazily (``drivers.ModbusRobot`` loads pymodbus only when first used).
"""

from __future__ import annotations

import importlib

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
from drivers.protocols import (
    CommandedPosition,
    Environment,
    EnvironmentSensor,
    JointReading,
    Measurement,
    Readiness,
    ReadyGate,
    Reflector,
    ReflectorSelect,
    RobotDriver,
    RobotStatus,
    TrackerDriver,
    TrackerStatus,
    TwoFace,
)
from drivers.urls import open_robot, open_tracker, register_scheme, unregister_scheme

_LAZY = {
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
    "CommandedPosition",
    "ConnectionLost",
    "DriverError",
    "Environment",
    "EnvironmentSensor",
    "JointReading",
    "LimitError",
    "Measurement",
    "NotReady",
    "ProtectiveStop",
    "ProtocolError",
    "Readiness",
    "ReadyGate",
    "Reflector",
    "ReflectorSelect",
    "RobotDriver",
    "RobotStatus",
    "TrackerDriver",
    "TrackerStatus",
    "TwoFace",
    "open_robot",
    "open_tracker",
    "register_scheme",
    "unregister_scheme",
    *_LAZY,
]


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'drivers' has no attribute {name!r}")
