"""What capture code needs from a robot and from a tracker.

Small protocols named by capability: a device is whatever implements these
few methods. Units at this boundary: joint angles in **radians**, lengths in
**millimetres**, times in seconds (``time.time()`` epoch for timestamps,
``time.monotonic()`` for timeouts). Every call takes an explicit ``timeout``
in seconds; a call that cannot finish in time raises
:class:`drivers.errors.CommandTimeout`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class RobotStatus:
    """A robot controller's state at one instant."""

    connected: bool
    moving: bool
    in_position: bool
    fault: bool = False
    protective_stop: bool = False
    emergency_stop: bool = False
    error_code: int = 0
    message: str = ""
    timestamp: float = 0.0


@dataclass(frozen=True)
class JointReading:
    """Joint positions read from the controller (rad) and when they were read."""

    q: np.ndarray
    timestamp: float


@dataclass(frozen=True)
class TrackerStatus:
    """A tracker's state at one instant."""

    connected: bool
    initialised: bool
    warmed_up: bool
    beam_ok: bool
    target_present: bool = True
    message: str = ""
    timestamp: float = 0.0


@dataclass(frozen=True)
class Measurement:
    """One stationary tracker measurement (averaged over ``n`` samples).

    ``xyz`` in mm in the tracker frame, ``std`` the per-axis standard deviation
    of the samples (mm), ``timestamp`` the time of the measurement (epoch s),
    ``env`` whatever the instrument knows about its environment, e.g.
    ``{"temp_c": 20.3, "pressure_hpa": 1013.2, "humidity_pct": 41.0}``.
    """

    xyz: np.ndarray
    std: np.ndarray
    n: int
    timestamp: float
    env: dict[str, float] = field(default_factory=dict)


@runtime_checkable
class RobotDriver(Protocol):
    """A robot controller that can move to joint or Cartesian targets and report joints."""

    url: str

    def connect(self, timeout: float = 5.0) -> None: ...

    def close(self) -> None: ...

    def read_joints(self, timeout: float = 1.0) -> JointReading: ...

    def move_joints(self, q: np.ndarray, speed: float = 0.5, timeout: float = 60.0) -> None:
        """Start (or perform) a joint move to ``q`` (rad); ``speed`` in rad/s."""
        ...

    def move_linear(self, xyz: np.ndarray, speed: float = 100.0, timeout: float = 60.0) -> None:
        """Linear move of the TCP to ``xyz`` (mm, robot base frame), keeping orientation."""
        ...

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Return once the robot is in position and still; raise on fault or timeout."""
        ...

    def status(self, timeout: float = 1.0) -> RobotStatus: ...

    def stop(self, timeout: float = 2.0) -> None: ...


@runtime_checkable
class TrackerDriver(Protocol):
    """A laser tracker that measures a stationary target."""

    url: str

    def connect(self, timeout: float = 5.0) -> None: ...

    def close(self) -> None: ...

    def status(self, timeout: float = 1.0) -> TrackerStatus: ...

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement:
        """Measure a stationary target, averaging for ``duration_s``."""
        ...


@runtime_checkable
class CommandedPosition(Protocol):
    """Optional capability: the controller's own nominal TCP position (teach pendant)."""

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """Nominal TCP position (mm, robot base frame) as the controller computes it."""
        ...
