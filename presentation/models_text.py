"""The table ``cellcal models`` prints: one row per built-in model."""

from __future__ import annotations

from .text_table import table


def models_table(models) -> str:
    """``models``: one object per model with ``name``, ``convention``, ``joints``,
    ``mass_model`` (bool) and ``reach_mm`` (the sum of |a| + |d|)."""
    return table([[m.name, m.convention, m.joints, "yes" if m.mass_model else "no",
                   f"{m.reach_mm:.0f}"] for m in models],
                 ["model", "convention", "joints", "mass model", "sum |a|+|d| mm"])
