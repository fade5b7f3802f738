"""What ``cellcal report`` prints about the page it wrote: one line per model shown, the
recommendation and the file (:func:`report_text`), or one JSON object
(:func:`report_summary`, docs/formats.md §4)."""

from __future__ import annotations

from pathlib import Path

from calibration.workflow import AutoStory

from .html_report import Report
from .provenance import Provenance


def report_summary(rep: Report, out: Path, size: int, prov: Provenance) -> dict:
    """The ``report --json`` object: the file (``out``, ``size`` bytes), its figures, the
    fits shown, the recommendation, the timings, the provenance, the blunders and, with an
    automatic diagnosis, its steps."""
    return {
        "out": str(out),
        "bytes": size,
        "figures": [f for f, _ in rep.figures],
        "stages": [{"label": s.label, "effects": s.fit.error_model.labels,
                    "calib": s.fit.calib, "valid": s.fit.valid} for s in rep.stages],
        "noise_floor_mm": rep.diagnosis.noise_floor_mm,
        "recommendation": rep.diagnosis.recommendation(),
        "next_effects": rep.diagnosis.next_effects(),
        "timings_s": rep.timings,
        "provenance": prov.to_json(),
        "outliers": _outliers(rep),
        **({"steps": _steps(rep.story)} if rep.story is not None else {}),
    }


def report_text(rep: Report, out: Path, size: int) -> str:
    """One line per fit shown (RMS on the calibration and validation rows), why an
    automatic diagnosis stopped, the recommendation and the file written."""
    lines = []
    for s in rep.stages:
        v = s.fit.valid
        lines.append(f"{s.label:<30} RMS {s.fit.calib['rms_mm']:.4f} mm calibration"
                     + (f", {v['rms_mm']:.4f} mm validation" if v else "")
                     + f"  ({','.join(s.fit.error_model.labels)})")
    if rep.story is not None:
        lines.append(f"automatic diagnosis: {rep.story.stop_reason}")
    lines.append(rep.diagnosis.recommendation())
    lines.append(f"wrote {out}: {len(rep.figures)} figures, {size / 1e6:.2f} MB "
                 f"in {rep.timings['total_s']:.1f} s")
    return "\n".join(lines)


def _steps(story: AutoStory) -> dict:
    return {"recorded": story.recorded, "heldout_method": story.heldout_method,
            "stop_reason": story.stop_reason,
            "steps": [{"effect": s.effect, "n_params": s.n_params,
                       "calib_rms_mm": s.calib_rms_mm, "heldout_rms_mm": s.heldout_rms_mm,
                       "range_blocked_rms_mm": s.blocked_rms_mm}
                      for s in story.steps]}


def _outliers(rep: Report) -> list[dict]:
    """The blunders any shown fit left out (docs/formats.md §4 ``outliers`` entries)."""
    seen, out = set(), []
    for sc in [s.fit.outliers for s in rep.stages] + [rep.diagnosis.outliers]:
        for o in (sc.to_json() if sc is not None else []):
            if o["pose_id"] not in seen:
                seen.add(o["pose_id"])
                out.append(o)
    return out
