"""Typed requests: what a command was asked, checked once, naming the user's flags.

A command parses its arguments (argparse), then builds one :class:`Request` subclass from
them and hands it to its use-case function. The request's fields carry the command-line
names as aliases (``floor_z_mm: float = Field(alias="--floor-z-mm")``), so a refused value
is reported with the flag the user typed, with no string patching of field names::

    class CaptureLimits(Request):
        floor_z_mm: FiniteFloat | None = Field(None, alias="--floor-z-mm")

    limits = CaptureLimits.from_args(args)      # UsageError "--floor-z-mm: ..." (exit 2)

Positional arguments take their metavar as alias (``Field(alias="DATA.csv")``). Requests
are frozen; a use-case function reads them and never the argparse namespace.

This module imports pydantic: a command imports it (and its use-case module) inside its
``run``, never at the parser's start-up (``cellcal --help`` stays fast).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Self

from pydantic import AfterValidator, BaseModel, ConfigDict, ValidationError

from .errors import UsageError


def _finite(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"{v} is not a finite number")
    return v


def _finite_all(v: tuple[float, ...]) -> tuple[float, ...]:
    for x in v:
        _finite(x)
    return v


#: a finite number (NaN and infinities refused)
FiniteFloat = Annotated[float, AfterValidator(_finite)]
#: a tuple of finite numbers
FiniteFloats = Annotated[tuple[float, ...], AfterValidator(_finite_all)]


class Request(BaseModel):
    """Base of the commands' typed requests (frozen; unknown fields refused)."""

    model_config = ConfigDict(frozen=True, extra="forbid", populate_by_name=True,
                              arbitrary_types_allowed=True)

    @classmethod
    def from_args(cls, args: Any, **given: Any) -> Self:
        """The request from an argparse namespace (attributes named as the fields; absent
        ones take the field's default) and ``given`` values (by field name), checked.

        Raises
        ------
        UsageError
            A value the request refuses, naming its flag: ``--floor-z-mm: ...``.
        """
        data: dict[str, Any] = {}
        for name, info in cls.model_fields.items():
            if name in given:
                data[info.alias or name] = given[name]
            elif hasattr(args, name):
                data[info.alias or name] = getattr(args, name)
        try:
            return cls.model_validate(data)
        except ValidationError as e:
            raise UsageError(describe_validation(e)) from None


def describe_validation(e: ValidationError) -> str:
    """One line per refused value, each naming the flag (the field's alias)."""
    parts = []
    for err in e.errors(include_url=False):
        where = ".".join(str(x) for x in err["loc"]) or "request"
        msg = err["msg"]
        for prefix in ("Value error, ", "Assertion failed, "):
            msg = msg.removeprefix(prefix)
        parts.append(f"{where}: {msg}")
    return "; ".join(parts)
