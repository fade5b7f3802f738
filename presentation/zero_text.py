"""The zero-point recalibration for people (``cellcal zero`` without ``--json``): the
postures and each method's convergence, a row per joint (offset, its std, the seed
method's offset, changed or not), then the tool, the target, the notes and the verdict.

Read from the ``zero --json`` document (:func:`presentation.summaries.zero_summary` plus
``source``, ``notes``, ``out_file``) and the :class:`~calibration.zero_point.ZeroResult`
objects; the caller lays the rows out as a table.
"""

from __future__ import annotations

import math

from calibration.zero_point import ZeroResult

#: the joint table's columns
ZERO_HEADER = ["joint", "offset deg", "std deg", "seed deg", "changed"]


def _deg(v: float) -> str:
    return f"{math.degrees(v):.4f}" if math.isfinite(v) else "-"


def zero_head(doc: dict, main: ZeroResult, results: dict[str, ZeroResult]) -> list[str]:
    """The postures, each method's convergence and time, the postures left out."""
    lines = [f"postures  {doc['source']}: {doc['n_poses']} postures; model {doc['model']}"]
    lines += [f"{name:9s} {r.reason}; rms {r.rms_mm:.4f} mm; {r.solve_s * 1000:.1f} ms"
              for name, r in results.items()]
    if main.outliers:
        lines.append(f"outliers  {', '.join(main.outliers)} (left out)")
    return lines


def zero_rows(doc: dict, main: ZeroResult, seed: ZeroResult | None) -> list[list[str]]:
    """One row per joint: ``undetermined`` where the postures cannot tell."""
    rows = []
    for j in range(len(main.offsets)):
        det = bool(main.determined[j])
        rows.append([
            f"j{j + 1}",
            _deg(main.offsets[j]) if det else "undetermined",
            _deg(main.std[j]) if det else "-",
            _deg(seed.offsets[j]) if seed is not None and det else "-",
            "yes" if f"j{j + 1}" in doc["changed"] else "",
        ])
    return rows


def zero_tail(doc: dict, main: ZeroResult, out) -> list[str]:
    """The tool and the target found, the notes, the status, and the file written (or
    not: ``out`` is the file asked for, None when none was)."""
    lines = [f"tool      {', '.join(f'{v:.3f}' for v in main.tool)} mm (flange frame)",
             f"target    {', '.join(f'{v:.3f}' for v in main.target)} mm (base frame)"]
    lines += [f"note      {name}: {why}" for name, why in main.fixed.items()]
    lines += [f"note      {why}" for why in doc["notes"]]
    lines.append(f"status    {doc['status']}"
                 + (": " + "; ".join(doc["reasons"]) if doc["reasons"] else ""))
    if out is not None:
        lines.append(f"written   {out}" if doc["out_file"] else f"not written ({out}): "
                     "status poor")
    return lines
