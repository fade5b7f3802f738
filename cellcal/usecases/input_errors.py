"""A reader's input error as a usage error of the command (exit 2, the reader's message).
Light at import: the core's error classes are loaded only when called."""

from __future__ import annotations

from ..errors import UsageError


def wrap_errors(fn, *exc):
    """Run fn(); turn the given exception types into UsageError."""
    from calibration import DataError, ModelError
    from calibration.effects import EffectError
    from calibration.exports.params_io import ParamsError

    try:
        return fn()
    except (ModelError, DataError, EffectError, ParamsError, *exc) as e:
        raise UsageError(str(e)) from None
