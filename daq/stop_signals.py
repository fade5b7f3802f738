"""Stops that stop: how a running capture answers Ctrl-C, SIGTERM and SIGHUP.

* The first Ctrl-C (SIGINT) asks the executor to stop after the current point (the
  run ends ``stopped``, exit code 130).
* A second Ctrl-C, SIGTERM or SIGHUP stops at once: :class:`StopNow` is raised in the
  main thread wherever it is (a move, a wait, a measurement), the executor sends the
  controller's stop (``RobotDriver.stop``: the line protocol's ``STOP``, Modbus
  ``CMD_STOP``, ur-rtde ``stopJ``) and leaves the run ``paused`` with the reason; the
  command exits with 128 + the signal number (130, 143, 129).

Handlers are installed only in the main thread (elsewhere :func:`stop_handlers` does
nothing) and the previous ones are restored on exit.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator


class StopNow(BaseException):  # noqa: N818 - a request, like KeyboardInterrupt
    """Stop at once (a second Ctrl-C, SIGTERM, SIGHUP); ``signum`` the signal."""

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(signal_name(signum))


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


@contextlib.contextmanager
def stop_handlers(request_stop: Callable[[], None], stop_requested: Callable[[], bool],
                  halting: Callable[[], bool]) -> Iterator[None]:
    """Install the handlers for the block.

    ``request_stop()`` is the first Ctrl-C (stop after the current point);
    ``stop_requested()`` tells whether it came already (then Ctrl-C stops at once);
    while ``halting()`` (the robot's stop is being sent) further signals are ignored.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, frame):
        if halting():
            return
        if signum == signal.SIGINT and not stop_requested():
            request_stop()
            return
        raise StopNow(signum)

    wanted = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP")
                                                else [])
    previous = {s: signal.getsignal(s) for s in wanted}
    for s in wanted:
        signal.signal(s, handler)
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
