"""Asking the user before anything moves: :func:`confirm_motion`, the ``confirm`` callback
``capture`` and ``resume`` hand to the capture service."""

from __future__ import annotations

import sys

from ..errors import UsageError


def confirm_motion(cell, urls: list[str], yes: bool, stdin=None, stderr=None) -> None:
    """Ask before moving devices that did not identify themselves as simulators.

    ``cell`` is what they said (:class:`daq.devices.CellIdentity`); only a robot and a
    tracker that both declared themselves simulators go without asking. Any other
    endpoint — a loopback address or a pty included (an SSH tunnel or a serial bridge
    may lead to a real controller) — needs ``yes`` or a ``yes`` typed at a terminal;
    UsageError when refused (nothing moved).
    """
    if cell.simulated or yes:
        return
    what = ", ".join(f"{u} ({d})" for u, d in zip(urls, (cell.robot, cell.tracker),
                                                     strict=True) if not d.simulator)
    stdin = stdin or sys.stdin
    stderr = stderr or sys.stderr
    try:
        tty = stdin.isatty()
    except (AttributeError, ValueError):
        tty = False
    if not tty:
        raise UsageError(f"{what} did not identify as a simulator: refusing to move without "
                         "confirmation (no terminal); pass --yes to confirm")
    stderr.write(f"About to move real hardware: {what}.\n"
                 "Is the cell clear and the robot's speed limited? Type 'yes' to start: ")
    stderr.flush()
    if stdin.readline().strip().lower() not in ("y", "yes"):
        raise UsageError("not confirmed: nothing moved")


def confirm_with(yes: bool):
    """The service's ``confirm(cell, robot_url, tracker_url)`` callback: :func:`confirm_motion`."""
    return lambda cell, robot, tracker: confirm_motion(cell, [robot, tracker], yes)
