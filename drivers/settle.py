"""Waiting until a robot is settled, by polling its status: shared by the drivers whose
controllers report in-position/moving flags (line protocol, Modbus)."""

from __future__ import annotations

import time
from collections.abc import Callable

from .errors import CommandRejected, CommandTimeout, ProtectiveStop
from .protocols import RobotStatus


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
