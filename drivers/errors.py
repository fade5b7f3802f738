"""One error hierarchy for every driver.

Each error is also the built-in it resembles (``CommandTimeout`` is a
``TimeoutError``, ``ConnectionLost`` a ``ConnectionError``...), so callers can
catch either. Messages name the device and the command: ``"tracker
tracker+tcp://127.0.0.1:15700: MEAS: ERR 14 BEAM_BROKEN"``. Every one is a failure at run
time: ``exit_code`` 1 at the command line (docs/formats.md §6).
"""

from __future__ import annotations


class DriverError(Exception):
    """Base of every error raised by a driver.

    Parameters
    ----------
    device : str
        Who failed: a URL or a short description of the device.
    command : str
        What was being done when it failed (``"moveJ"``, ``"MEAS"``...).
    detail : str
        The device's own words, or what went wrong.
    """

    #: True when retrying the same command (after a reconnect) may succeed.
    transient = False
    #: what the command line exits with when this error ends a command: run time failure
    exit_code = 1

    def __init__(self, device: str = "", command: str = "", detail: str = "") -> None:
        self.device = device
        self.command = command
        self.detail = detail
        parts = [p for p in (device, command, detail) if p]
        super().__init__(": ".join(parts) if parts else self.__class__.__name__)


class ConnectionLost(DriverError, ConnectionError):
    """The link to the device is gone (socket closed, port vanished, stale data)."""

    transient = True


class CommandTimeout(DriverError, TimeoutError):
    """The device did not answer or finish within the call's timeout."""

    transient = True


class CommandRejected(DriverError, ValueError):
    """The device refused the command (bad argument, out of range, Modbus exception)."""


class ProtectiveStop(DriverError):
    """The robot is in a protective or emergency stop; a person must clear it."""


class BeamBroken(DriverError):
    """The tracker lost its beam (line of sight) during a measurement."""

    transient = True


class NotReady(DriverError):
    """The device is not in a state to do this yet (not initialised, warming up, busy)."""

    transient = True


class ProtocolError(DriverError):
    """The device answered something the protocol does not allow (garbage, bad frame)."""

    transient = True


class LimitError(DriverError, ValueError):
    """A commanded target lies outside the joint limits known to the driver."""
