"""The capture service's errors, one family (:class:`DaqError`), each class with the exit
code the command line gives it (:mod:`cellcal.cli`; the codes: docs/formats.md §6).

The executor handles two families alike (record, then retry or pause):
:class:`drivers.errors.DriverError` (the devices) and :class:`CaptureError` (the capture:
a measurement too noisy, a closed loop that did not converge). Both carry ``transient``
(retrying the point may succeed) and the executor names either kind in the run's
interruptions table (:attr:`CaptureError.kind`).

The service (:mod:`daq.service`) raises :class:`RequestError` for input it refuses (a
model, parameters, a plan that fails the dry run, an unknown run, a tracker that fails
its checks: :class:`TrackerRefused`, a plan made blind: :class:`TrackerUnknown`; exit
code 2, but 3 for :class:`NotEnoughVisible`, a
plan the tracker would not see) and :class:`ConnectFailed` when the devices cannot be
reached (exit code 1). The run store's errors are its own (:mod:`daq.store.errors`).
"""

from __future__ import annotations


class DaqError(Exception):
    """An error of the capture service; ``exit_code`` is what the command line exits with
    (1: the work failed at run time)."""

    exit_code = 1


class CaptureError(DaqError):
    """A point could not be acquired for a reason of the capture itself (exit code 1).

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


class ZeroDiverged(CaptureError):
    """The zero-point closed loop stopped: the measured tip does not behave as its
    corrections predict (a tracker reading that jumped, a frame of another cell), or it
    starts too far from the target to be corrected safely."""

    kind = "zero_diverged"


class RequestError(DaqError, ValueError):
    """The service refuses its input (model, parameters, plan, run): exit code 2 at the CLI."""

    exit_code = 2


class NotEnoughVisible(RequestError):
    """The tracker would not see enough of a plan's targets (facing away, a link or fixture in
    the beam); the message lists them and says what to change. Exit code 3 at the CLI (the
    data would be too poor), not 2."""

    exit_code = 3


class TrackerUnknown(RequestError):
    """A plan would be made blind: the tracker's position is unknown, the reflector does not
    accept every direction and the line of sight was not waived (``visibility=False``); the
    message names the ways to give the position. Exit code 2; nothing is opened or moved."""


class PlanRefused(RequestError):
    """A plan failed the dry run; ``result`` (a :class:`daq.check.CheckResult`) names why."""

    def __init__(self, result) -> None:
        self.result = result
        super().__init__(result.report())


class TrackerRefused(RequestError):
    """The tracker failed a check before the run (not ready, two faces apart, an unknown
    reflector, ``--meteo`` it cannot take): :mod:`daq.tracker_checks`. Nothing is stored."""


class ConnectFailed(DaqError, ConnectionError):
    """The robot or the tracker could not be reached (exit code 1)."""

    exit_code = 1


def one_line(e: Exception) -> str:
    """An error's message on one line: a pydantic ValidationError as ``field: reason; ...``
    (its own text spans lines and links to the docs), anything else as it is."""
    errors = getattr(e, "errors", None)
    if callable(errors):
        try:
            items = errors()
        except Exception:  # noqa: BLE001 - not a ValidationError after all
            items = None
        if items:
            return "; ".join(f"{'.'.join(str(p) for p in it.get('loc', ())) or 'value'}: "
                             f"{it.get('msg', '')}" for it in items)
    return " ".join(str(e).split())
