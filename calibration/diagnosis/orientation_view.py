"""Where a fit's orientations fail: per axis of the flange and per joint.

The orientation counterpart of :func:`calibration.workflow.joint_view`. An orientation
residual (the turn from predicted to measured, tracker frame) is shown

- per axis of the flange frame: tilts about x and y and a spin about the tool axis z
  have different causes (a wrist axis's alignment, a joint's zero);
- per joint: the correction of joint j alone that explains it best is its component
  along joint j's axis; a joint whose axis carries much of the residual over the poses
  (``share``, the fraction of the residual's sum of squares) is where to look first.

Joints are ranked by that share, largest first, as diagnose ranks the positions' causes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fit.identify import Fit
from ..model.kinematics import run_chain


@dataclass
class OrientationView:
    """A fit's orientation residuals on its calibration rows, by axis and by joint.

    Attributes
    ----------
    fitted : whether the fit used the orientations (full pose) or predicts them
    flange_deg : (n, 3) residuals in the flange frame, deg
    joint_deg : (n, N) each joint's best explaining correction, deg (0 for a prismatic
        joint, which turns nothing)
    share : (N,) fraction of the residual's sum of squares along each joint's axis
    """

    fitted: bool
    flange_deg: np.ndarray
    joint_deg: np.ndarray
    share: np.ndarray

    @property
    def axis_rms_deg(self) -> np.ndarray:
        """(3,) RMS about the flange's x, y and z axes, deg."""
        return np.sqrt(np.mean(self.flange_deg**2, axis=0))

    def ranked_joints(self) -> list[dict]:
        """One row per joint, largest share first: joint (1-based), share, RMS deg."""
        rms = np.sqrt(np.mean(self.joint_deg**2, axis=0))
        order = np.argsort(-self.share, kind="stable")
        return [{"joint": int(j + 1), "share": float(self.share[j]),
                 "rms_deg": float(rms[j])} for j in order]

    def to_json(self) -> dict:
        return {"fitted": self.fitted,
                "axis_rms_deg": dict(zip("xyz", map(float, self.axis_rms_deg), strict=True)),
                "joints": self.ranked_joints()}


def orientation_view(fit: Fit) -> OrientationView | None:
    """``fit``'s orientation residuals seen per flange axis and per joint; None when its
    data have no orientations."""
    r = fit.orientation_residuals
    if r is None:
        return None
    em = fit.error_model
    c = em.perturb(fit.values, em.bind(fit.data))
    assert c.q is not None  # perturbed with bound data: the joints as they really are
    chain = run_chain(em.model.convention, c.table, c.q, c.tool, c.length_scale,
                      jacobian=False, prismatic=em.model.prismatic_mask())
    R_base = np.eye(3) if c.tracker_T_base is None else c.tracker_T_base[0]
    tracker_R_flange = R_base @ chain.base_R_flange
    flange = np.einsum("nji,nj->ni", tracker_R_flange, r)
    axes = R_base @ chain.dR_dq  # (n, 3, N) unit axes in the tracker frame (0: prismatic)
    along = np.einsum("nij,ni->nj", axes, r)
    total = float(np.sum(r**2))
    share = np.sum(along**2, axis=0) / total if total > 0 else np.zeros(along.shape[1])
    return OrientationView(bool(fit.orientation_fitted), np.degrees(flange),
                           np.degrees(along), share)
