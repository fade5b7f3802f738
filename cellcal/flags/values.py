"""Values the user types as text: ``"1,2,3"`` as numbers.

Free of heavy imports: the parser's helpers (:mod:`cellcal.flags.routine_args`) use it
too.
"""

from __future__ import annotations

import math


def parse_floats(text: str, n: int | None = None) -> list[float]:
    """``"1,2,3"`` as finite floats (exactly ``n`` when given); ValueError saying what was
    expected. A NaN or an infinity is refused here, as a scalar flag's is, so that no list
    option carries one past the parser to a device or a file."""
    try:
        v = [float(s) for s in str(text).replace(" ", "").split(",") if s]
    except ValueError:
        raise ValueError(f"expected comma-separated numbers, got {text!r}") from None
    if n is not None and len(v) != n:
        raise ValueError(f"expected {n} numbers, got {len(v)}")
    if not all(math.isfinite(x) for x in v):
        raise ValueError(f"expected {'' if n is None else f'{n} '}finite numbers, got {text!r}")
    return v


def floats(text: str | None, n: int | None, what: str) -> list[float] | None:
    """:func:`parse_floats` of ``text`` (None stays None); ValueError naming ``what``."""
    if text is None:
        return None
    try:
        return parse_floats(text, n)
    except ValueError as e:
        raise ValueError(f"{what}: {e}") from None
