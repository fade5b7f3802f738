"""The orientation lines ``cellcal calibrate`` prints when the data have orientations (a
6-DoF target): the error table of the orientations, fitted (full pose) or predicted (a
position-only fit), the residual about the flange's axes and the joints ranked by how
much of it their axes carry (:mod:`calibration.diagnosis.orientation_view`).

Returns text and prints nothing.
"""

from __future__ import annotations

import numpy as np

from calibration.diagnosis.orientation_view import orientation_view
from calibration.fit.identify import Fit

from .text_table import fmt, table

#: joints shown in the ranking
TOP_JOINTS = 3


def orientation_lines(fit: Fit) -> list[str]:
    """The orientation section (empty without orientations)."""
    view = orientation_view(fit)
    if view is None:
        return []
    how = ("fitted (full pose)" if view.fitted else
           "predicted by this position-only calibration (the target's mounting fitted)")
    rows = []
    for part in ("calib", "valid"):
        s = getattr(fit, part)
        if s and s.get("orientation_rms_deg") is not None:
            rows.append([f"calibrated, {part}", s["n"], fmt(s["orientation_rms_deg"], 4),
                         fmt(s["orientation_mean_deg"], 4), fmt(s["orientation_max_deg"], 4)])
    lines = ["", f"orientations {how}",
             table(rows, ["orientation error", "n", "rms deg", "mean deg", "max deg"])]
    if fit.data.sigma_deg is not None:
        floor = float(np.sqrt(3.0 * np.mean(np.square(fit.data.sigma_deg))))
        ref = fit.valid if fit.valid and "orientation_rms_deg" in fit.valid else fit.calib
        lines.append(f"orientation noise floor sqrt(3)*sigma = {floor:.4f} deg; RMS is "
                     f"{ref['orientation_rms_deg'] / floor:.2f} x the floor")
    x, y, z = view.axis_rms_deg
    lines.append(f"about the flange's axes (RMS, deg): x {fmt(x, 4)}, y {fmt(y, 4)}, z {fmt(z, 4)}")
    ranked = ", ".join(f"joint {r['joint']} {r['share'] * 100:.0f}%"
                       for r in view.ranked_joints()[:TOP_JOINTS])
    lines.append(f"along the joints' axes (share of the orientation residual): {ranked}")
    return lines
