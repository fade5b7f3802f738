"""What ``cellcal validate`` prints after its run: each variant's waypoint error against
the calibration's validation RMS (:func:`validation_lines`), and the ``--json`` keys it
adds to the run's outcome (:func:`validation_summary`).

The figures are the run summary's ``validation`` (per variant: ``n``, ``rms_mm``,
``mean_mm``, ``max_mm``, ``ap_max_mm``, ``rp_max_mm``; :mod:`daq.routines.validate`).
Nothing is printed here.
"""

from __future__ import annotations

from .text_table import fmt, table

#: what each variant is, in the table
VARIANT_NAMES = {"uncompensated": "as written", "compensated": "compensated",
                 "geometric": "calibration.conf only"}
#: the geometric variant's name where the controller is not a UR's (an ABB's has no
#: calibration.conf: the variant is a controller with the calibrated geometry alone)
GEOMETRY_ONLY = "geometry only"


def validation_lines(summary: dict, valid_rms_mm: float | None, notes: list[str],
                     robot: str | None = None) -> list[str]:
    """The table of variants (error RMS, mean, max, ISO 9283 AP and RP at worst, and the
    RMS as a multiple of the calibration's validation RMS), then the notes. ``robot``: the
    robot's URL (an ``abb://`` robot's geometric variant is called "geometry only")."""
    names = dict(VARIANT_NAMES)
    if robot is not None and robot.lower().startswith("abb:"):
        names["geometric"] = GEOMETRY_ONLY
    figures = summary.get("validation") or {}
    if not figures:
        return [f"note: {n}" for n in notes]
    rows = []
    for v, f in figures.items():
        ratio = (f"{f['rms_mm'] / valid_rms_mm:.2f}" if valid_rms_mm else "-")
        rows.append([names.get(v, v), str(f["n"]), fmt(f["rms_mm"]),
                     fmt(f["mean_mm"]), fmt(f["max_mm"]), fmt(f.get("ap_max_mm")),
                     fmt(f.get("rp_max_mm")), ratio])
    out = ["", f"waypoint error, in {summary.get('validation_frame', 'the run frame')}:",
           table(rows, ["program", "n", "rms mm", "mean mm", "max mm", "AP mm", "RP mm",
                        "/valid"])]
    out.append("AP, RP: ISO 9283 accuracy and repeatability, the worst waypoint"
               + (f"; /valid: the RMS over the calibration's validation RMS "
                  f"{valid_rms_mm:.4f} mm" if valid_rms_mm else ""))
    out += [f"note: {n}" for n in notes]
    return out


def validation_summary(summary: dict, valid_rms_mm: float | None, n_waypoints: int,
                       notes: list[str]) -> dict:
    """The keys ``--json`` adds to the run's outcome."""
    return {"validation": summary.get("validation") or {},
            "validation_frame": summary.get("validation_frame"),
            "calibration_valid_rms_mm": valid_rms_mm, "waypoints": n_waypoints,
            "notes": notes}
