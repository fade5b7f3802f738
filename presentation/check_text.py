"""What ``cellcal check`` prints: a calibration's error on new poses, exactly as
calibrated (:func:`check_text`), and its ``--json`` object (:func:`check_summary`,
docs/formats.md §4).

Every function returns text or a JSON-ready mapping and prints nothing.
"""

from __future__ import annotations

from calibration.fit.model_check import FrameVerdict, ModelCheck

from .text_table import fmt, table

#: the poses named in the text and in ``worst`` of the JSON
WORST = 5
#: with a tolerance, at most this many of the poses beyond it are named
BEYOND = 10


def _refit_words(result: ModelCheck) -> str:
    if not result.refitted:
        return "nothing refitted"
    return f"{', '.join(result.refitted)} refitted (the tracker-to-base transform only)"


def _poses(rows) -> str:
    return ", ".join(f"{p} (line {line}) {e:.3f} mm" for p, line, e in rows)


def check_text(result: ModelCheck, frame: FrameVerdict, refit_reason: str | None, *,
               params: str, calibration_stats: dict, tolerance_mm: float | None,
               within: bool | None, recorded: dict | None = None,
               db: str | None = None) -> str:
    """The check in tables: what was checked, the frame, the calibration's own figures,
    the error on the new poses, the worst poses and the verdict."""
    em = result.error_model
    d = result.data
    tool = ", ".join(f"{v:g}" for v in em.model.tool)
    lines = [
        f"check     {params} on {d.source}: {d.n} poses, {_refit_words(result)}",
        f"model     {em.model.name} ({em.model.convention}), tool {tool} mm ({params}), "
        f"effects {','.join(em.labels)}",
        f"frame     {frame.reason}",
    ]
    if refit_reason is not None:
        lines.append(f"refitted  base: {refit_reason}; it moved {result.base_shift_mm:.3f} mm "
                     f"and turned {result.base_turn_deg:.4f} deg from the calibration's")
    own = []
    for part, what in (("calib", "calibration"), ("valid", "validation")):
        s = calibration_stats.get(part)
        if s and s.get("rms_mm") is not None:
            own.append(f"{s['rms_mm']:.4f} mm on its {s.get('n', '?')} {what} poses")
    if own:
        lines.append("calibrated RMS " + ", ".join(own) + " (its own figures)")
    s = result.stats
    label = "the given model" + (", base refitted" if result.refitted else "") + ", new poses"
    lines += ["", table([[label, s["n"], fmt(s["rms_mm"]), fmt(s["mean_mm"]), fmt(s["p95_mm"]),
                          fmt(s["max_mm"])]],
                        ["position error", "n", "rms mm", "mean mm", "p95 mm", "max mm"])]
    floor = d.noise_floor_mm()
    if floor:
        lines.append(f"noise floor sqrt(3)*sigma = {floor:.4f} mm; RMS is "
                     f"{s['rms_mm'] / floor:.2f} x the floor")
    if s.get("orientation_rms_deg") is not None:
        lines.append(f"orientation error: RMS {s['orientation_rms_deg']:.4f} deg, mean "
                     f"{s['orientation_mean_deg']:.4f} deg, max "
                     f"{s['orientation_max_deg']:.4f} deg")
    lines.append(f"worst     {_poses(result.worst(WORST))}")
    if tolerance_mm is not None:
        k = result.n_beyond(tolerance_mm)
        if within:
            verdict = (f"within: RMS {s['rms_mm']:.4f} mm <= {tolerance_mm:g} mm"
                       + (f"; {k} of {d.n} poses miss by more" if k else ""))
        else:
            verdict = (f"BEYOND: RMS {s['rms_mm']:.4f} mm > {tolerance_mm:g} mm; {k} of {d.n} "
                       f"poses miss by more, the worst: "
                       f"{_poses(result.worst(BEYOND, tolerance_mm))}")
        lines.append(f"tolerance {verdict}")
    if recorded is not None:
        lines += ["", recorded_check_line(recorded, db)]
    return "\n".join(lines)


def recorded_check_line(recorded: dict, db: str | None) -> str:
    """Where ``check --db`` recorded the check."""
    cal = recorded.get("calibration")
    of = (f"of calibration {cal}" if cal is not None else
          "(the parameters checked are no calibration recorded for this robot)")
    return (f"{'recorded' if recorded['new'] else 'already recorded'} as check "
            f"{recorded['id']} of robot {recorded['robot_id']} {of} in "
            f"{recorded.get('db') or db}")


def check_summary(result: ModelCheck, frame: FrameVerdict, refit_reason: str | None, *,
                  params: str, calibration_stats: dict, tolerance_mm: float | None,
                  within: bool | None, notes: list[str] | None = None) -> dict:
    """The ``check --json`` object (docs/formats.md §4): the statistics (``n``, ``rms_mm``,
    ``mean_mm``, ``p95_mm``, ``max_mm``, the orientation's for a full-pose model),
    ``refitted``, ``within_tolerance`` and the rest of what the text says, with every
    pose's error (``poses``)."""
    em = result.error_model
    d = result.data
    out = {
        "model": em.model.name, "effects": list(em.labels), "params_file": params,
        "data": d.source, **result.stats,
        "noise_floor_mm": d.noise_floor_mm(),
        "refitted": list(result.refitted), "refit_reason": refit_reason,
        "base_shift_mm": result.base_shift_mm, "base_turn_deg": result.base_turn_deg,
        "frame": {"same": frame.same, "reason": frame.reason,
                  "distance_mm": frame.distance_mm, "angle_deg": frame.angle_deg},
        "calibration": {f"{part}_rms_mm": (calibration_stats.get(part) or {}).get("rms_mm")
                        for part in ("calib", "valid")},
        "tolerance_mm": tolerance_mm, "within_tolerance": within,
        "n_beyond_tolerance": None if tolerance_mm is None else result.n_beyond(tolerance_mm),
        "worst": [{"pose_id": p, "line": line, "error_mm": e}
                  for p, line, e in (result.worst(BEYOND, tolerance_mm) if within is False
                                     else result.worst(WORST))],
        "notes": list(notes if notes is not None else result.notes),
        "poses": [{"pose_id": str(p), "line": int(line), "error_mm": float(e),
                   "dx_mm": float(r[0]), "dy_mm": float(r[1]), "dz_mm": float(r[2])}
                  for p, line, e, r in zip(d.pose_id, d.lines, result.errors, result.residuals,
                                           strict=True)],
    }
    return out
