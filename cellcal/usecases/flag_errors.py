"""A model's validation errors reported with the flags the user typed.

A use case builds a model of a lower layer (the capture service's
:class:`~daq.run_context.ExecutorOptions`, :class:`~daq.motion_guard.MotionLimits`) from
request values; a value it refuses is named by the flag it came from: ``flags`` maps the
model's field names to flags (a request's aliases, :func:`aliases`, or a flag table).
"""

from __future__ import annotations

from pydantic import BaseModel, ValidationError

from ..errors import UsageError


def aliases(request: type[BaseModel]) -> dict[str, str]:
    """Field name -> flag (the alias) of a request class."""
    return {name: info.alias for name, info in request.model_fields.items() if info.alias}


def flag_error(e: ValidationError, flags: dict[str, str]) -> UsageError:
    """One line per refused value, ``--flag[.index]: reason`` (the location's first part,
    a field name, replaced by its flag)."""
    parts = []
    for err in e.errors(include_url=False):
        loc = [str(x) for x in err["loc"]] or ["value"]
        parts.append(f"{'.'.join([flags.get(loc[0], loc[0]), *loc[1:]])}: {err['msg']}")
    return UsageError("; ".join(parts))


def build(model: type[BaseModel], values: dict, flags: dict[str, str]):
    """``model(**values)``; a refused value is a UsageError naming its flag."""
    try:
        return model(**values)
    except ValidationError as e:
        raise flag_error(e, flags) from None
