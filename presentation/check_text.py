"""What ``cellcal check`` prints: a calibration's error on new poses, exactly as
calibrated (:func:`check_text`), and its ``--json`` object (:func:`check_summary`,
docs/formats.md §4). When the params.json records the calibrated envelope, both split
the figures inside and outside it (as ``calibrate`` splits its validation poses) and name
each pose's quantities beyond it (``outside_range``, as ``compensate`` names a target's).

Every function returns text or a JSON-ready mapping and prints nothing.
"""

from __future__ import annotations

from calibration.fit.model_check import FrameVerdict, ModelCheck

from .calibration_text import beyond_line, split_rows
from .text_table import fmt, table

#: the poses named in the text and in ``worst`` of the JSON
WORST = 5
#: with a tolerance, at most this many of the poses beyond it are named
BEYOND = 10


def _refit_words(result: ModelCheck) -> str:
    if not result.refitted:
        return "nothing refitted"
    return f"{', '.join(result.refitted)} refitted (the tracker-to-base transform only)"


def _poses(result: ModelCheck, rows) -> str:
    """The poses of rows ``rows`` (largest error first): pose id, file line, error and,
    beyond the envelope, what lies beyond it (``(outside q2;t_s)``)."""
    out = []
    for i in rows:
        names = result.outside_of(int(i))
        out.append(f"{result.data.pose_id[i]} (line {int(result.data.lines[i])}) "
                   f"{float(result.errors[i]):.3f} mm"
                   + (f" (outside {';'.join(names)})" if names else ""))
    return ", ".join(out)


def envelope_line(result: ModelCheck) -> str | None:
    """How many poses lie beyond the calibrated envelope and in which quantities (None
    without an envelope)."""
    if result.split is None:
        return None
    n = result.data.n
    return (beyond_line(result.split["outside"], n, "poses")
            or f"envelope  all {n} poses lie inside the calibrated envelope")


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
    rows = [[label, s["n"], fmt(s["rms_mm"]), fmt(s["mean_mm"]), fmt(s["p95_mm"]),
             fmt(s["max_mm"])]]
    if result.split is not None:
        rows += split_rows(result.split)
    lines += ["", table(rows, ["position error", "n", "rms mm", "mean mm", "p95 mm", "max mm"])]
    beyond = envelope_line(result)
    if beyond is not None:
        lines.append(beyond)
    floor = d.noise_floor_mm()
    if floor:
        lines.append(f"noise floor sqrt(3)*sigma = {floor:.4f} mm; RMS is "
                     f"{s['rms_mm'] / floor:.2f} x the floor")
    if s.get("orientation_rms_deg") is not None:
        lines.append(f"orientation error: RMS {s['orientation_rms_deg']:.4f} deg, mean "
                     f"{s['orientation_mean_deg']:.4f} deg, max "
                     f"{s['orientation_max_deg']:.4f} deg")
    lines.append(f"worst     {_poses(result, result.worst_index(WORST))}")
    if tolerance_mm is not None:
        k = result.n_beyond(tolerance_mm)
        if within:
            verdict = (f"within: RMS {s['rms_mm']:.4f} mm <= {tolerance_mm:g} mm"
                       + (f"; {k} of {d.n} poses miss by more" if k else ""))
        else:
            verdict = (f"BEYOND: RMS {s['rms_mm']:.4f} mm > {tolerance_mm:g} mm; {k} of {d.n} "
                       f"poses miss by more, the worst: "
                       f"{_poses(result, result.worst_index(BEYOND, tolerance_mm))}")
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
    pose's error (``poses``); the calibrated envelope (``envelope``, as params.json records
    it, null without one), the statistics inside and outside it (``inside``, ``outside``
    with ``by_quantity``: those of ``calibrate --json``'s ``valid_inside`` and
    ``valid_outside``), ``n_outside_range`` and every pose's (and worst pose's)
    ``outside_range``."""
    em = result.error_model
    d = result.data
    worst = (result.worst_index(BEYOND, tolerance_mm) if within is False
             else result.worst_index(WORST))
    split = result.split or {}
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
        "envelope": None if result.envelope is None else result.envelope.to_json(),
        "inside": split.get("inside"), "outside": split.get("outside"),
        "n_outside_range": result.n_outside,
        "worst": [{"pose_id": str(d.pose_id[i]), "line": int(d.lines[i]),
                   "error_mm": float(result.errors[i]),
                   "outside_range": result.outside_of(int(i))} for i in worst],
        "notes": list(notes if notes is not None else result.notes),
        "poses": [{"pose_id": str(p), "line": int(line), "error_mm": float(e),
                   "dx_mm": float(r[0]), "dy_mm": float(r[1]), "dz_mm": float(r[2]),
                   "outside_range": result.outside_of(i)}
                  for i, (p, line, e, r) in enumerate(zip(d.pose_id, d.lines, result.errors,
                                                          result.residuals, strict=True))],
    }
    return out
