"""The poses as a fit sees them, ready to plot: each pose's residual, its joint-equivalent
(:func:`calibration.workflow.joint_view`) and that view's lever arm, the gravity torques,
the pose's place in the capture, and the same for the blunders left out of the fit.

Nothing here is new numerics: the core evaluates the model; this module only gathers
its answers per pose for the figures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.data.dataset import Dataset
from calibration.effects.physical import derive_directions
from calibration.fit.identify import Fit
from calibration.model.gravity import gravity_torques, has_mass_model
from calibration.workflow import joint_view

#: the joint-equivalent residual of a pose is shown only where the joint moves the target
#: at least this far per radian (mm/rad = mm of lever arm); nearer the joint's axis a
#: residual of a few µm reads as thousands of µrad and means nothing
LEVER_ARM_MIN_MM = 50.0


@dataclass
class Points:
    """Rows of a data set as one fit sees them.

    Attributes
    ----------
    pose_id : (n,) ids; line : (n,) file lines
    q : (n, N) joint angles, rad; xyz : (n, 3) measured target, tracker frame, mm
    residuals : (n, 3) measured minus predicted, mm; error_mm : (n,) their length
    joint_rad : (n, N) joint-equivalent residual, rad
    lever_mm : (n, N) lever arm of that view, mm
    torque_nm : (n, N) gravity torques, None without a mass model
    position : (n,) place among the data's calibration rows in capture order (0-based)
    t_s, temp_c : (n,) or None
    joint_temp : (n, N) each joint's temperature (°C), or None
    dirs : (n, N) approach direction of every joint (-1, 0, +1): the data's, else derived
        from consecutive rows
    """

    pose_id: list[str]
    line: np.ndarray
    q: np.ndarray
    xyz: np.ndarray
    residuals: np.ndarray
    joint_rad: np.ndarray
    lever_mm: np.ndarray
    torque_nm: np.ndarray | None
    position: np.ndarray
    t_s: np.ndarray | None
    temp_c: np.ndarray | None
    dirs: np.ndarray | None = None
    joint_temp: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.pose_id)

    @property
    def error_mm(self) -> np.ndarray:
        return np.linalg.norm(self.residuals, axis=1)

    def shown(self, j: int) -> np.ndarray:
        """(n,) bool: the poses whose joint-``j`` (0-based) equivalent means something
        (lever arm at least :data:`LEVER_ARM_MIN_MM`)."""
        return self.lever_mm[:, j] >= LEVER_ARM_MIN_MM


def points_of(fit: Fit, rows: Dataset, order: Dataset | None = None) -> Points:
    """``rows`` as ``fit`` sees them; ``order`` (default ``rows``) gives the capture
    positions: a row's index among ``order``'s calibration rows."""
    view = joint_view(fit, rows)
    torque = None
    if has_mass_model(fit.error_model.model):
        nominal = fit.error_model.bind(rows).nominal
        torque = gravity_torques(fit.error_model.model, nominal, rows.payload_kg)
    ref = order if order is not None else rows
    ref_ids = ref.calib().pose_id if ref.is_valid.any() else ref.pose_id
    where = {p: i for i, p in enumerate(ref_ids)}
    position = np.array([where.get(p, i) for i, p in enumerate(rows.pose_id)], float)
    dirs = rows.dirs if rows.dirs is not None else derive_directions(rows.q)
    return Points(list(rows.pose_id), np.asarray(rows.lines), rows.q, rows.tracker_p_smr,
                  view.residuals, view.joint_residual_rad, view.lever_arm_mm, torque,
                  position, rows.t_s, rows.temp_c, np.asarray(dirs), rows.joint_temp)


def blunder_rows(data: Dataset | None, ids: list[str]) -> Dataset | None:
    """The calibration rows of ``data`` with these pose ids (in capture order), or None."""
    if data is None or not ids:
        return None
    calib = data.calib() if data.is_valid.any() else data
    keep = np.isin(np.asarray(calib.pose_id, dtype=object), np.asarray(ids, dtype=object))
    return calib.subset(keep) if keep.any() else None
