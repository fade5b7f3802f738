"""Waiting on a robot by polling its status, shared by the drivers whose controllers
report in-position/moving flags (line protocol, Modbus, the in-process simulator): until
it is settled, until a move has settled (stopping it when it runs out of time), until it
stands still after a stop."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

from .errors import CommandRejected, CommandTimeout, DriverError, ProtectiveStop
from .protocols import STOP_AFTER_TIMEOUT_S, RobotStatus


def poll_until_settled(status: Callable[[float], RobotStatus], device: str, timeout: float,
                       poll_s: float) -> None:
    """Call ``status(timeout)`` every ``poll_s`` s until in position and not moving.

    Raises ProtectiveStop on a protective or emergency stop, CommandRejected on a
    controller fault, CommandTimeout (naming ``wait_settled``) when ``timeout`` passes
    first — also when a status poll itself runs out of the remaining time.
    """
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            raise CommandTimeout(device, "wait_settled", f"not settled after {timeout} s")
        try:
            st = status(max(left, 0.01))
        except CommandTimeout as e:
            raise CommandTimeout(device, "wait_settled",
                                 f"not settled after {timeout} s ({e.detail})") from e
        if st.protective_stop or st.emergency_stop:
            raise ProtectiveStop(device, "wait_settled", st.message)
        if st.fault:
            raise CommandRejected(device, "wait_settled", f"fault: {st.message}")
        if st.in_position and not st.moving:
            return
        time.sleep(min(poll_s, max(deadline - time.monotonic(), 0.0)))


def settle_move(wait_settled: Callable[[float], None], stop: Callable[[float], None],
                device: str, command: str, deadline: float) -> None:
    """The end of a blocking move sent as ``command``: ``wait_settled`` with the time left
    before ``deadline``; when that runs out, ``stop`` the robot (best effort, within
    :data:`~drivers.protocols.STOP_AFTER_TIMEOUT_S`) and raise CommandTimeout naming
    ``command``. Stops and faults raise as ``wait_settled`` raises them."""
    try:
        wait_settled(max(deadline - time.monotonic(), 0.0))
    except CommandTimeout as e:
        with contextlib.suppress(DriverError):
            stop(STOP_AFTER_TIMEOUT_S)
        raise CommandTimeout(device, command,
                             f"target not reached within timeout; robot stopped ({e.detail})"
                             ) from e


def poll_until_still(status: Callable[[float], RobotStatus], device: str, command: str,
                     deadline: float, poll_s: float) -> None:
    """Call ``status(timeout)`` every ``poll_s`` s until the robot is not moving (after a
    stop); CommandTimeout naming ``command`` when ``deadline`` passes first."""
    while True:
        left = deadline - time.monotonic()
        try:
            st = status(max(left, 0.01))
        except CommandTimeout as e:
            raise CommandTimeout(device, command, f"still moving? ({e.detail})") from e
        if not st.moving:
            return
        if time.monotonic() >= deadline:
            raise CommandTimeout(device, command, "still moving after the timeout")
        time.sleep(min(poll_s, max(deadline - time.monotonic(), 0.0)))
