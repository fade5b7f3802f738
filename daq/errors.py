"""The capture's own errors: what goes wrong in acquiring a point that is not a driver's fault,
and what the capture service refuses.

The executor handles two families alike (record, then retry or pause):
:class:`drivers.errors.DriverError` (the devices) and :class:`CaptureError` (the capture:
a measurement too noisy, a closed loop that did not converge). Both carry ``transient``
(retrying the point may succeed) and the executor names either kind in the run's
interruptions table (:attr:`CaptureError.kind`).

The service (:mod:`daq.service`) raises :class:`RequestError` for input it refuses (a
model, parameters, a plan that fails the dry run, an unknown run; exit code 2, but 3 for
:class:`NotEnoughVisible`, a plan the tracker would not see) and :class:`ConnectFailed`
when the devices cannot be reached (exit code 1).
"""

from __future__ import annotations


class CaptureError(Exception):
    """A point could not be acquired for a reason of the capture itself.

    Parameters as :class:`drivers.errors.DriverError` (``device``, ``command``,
    ``detail``), so both read alike: ``"tracker tracker+tcp://...: measure: std ..."``.
    """

    #: True when acquiring the same point again (after a reconnect) may succeed
    transient = False
    #: the interruption kind recorded in the run store
    kind = "capture"

    def __init__(self, device: str = "", command: str = "", detail: str = "") -> None:
        self.device, self.command, self.detail = device, command, detail
        parts = [p for p in (device, command, detail) if p]
        super().__init__(": ".join(parts) if parts else self.__class__.__name__)


class QualityError(CaptureError):
    """The tracker's std stayed above the threshold after the remeasurements."""

    transient = True
    kind = "quality"


class ZeroNotReached(CaptureError):
    """The zero-point closed loop did not bring the tool tip onto the target."""

    kind = "zero_not_reached"


class RequestError(ValueError):
    """The service refuses its input (model, parameters, plan, run): exit code 2 at the CLI."""


class NotEnoughVisible(RequestError):
    """The tracker would not see enough of a plan's targets (facing away, a link or fixture in
    the beam); the message lists them and says what to change. Exit code 3 at the CLI (the
    data would be too poor), not 2."""

    exit_code = 3


class PlanRefused(RequestError):
    """A plan failed the dry run; ``result`` (a :class:`daq.check.CheckResult`) names why."""

    def __init__(self, result) -> None:
        self.result = result
        super().__init__(result.report())


class ConnectFailed(ConnectionError):
    """The robot or the tracker could not be reached."""
