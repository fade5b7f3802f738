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


def compensated_csv(t: Targets, c: Compensation) -> str:
    """The compensated targets: each target, the joints that reach it (deg), the
    corrected Cartesian command (mm, rotation vector in deg), the nominal joints, the
    correction and residual (mm) and whether it was reached."""
    N = c.q.shape[1]
    head = (["pose_id", "x", "y", "z"] + [f"q{j + 1}" for j in range(N)]
            + ["cmd_x", "cmd_y", "cmd_z", "cmd_rx", "cmd_ry", "cmd_rz"]
            + [f"nom_q{j + 1}" for j in range(N)] + ["correction_mm", "residual_mm", "ok"])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    qd, nd = np.degrees(c.q), np.degrees(c.q_nominal)
    rv = np.degrees(matrix_to_rotvec_each(c.cmd_R))
    numbers = np.column_stack([c.target, qd, c.cmd_point, rv, nd, c.correction_mm,
                               c.residual_mm]).astype(float).tolist()
    w.writerows([pid, *map(repr, row), ok] for pid, row, ok in
                zip(t.pose_id, numbers, np.asarray(c.success).astype(int).tolist(),
                    strict=True))
    return buf.getvalue()


def compensation_text(model: RobotModel, capture: CaptureMeta, targets_file: str,
                      t: Targets, c: Compensation, notes: list[str]) -> str:
    """The model and its tool, the targets reached, the solver, the correction of the
    Cartesian targets and the notes."""
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
                         out_file: str | None = None) -> dict:
    """The ``compensate --json`` object: the calibration, the notes, the files exported
    with their parity (``exports`` None: none), the compensation of the targets (``t``,
    ``c``; ``out_file`` the CSV written)."""
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
    return doc
