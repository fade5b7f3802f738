"""What ``cellcal compensate`` writes and prints: the compensated targets as CSV
(:func:`compensated_csv`), the summary of a compensation (:func:`compensation_text`), the
lines about the files exported (:func:`export_lines`) and the ``--json`` object
(:func:`compensation_summary`, docs/formats.md §4).

Every function returns text or a JSON-ready mapping and prints nothing. An export is any
object with ``key`` (its JSON key), ``path`` and ``parity``
(:class:`calibration.exports.parity.Parity`).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from calibration.compensation.compensation import Compensation, Targets
from calibration.data.capture_meta import CaptureMeta
from calibration.model.robot_model import RobotModel
from calibration.model.transforms import matrix_to_rotvec_each

from .text_table import fmt

#: the JSON keys of the exported files, in the object's order
_FILE_KEYS = ("model_file", "ur_conf_file", "urdf_file", "ur_yaml_file", "table_file")


def compensated_csv(t: Targets, c: Compensation, outside: list[list[str]] | None = None
                    ) -> str:
    """The compensated targets: each target, the joints that reach it (deg), the
    corrected Cartesian command (mm, rotation vector in deg), the nominal joints, the
    correction and residual (mm), whether it was reached and ``outside_range``: the
    quantities beyond the calibrated envelope (``q2;q5``, empty inside; ``outside``)."""
    N = c.q.shape[1]
    outside = outside if outside is not None else [[] for _ in range(len(c.q))]
    head = (["pose_id", "x", "y", "z"] + [f"q{j + 1}" for j in range(N)]
            + ["cmd_x", "cmd_y", "cmd_z", "cmd_rx", "cmd_ry", "cmd_rz"]
            + [f"nom_q{j + 1}" for j in range(N)] + ["correction_mm", "residual_mm", "ok",
                                                     "outside_range"])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    qd, nd = np.degrees(c.q), np.degrees(c.q_nominal)
    rv = np.degrees(matrix_to_rotvec_each(c.cmd_R))
    numbers = np.column_stack([c.target, qd, c.cmd_point, rv, nd, c.correction_mm,
                               c.residual_mm]).astype(float).tolist()
    w.writerows([pid, *map(repr, row), ok, ";".join(out)] for pid, row, ok, out in
                zip(t.pose_id, numbers, np.asarray(c.success).astype(int).tolist(),
                    outside, strict=True))
    return buf.getvalue()


def outside_counts(outside: list[list[str]]) -> dict[str, int]:
    """How many targets lie beyond the envelope in each quantity (``q2``: 3, ...)."""
    counts: dict[str, int] = {}
    for names in outside:
        for n in names:
            counts[n] = counts.get(n, 0) + 1
    return counts


def outside_warning(outside: list[list[str]] | None, what: str = "targets",
                    where: str = "the outside_range column") -> str | None:
    """The stderr warning when targets lie beyond the calibrated envelope (None inside):
    how many, in which quantities, where they are named."""
    if not outside:
        return None
    n = sum(1 for names in outside if names)
    if not n:
        return None
    by = ", ".join(f"{k}: {v}" for k, v in outside_counts(outside).items())
    return (f"warning: {n} of {len(outside)} {what} lie beyond the calibrated envelope "
            f"({by}): the calibration did not measure there and holds its edge value; "
            f"see {where} (--strict-range refuses them)")


def outside_json(labels: list[str], outside: list[list[str]], key: str = "pose_id"
                 ) -> list[dict]:
    """``outside_range`` of a ``--json`` object: one entry per target beyond the envelope,
    ``{key: label, "outside_range": ["q2", ...]}``."""
    return [{key: lab, "outside_range": names}
            for lab, names in zip(labels, outside, strict=True) if names]


def compensation_text(model: RobotModel, capture: CaptureMeta, targets_file: str,
                      t: Targets, c: Compensation, notes: list[str],
                      outside: list[list[str]] | None = None) -> str:
    """The model and its tool, the targets reached, the solver, the correction of the
    Cartesian targets, the targets beyond the calibrated envelope (``outside``) and the
    notes."""
    where = (f" (capture run {capture.run}"
             + (f" of {capture.store})" if capture.store else ")")
             if capture.run is not None else "")
    lines = [f"model     {model.name}, tool {', '.join(f'{v:g}' for v in model.tool)} "
             f"mm{where}",
             f"targets   {targets_file}: {len(t.base_p_tcp)}, reached "
             f"{int(c.success.sum())}, orientation held {int(c.orientation_kept.sum())}",
             f"solver    {c.reason}; {c.iterations} iterations",
             f"correction of the Cartesian targets: mean {fmt(c.correction_mm.mean())} mm, "
             f"max {fmt(c.correction_mm.max())} mm"]
    bad = [(p, names) for p, names in zip(t.pose_id, outside or [], strict=False) if names]
    if outside is not None and not bad:
        lines.append("envelope  every target inside the calibrated envelope")
    elif bad:
        lines.append(f"envelope  {len(bad)} of {len(outside)} targets beyond the calibrated "
                     "envelope: " + "; ".join(f"{p} ({', '.join(n)})" for p, n in bad[:10])
                     + (f"; and {len(bad) - 10} more" if len(bad) > 10 else ""))
    lines += [f"note      {note}" for note in notes]
    return "\n".join(lines)


def export_lines(exports, not_exported: list[str]) -> list[str]:
    """Per file exported, where and its parity check; then what no file holds."""
    lines = []
    for e in exports:
        lines += [f"written   {e.path}", e.parity.line()]
    return lines + [f"not exported: {n}" for n in not_exported]


def compensation_summary(*, params_file: str, model: RobotModel, capture: CaptureMeta,
                         notes: list[str], exports=None, not_exported=None,
                         t: Targets | None = None, c: Compensation | None = None,
                         out_file: str | None = None,
                         outside: list[list[str]] | None = None) -> dict:
    """The ``compensate --json`` object: the calibration, the notes, the files exported
    with their parity (``exports`` None: none), the compensation of the targets (``t``,
    ``c``; ``out_file`` the CSV written; ``outside``: per target the quantities beyond the
    calibrated envelope, as ``n_outside_range`` and ``outside_range``)."""
    doc = {"params_file": params_file, "model": model.name, "tool_mm": list(model.tool),
           "capture": capture.to_json() if capture.known else None, "notes": notes}
    if exports is not None:
        by_key = {e.key: str(Path(e.path)) for e in exports}
        doc.update({k: by_key[k] for k in _FILE_KEYS if k in by_key})
        doc["parity"] = [e.parity.as_dict() for e in exports]
        doc["not_exported"] = not_exported
    if t is not None:
        doc.update({
            "n_targets": len(t.base_p_tcp),
            "n_reached": int(c.success.sum()),
            "n_orientation_kept": int(c.orientation_kept.sum()),
            "nominal_joints": "given" if t.q is not None else "computed",
            "correction_mm": {"mean": float(c.correction_mm.mean()),
                              "max": float(c.correction_mm.max())},
            "residual_mm_max": float(c.residual_mm.max()),
            "iterations": c.iterations,
            "reason": c.reason,
            "out_file": out_file,
        })
        outside = outside if outside is not None else [[] for _ in t.pose_id]
        doc["n_outside_range"] = sum(1 for names in outside if names)
        doc["outside_range"] = outside_json(list(t.pose_id), outside)
    return doc
