"""What ``cellcal compensate --program`` prints: the report of a compensated robot program
in words (:func:`program_lines`) and as one JSON object (:func:`program_summary`).

A report is any object with the attributes of
:class:`cellcal.programs.program_report.ProgramReport`: ``source``, ``out``, ``language``,
``n_targets``, ``rows`` (one dict per compensated target: ``line``, ``kind``,
``context``, ``correction_mm``/``_deg``, ``predicted_miss_mm``/``_deg``,
``outside_range``: what lies beyond the calibrated envelope), ``refusals``
(``line``, ``construct``, ``reason``), ``notes`` and ``written``. Nothing is printed here.
"""

from __future__ import annotations

import numpy as np


def _stats(rows: list[dict], key: str) -> tuple[float, float]:
    """(RMS, worst) of one column of the rows (0, 0 without rows)."""
    v = np.array([r[key] for r in rows])
    return (float(np.sqrt(np.mean(v**2))), float(v.max())) if v.size else (0.0, 0.0)


def _refusal(r) -> str:
    return f"line {r.line}: {r.construct}: {r.reason}"


def program_lines(report) -> list[str]:
    """The report in words: targets found and compensated, the predicted miss without
    compensation and the correction (RMS, worst), what was not compensated (with lines),
    the notes, and what was written."""
    out = [f"{report.source}: {report.language}, {report.n_targets} targets found, "
           f"{len(report.rows)} compensated"]
    if report.rows:
        rms, worst = _stats(report.rows, "predicted_miss_mm")
        out.append(f"  predicted miss without compensation: RMS {rms:.3f} mm, "
                   f"worst {worst:.3f} mm")
        rms, worst = _stats(report.rows, "correction_mm")
        out.append(f"  correction: RMS {rms:.3f} mm, worst {worst:.3f} mm")
    beyond = [r for r in report.rows if r.get("outside_range")]
    if beyond:
        out.append(f"  beyond the calibrated envelope ({len(beyond)} of {len(report.rows)}): "
                   + "; ".join(f"line {r['line']} ({', '.join(r['outside_range'])})"
                               for r in beyond[:10])
                   + (f"; and {len(beyond) - 10} more" if len(beyond) > 10 else ""))
    if report.refusals:
        out.append(f"  not compensated ({len(report.refusals)}):")
        out += [f"    {_refusal(r)}" for r in report.refusals]
    out += [f"  note: {n}" for n in report.notes]
    if report.written:
        out.append(f"  wrote {report.out}" + (" (partly compensated)" if report.refusals
                                              else ""))
    elif report.refusals:
        out.append(f"  nothing written: {len(report.refusals)} construct(s) cannot be "
                   "compensated (--allow-partial writes the rest)")
    return out


def program_summary(report) -> dict:
    """The ``--json`` object (docs/programs.md)."""
    return {"source": report.source, "out": report.out if report.written else None,
            "language": report.language, "n_targets": report.n_targets,
            "n_compensated": len(report.rows), "targets": report.rows,
            "n_outside_range": sum(1 for r in report.rows if r.get("outside_range")),
            "refused": [{"line": r.line, "construct": r.construct, "reason": r.reason}
                        for r in report.refusals],
            "notes": report.notes, "written": report.written}
