"""Plain-text tables and numbers for the command line: :func:`table` lays rows out in
aligned columns, :func:`fmt` writes a number with fixed decimals (``-`` for none)."""

from __future__ import annotations

import math


def fmt(v, digits: int = 3) -> str:
    """``v`` with ``digits`` decimals; ``-`` for None, NaN and infinities."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    return f"{v:.{digits}f}"


def table(rows: list[list[str]], header: list[str], left: tuple[int, ...] = (0,)) -> str:
    """A plain-text table: columns in ``left`` left-aligned, the others right-aligned."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(str(h).ljust(w) for h, w in zip(header, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    for r in rows:
        lines.append("  ".join(
            str(c).ljust(w) if i in left else str(c).rjust(w)
            for i, (c, w) in enumerate(zip(r, widths, strict=True))
        ))
    return "\n".join(line.rstrip() for line in lines)
