"""What capture code needs from a robot and from a tracker.

Small protocols named by capability: a device is whatever implements these
few methods. Units at this boundary: joint angles in **radians**, lengths in
**millimetres**, times in seconds (``time.time()`` epoch for timestamps,
``time.monotonic()`` for timeouts). Every call takes an explicit ``timeout``
in seconds; a call that cannot finish in time raises
:class:`drivers.errors.CommandTimeout`.

The contract every driver keeps (checked for each one by
``tests/drivers/conformance/``: its methods' signatures against these protocols, and
its behaviour against the simulator):

* **Every call blocks** until it is done and returns its result, or raises; nothing
  goes on in the background when it returns. A robot's ``move_joints`` and
  ``move_linear`` return once the motion has ended and the robot is *settled* (in
  position and still: what :meth:`RobotDriver.wait_settled` waits for), so the joints
  read right after equal the target; ``stop`` returns once the robot stands still; a
  tracker's ``measure`` returns the finished measurement.
* **Signatures are the protocol's**: the same parameter names, kinds and defaults; a
  driver adds no parameter of its own to a protocol method (its options go to its
  constructor or URL).
* **Errors** are only those of :mod:`drivers.errors`, each meaning one thing at every
  driver: :class:`~drivers.errors.CommandTimeout` not done within ``timeout`` (a move
  that runs out of time is stopped first, so the robot stands still when it is
  raised; the stop may take up to :data:`STOP_AFTER_TIMEOUT_S` more);
  :class:`~drivers.errors.ConnectionLost` the link is gone, or the driver is not
  connected (before ``connect``, after ``close``: a driver never reconnects by itself
  for a move); :class:`~drivers.errors.LimitError` a target outside the joint limits
  the controller names or the driver was given (ur-rtde's ``limits=``), nothing moved;
  :class:`~drivers.errors.CommandRejected` any other refused command (bad shape, an
  unreachable target, a controller fault, a refusal that does not say why);
  :class:`~drivers.errors.ProtectiveStop` a protective or emergency stop, before or
  during the motion;
  :class:`~drivers.errors.BeamBroken` the tracker lost its beam (or never had it);
  :class:`~drivers.errors.NotReady` the device cannot do this yet (tracker not
  initialised or warming up, robot not in its running mode, opened read-only);
  :class:`~drivers.errors.ProtocolError` an answer the protocol does not allow.
* ``connect`` opens the link, again after ``close`` (``close()`` then ``connect()`` is how
  a caller reconnects); ``close`` is idempotent and never raises.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from drivers.errors import NotReady, ProtocolError


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
class DeviceIdentity:
    """Who a device says it is, as learnt when connecting.

    ``model``, ``serial``, ``firmware``: the device's own words ("" when its protocol
    does not say). ``simulator``: the device declared itself a simulator (the line
    protocols' ``HELLO ... sim=1``, the Modbus device identification, the emScon
    software version, the UR dashboard's PolyScope version); a device that does not
    say so is real hardware. ``kinematics``: the robot model a simulator moves (a
    built-in model name or YAML path), "" for real controllers. ``n_joints``: 0 for
    trackers and when unknown.
    """

    kind: str
    model: str = ""
    serial: str = ""
    firmware: str = ""
    simulator: bool = False
    kinematics: str = ""
    n_joints: int = 0

    def to_dict(self) -> dict:
        """JSON-ready dict (stored with a run)."""
        return {"kind": self.kind, "model": self.model, "serial": self.serial,
                "firmware": self.firmware, "simulator": self.simulator,
                "kinematics": self.kinematics, "n_joints": self.n_joints}

    @classmethod
    def from_dict(cls, d: dict) -> DeviceIdentity:
        return cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})

    def same_device(self, other: DeviceIdentity) -> bool:
        """Whether both name the same device: kind, model and serial agree (a serial
        unknown on both sides compares the models only)."""
        return (self.kind == other.kind and self.model == other.model
                and self.serial == other.serial and self.simulator == other.simulator)

    def __str__(self) -> str:
        words = [self.model or "unknown model"]
        if self.serial:
            words.append(f"serial {self.serial}")
        if self.simulator:
            words.append(f"simulator of {self.kinematics}" if self.kinematics else "simulator")
        return " ".join(words)


@runtime_checkable
class Identified(Protocol):
    """Optional capability: say who the device is (:class:`DeviceIdentity`); call after
    ``connect``."""

    def identify(self, timeout: float = 2.0) -> DeviceIdentity: ...


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
    ``{"temp_c": 20.3, "pressure_hpa": 1013.2, "humidity_pct": 41.0}``
    (also readable as :attr:`temp_c`, :attr:`pressure_hpa`, :attr:`humidity_pct`).

    Optional, when the instrument reports them: ``cov`` the 3×3 covariance of
    ``xyz`` (mm², its diagonal ``std**2``), ``reflector`` the name of the
    reflector the tracker measured with, ``face`` the tracker face (1 or 2; 0
    unknown).
    """

    xyz: np.ndarray
    std: np.ndarray
    n: int
    timestamp: float
    env: dict[str, float] = field(default_factory=dict)
    cov: np.ndarray | None = None
    reflector: str = ""
    face: int = 0

    @property
    def temp_c(self) -> float | None:
        """Air temperature (°C) the tracker used, if reported."""
        return self.env.get("temp_c")

    @property
    def pressure_hpa(self) -> float | None:
        """Air pressure (hPa) the tracker used, if reported."""
        return self.env.get("pressure_hpa")

    @property
    def humidity_pct(self) -> float | None:
        """Relative humidity (%) the tracker used, if reported."""
        return self.env.get("humidity_pct")


@dataclass(frozen=True, kw_only=True)
class PoseMeasurement(Measurement):
    """One stationary measurement of a 6-DoF target: its position and its orientation.

    A :class:`Measurement` (``xyz``, ``std``... of the target's reference point, mm,
    tracker frame) plus ``quat``, the unit quaternion (w, x, y, z) of the target frame in
    the tracker frame (it turns target-frame vectors into tracker-frame ones:
    ``tracker_R_target``), and its uncertainty: ``std_deg`` the standard deviation of the
    rotation about the tracker's x, y, z axes (deg) and ``sigma_deg`` one number for it
    (their root mean square, the ``sigma_deg`` column of FORMATS §1). ``target``: the
    6-DoF target's name as the tracker reports it (e.g. its probe name), "" unknown.
    """

    quat: np.ndarray
    std_deg: np.ndarray
    sigma_deg: float
    target: str = ""


#: how long a driver may take to stop the robot after a move ran out of its ``timeout``,
#: before it raises :class:`~drivers.errors.CommandTimeout` (s)
STOP_AFTER_TIMEOUT_S = 2.0


@runtime_checkable
class RobotDriver(Protocol):
    """A robot controller that can move to joint or Cartesian targets and report joints.

    Moves **block**: they return once the robot has arrived and settled, or raise (module
    docstring). Errors of a move: :class:`~drivers.errors.LimitError` (target outside the
    joint limits), :class:`~drivers.errors.CommandRejected` (wrong shape, unreachable,
    refused), :class:`~drivers.errors.ProtectiveStop`,
    :class:`~drivers.errors.CommandTimeout` (not settled within ``timeout``: the robot
    was stopped), :class:`~drivers.errors.ConnectionLost`,
    :class:`~drivers.errors.NotReady`, :class:`~drivers.errors.ProtocolError`.
    """

    url: str

    def connect(self, timeout: float = 5.0) -> None:
        """Open the link; ConnectionLost when the controller cannot be reached,
        CommandTimeout when it does not answer in time."""
        ...

    def close(self) -> None:
        """Close the link; idempotent, never raises. Calls after it raise ConnectionLost
        ("not connected") until :meth:`connect`."""
        ...

    def read_joints(self, timeout: float = 1.0) -> JointReading:
        """The joints (rad, shape ``(n_joints,)``) and when they were read."""
        ...

    def move_joints(self, q: np.ndarray, speed: float = 0.5, timeout: float = 60.0) -> None:
        """Move the joints to ``q`` (rad) at ``speed`` (rad/s, the leading joint); return
        once the robot has arrived and settled (:meth:`wait_settled`'s condition), all
        within ``timeout``."""
        ...

    def move_linear(self, xyz: np.ndarray, speed: float = 100.0, timeout: float = 60.0) -> None:
        """Move the TCP in a line to ``xyz`` (mm, robot base frame; orientation kept) at
        ``speed`` (mm/s); return once the robot has arrived and settled, all within
        ``timeout``."""
        ...

    def wait_settled(self, timeout: float = 30.0) -> None:
        """Return once the robot is in position and still (at once after a move, which
        settles before it returns); ProtectiveStop on a protective or emergency stop,
        CommandRejected on a controller fault, CommandTimeout when ``timeout`` passes."""
        ...

    def status(self, timeout: float = 1.0) -> RobotStatus:
        """The controller's motion and safety state now."""
        ...

    def stop(self, timeout: float = 2.0) -> None:
        """Halt any motion; return once the robot stands still (CommandTimeout when it
        still moves after ``timeout``)."""
        ...


@runtime_checkable
class TrackerDriver(Protocol):
    """A laser tracker that measures a stationary target."""

    url: str

    def connect(self, timeout: float = 5.0) -> None:
        """Open the link and initialise the tracker when it is not (unless the driver was
        told not to)."""
        ...

    def close(self) -> None:
        """Close the link; idempotent, never raises. Calls after it raise ConnectionLost
        ("not connected") until :meth:`connect`."""
        ...

    def status(self, timeout: float = 1.0) -> TrackerStatus:
        """The tracker's state now."""
        ...

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement:
        """Measure a stationary target, averaging for ``duration_s``; return the finished
        measurement within ``timeout`` (else CommandTimeout). BeamBroken when the beam is
        broken or finds no target, NotReady when the tracker is not initialised or still
        warming up."""
        ...


@runtime_checkable
class JointTemperatures(Protocol):
    """Optional capability: each joint's temperature as the controller's drives report it
    (°C, one per joint, base to flange), for the thermal state of a sample. A controller
    found not to report them (an older firmware, a map without them) raises
    :class:`~drivers.errors.CommandRejected`."""

    def joint_temperatures(self, timeout: float = 1.0) -> tuple[float, ...]: ...


@runtime_checkable
class CommandedPosition(Protocol):
    """Optional capability: the controller's own nominal TCP position (teach pendant)."""

    def read_tcp(self, timeout: float = 1.0) -> np.ndarray:
        """Nominal TCP position (mm, robot base frame) as the controller computes it."""
        ...


# ---------------------------------------------------------------------------
# Optional tracker capabilities: small protocols a capture routine checks with
# ``isinstance(tracker, ReadyGate)`` before it relies on them.


@dataclass(frozen=True)
class Readiness:
    """The result of a tracker's ready gate: each check, and what failed in words.

    ``initialised``: the tracker was homed/initialised since power-up.
    ``warmed_up``: the laser is stable (warm-up over).
    ``weather_station``: a weather station reports the air (temperature, pressure,
    humidity) to the tracker; without one the environment must be set by hand
    (:class:`EnvironmentSensor`). ``target``: the beam is on a reflector.
    """

    initialised: bool
    warmed_up: bool
    weather_station: bool
    target: bool = True
    problems: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        """All checks passed."""
        return not self.problems

    @classmethod
    def of(cls, initialised: bool, warmed_up: bool, weather_station: bool, target: bool = True,
           detail: dict[str, str] | None = None) -> Readiness:
        """The checks with the standard words for each failure (``detail``: the device's
        own words per check, e.g. ``{"initialised": "ES_TPS_CompensationSet"}``)."""
        detail = detail or {}
        words = {
            "initialised": "not initialised: initialise it (connect with auto_init)",
            "warmed_up": "still warming up: wait until the laser is stable",
            "weather_station": "no weather station reports the air: connect one, or set the "
                               "air by hand (set_environment)",
            "target": "no reflector in the beam: put the SMR back in the beam",
        }
        ok = {"initialised": initialised, "warmed_up": warmed_up,
              "weather_station": weather_station, "target": target}
        problems = tuple(
            words[k] + (f" ({detail[k]})" if detail.get(k) else "") for k, v in ok.items() if not v
        )
        return cls(bool(initialised), bool(warmed_up), bool(weather_station), bool(target),
                   problems)

    def raise_if_not_ok(self, device: str) -> Readiness:
        """Self when every check passed, else NotReady naming the failures."""
        if self.problems:
            raise NotReady(device, "ready", "; ".join(self.problems))
        return self


@runtime_checkable
class ReadyGate(Protocol):
    """Capability: say whether the tracker is fit to measure, and why not."""

    def ready(self, timeout: float = 2.0) -> Readiness: ...

    def check_ready(self, timeout: float = 2.0) -> Readiness:
        """:meth:`ready`, raising :class:`~drivers.errors.NotReady` naming every failed check."""
        ...


@dataclass(frozen=True)
class Environment:
    """Air as the tracker uses it for refraction: °C, hPa, %RH.

    ``source`` is ``"station"`` when a weather station feeds these values,
    ``"manual"`` when they were set by a client (or are the tracker's defaults).
    """

    temp_c: float
    pressure_hpa: float
    humidity_pct: float
    source: str = "manual"


@runtime_checkable
class EnvironmentSensor(Protocol):
    """Capability: read the tracker's environment values and set them by hand."""

    def environment(self, timeout: float = 2.0) -> Environment: ...

    def set_environment(
        self, temp_c: float, pressure_hpa: float, humidity_pct: float, timeout: float = 2.0
    ) -> None: ...


@dataclass(frozen=True)
class Reflector:
    """A reflector the tracker knows: its name, the tracker's id for it, its type and
    surface offset (mm, sphere centre to contact surface)."""

    name: str
    id: int
    target_type: str = ""
    surface_offset_mm: float = 0.0


@runtime_checkable
class ReflectorSelect(Protocol):
    """Capability: list the reflectors and choose one by name."""

    def reflectors(self, timeout: float = 2.0) -> list[Reflector]: ...

    def reflector(self, timeout: float = 2.0) -> Reflector:
        """The reflector the tracker measures with now."""
        ...

    def set_reflector(self, name: str, timeout: float = 2.0) -> Reflector:
        """Select the reflector called ``name``; CommandRejected naming the known ones."""
        ...


@runtime_checkable
class SixDof(Protocol):
    """Capability: measure a 6-DoF target's position and orientation (a T-Mac, say)."""

    def measure_pose(self, duration_s: float = 0.5, timeout: float = 10.0) -> PoseMeasurement:
        """Measure the stationary 6-DoF target, averaging for ``duration_s``; raises
        :class:`~drivers.errors.CommandRejected` when the tracker has no 6-DoF target (or
        cannot measure one now, e.g. in face 2) and
        :class:`~drivers.errors.BeamBroken` when the target is out of sight."""
        ...


@runtime_checkable
class TwoFace(Protocol):
    """Capability: measure in both tracker faces (front and back sight)."""

    def face(self, timeout: float = 2.0) -> int:
        """The current face, 1 or 2."""
        ...

    def change_face(self, timeout: float = 30.0) -> int:
        """Turn the tracker head to the other face; returns the new face."""
        ...

    def measure_faces(
        self, duration_s: float = 0.5, timeout: float = 60.0
    ) -> tuple[Measurement, Measurement]:
        """Measure the stationary target in the current face, change face, measure
        again; returns ``(face-1 measurement, face-2 measurement)``."""
        ...


class _FaceChanging(Protocol):
    """What :func:`measure_both_faces` asks of a tracker."""

    def measure(self, duration_s: float = 0.5, timeout: float = 10.0) -> Measurement: ...

    def change_face(self, timeout: float = 30.0) -> int: ...


def measure_both_faces(tracker: _FaceChanging, duration_s: float,
                       timeout: float) -> tuple[Measurement, Measurement]:
    """:meth:`TwoFace.measure_faces` for any tracker with ``measure``, ``change_face``
    and measurements that carry their ``face``: measure, change face, measure;
    returns ``(face 1, face 2)``. The tracker stays in the second face."""
    deadline = time.monotonic() + timeout

    def left() -> float:
        return max(deadline - time.monotonic(), 0.01)

    first = tracker.measure(duration_s, left())
    tracker.change_face(left())
    second = tracker.measure(duration_s, left())
    if sorted((first.face, second.face)) != [1, 2]:
        raise ProtocolError(getattr(tracker, "url", "tracker"), "change_face",
                            f"measured in faces {first.face} then {second.face}, expected both")
    return (first, second) if first.face == 1 else (second, first)
