"""The devices of a run: open them from URLs, learn who they are, check them against the
model, and tell whether two runs were measured in the same cell.

:func:`open_drivers` connects a robot and a tracker; :func:`identify` asks each who it
is (:class:`drivers.protocols.DeviceIdentity`: model, serial number, simulator or
not); :func:`check_robot` refuses a robot whose joint count (or, for a simulator, whose
robot model) is not the run's model's — before any run exists; :func:`same_cell`
compares the identities stored with a run with the devices reached now;
:func:`default_robot_id` names the robot for the store (``MODEL/SERIAL``).

Errors: :class:`~daq.errors.RequestError` for a URL no driver knows or a robot that does
not fit the model (exit code 2), :class:`~daq.errors.ConnectFailed` when a device cannot
be reached.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

from drivers.protocols import DeviceIdentity, Identified

from .errors import ConnectFailed, RequestError


@dataclass(frozen=True)
class CellIdentity:
    """Who the robot and the tracker said they were."""

    robot: DeviceIdentity
    tracker: DeviceIdentity

    @property
    def simulated(self) -> bool:
        """Both devices declared themselves simulators."""
        return self.robot.simulator and self.tracker.simulator


def describe(driver) -> str:
    """A one-line description of a driver (class, model, serial, firmware when known)."""
    parts = [type(driver).__name__]
    for k in ("model", "serial", "firmware"):
        v = getattr(driver, k, "")
        if isinstance(v, str) and v:
            parts.append(f"{k}={v}")
    n = getattr(driver, "n_joints", 0)
    if isinstance(n, int) and n:
        parts.append(f"joints={n}")
    return " ".join(parts)


def open_drivers(robot_url: str, tracker_url: str, timeout: float = 5.0):
    """Connected (robot, tracker); closes what was opened when the other fails.

    :class:`RequestError` for a URL no driver knows, :class:`ConnectFailed` when a
    device cannot be reached.
    """
    from drivers.errors import DriverError
    from drivers.urls import open_robot, open_tracker

    try:
        robot = open_robot(robot_url)
        tracker = open_tracker(tracker_url)
    except ValueError as e:
        raise RequestError(str(e)) from None
    try:
        robot.connect(timeout=timeout)
        tracker.connect(timeout=timeout)
    except DriverError as e:
        robot.close()
        tracker.close()
        raise ConnectFailed(str(e)) from e
    return robot, tracker


@contextlib.contextmanager
def devices(robot_url, tracker_url, given, timeout, on_fail=None) -> Iterator[tuple]:
    """The ``given`` connected devices (left open), else the URLs' (closed at the end);
    ``on_fail(error)`` is called before a :class:`ConnectFailed` propagates."""
    if given is not None:
        yield given
        return
    try:
        robot, tracker = open_drivers(robot_url, tracker_url, timeout)
    except ConnectFailed as e:
        if on_fail is not None:
            on_fail(e)
        raise
    try:
        yield robot, tracker
    finally:
        robot.close()
        tracker.close()


def _identity(driver, kind: str, timeout: float) -> DeviceIdentity:
    from drivers.errors import DriverError

    if isinstance(driver, Identified):
        try:
            return driver.identify(timeout=timeout)
        except DriverError as e:
            raise ConnectFailed(f"{kind} {getattr(driver, 'url', '')}: identify: {e}") from e
    n = getattr(driver, "n_joints", 0)
    return DeviceIdentity(kind, str(getattr(driver, "model", "") or ""),
                          str(getattr(driver, "serial", "") or ""),
                          str(getattr(driver, "firmware", "") or ""),
                          n_joints=n if isinstance(n, int) else 0)


def identify(robot, tracker, timeout: float = 2.0) -> CellIdentity:
    """Who the connected robot and tracker are (a driver without ``identify`` gives what
    its attributes say, never a simulator)."""
    return CellIdentity(_identity(robot, "robot", timeout), _identity(tracker, "tracker",
                                                                       timeout))


def check_robot(model, robot, identity: DeviceIdentity) -> None:
    """Refuse a robot that cannot be the model's: another joint count, or a simulator of
    another robot model (:class:`RequestError`, before a run exists)."""
    url = getattr(robot, "url", "")
    n = getattr(robot, "n_joints", 0) or identity.n_joints
    if isinstance(n, int) and n and n != model.n_joints:
        raise RequestError(f"the robot at {url} has {n} joints, the model {model.name} has "
                           f"{model.n_joints}: wrong --model, or the wrong robot")
    if identity.simulator and identity.kinematics and identity.kinematics != model.name:
        raise RequestError(f"the robot at {url} simulates a {identity.kinematics}, the run's "
                           f"model is {model.name}: wrong --model, or the wrong robot")


def default_robot_id(identity: DeviceIdentity | None, given: str | None = None) -> str | None:
    """Who the robot is, as recorded with a run (``runs.robot_id``): ``given`` (a name from
    the command line), else the controller's ``MODEL/SERIAL`` when it reports a serial
    number (its :class:`DeviceIdentity`), else None."""
    if given:
        return given
    if identity is not None and identity.serial:
        return f"{identity.model}/{identity.serial}" if identity.model else identity.serial
    return None


def stored_identity(d: dict | None) -> DeviceIdentity | None:
    return None if d is None else DeviceIdentity.from_dict(d)


def same_cell(run, now: CellIdentity, robot_url: str, tracker_url: str) -> tuple[bool, str]:
    """Whether the devices reached now are the run's: (same, why not).

    Both devices must say the same model and serial number as stored with the run. A
    device that gives no serial number (on either side) is the same only at the same
    URL. A run stored without identities (before schema 4) cannot be compared: same.
    """
    why = []
    for kind, stored, cur, url, old_url in (
            ("robot", run.robot_identity, now.robot, robot_url, run.robot_url),
            ("tracker", run.tracker_identity, now.tracker, tracker_url, run.tracker_url)):
        old = stored_identity(stored)
        if old is None:
            continue
        if not old.same_device(cur):
            why.append(f"the {kind} was {old}, {url} is {cur}")
        elif not (old.serial and cur.serial) and url != old_url:
            why.append(f"the {kind} at {url} gives no serial number to tell it from the "
                       f"run's ({old_url})")
    return not why, "; ".join(why)
