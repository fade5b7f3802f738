"""The calibration core's errors, each with the exit code the command line gives it.

Bad input (a file, a value or a model the core refuses) is exit 2; data too poor for
what was asked (they cannot decide: too few poses, a rank-deficient design) is exit 3, and
so are data too large for the memory the machine has (:class:`TooLarge`).
The command line maps every error of every layer through ``exit_code``
(:mod:`cellcal.cli`); the codes are documented once, in docs/formats.md §6.
"""

from __future__ import annotations


class CalibrationError(Exception):
    """An error of the calibration core; ``exit_code`` is what the command line exits with."""

    exit_code = 2


class InputError(CalibrationError, ValueError):
    """Bad input: the message names the file (line, column or field) and what is wrong."""


class DataError(InputError):
    """A data file that cannot be used; the message names file, line and column."""


class ModelError(InputError):
    """A model file or name that cannot be used; the message names the file and field."""


class UrdfError(ModelError):
    """A URDF (or a chain in it) that cannot be used; the message names the element."""


class EffectError(InputError):
    """An effect that cannot be used with this model or data (message says why)."""


class ParamsError(InputError):
    """A params.json that cannot be used."""


class CellError(InputError):
    """A cell file or value that cannot be used; the message names the file and field."""


class URConfError(InputError):
    """A calibration.conf or delta set that cannot be used."""


class ExportError(InputError):
    """A model that the asked format cannot hold (the message says why)."""


class InsufficientData(CalibrationError):  # noqa: N818 - named for what the data are
    """The data are too poor for what was asked (exit code 3): the message says why and
    what to capture instead."""

    exit_code = 3


class TooLarge(CalibrationError):  # noqa: N818 - named for what the data are
    """The data are too large for the memory this machine has left (exit code 3), said
    before the work starts: the message gives the size that would fit."""

    exit_code = 3


class OutsideEnvelope(InsufficientData):
    """Targets beyond the calibrated envelope were refused (``--strict-range``, exit code
    3): the calibration did not measure there; the message names them."""
