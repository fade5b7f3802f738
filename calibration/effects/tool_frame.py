"""The orientation of a 6-DoF target in the flange frame: ``tool_rotation``.

With the ``tool`` effect (the target's centre in the flange frame) it makes the tool a
full frame, ``flange_T_target``. A 6-DoF target (a T-Mac) measures
``tracker_R_target = tracker_R_base · base_R_flange · flange_R_target``; the effect's
parameters are the rotation vector of ``flange_R_target`` (absolute, rad), at the
``target`` stage of :class:`~calibration.fit.error_model.ErrorModel`. Data without
orientations do not see it: its parameters are then unidentifiable and fixed.
"""

from __future__ import annotations

import numpy as np

from ..data.dataset import Dataset
from ..model.robot_model import RobotModel
from ..model.transforms import (
    fit_rotation,
    matrix_to_rotvec,
    quat_to_matrix,
    right_jacobian,
    rotvec_to_matrix,
)
from .base import Effect


def mean_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation closest (chordal L2) to a stack of rotations (n, 3, 3): the projection
    of their mean onto SO(3)."""
    return fit_rotation(np.eye(3), R.mean(axis=0).T)


class ToolRotation(Effect):
    """Orientation of the 6-DoF target in the flange frame, rotation vector rx, ry, rz
    (rad): absolute, started from the measured orientations (see :meth:`start_from`)."""

    family = "tool_rotation"
    stage = "target"
    summary = "orientation of a 6-DoF target in the flange frame (needs orientation data)"

    def __init__(self, model: RobotModel, joint: int | None = None,
                 order: int | None = None) -> None:
        super().__init__(model, joint, order)
        self.param_names = ["rx", "ry", "rz"]
        self.units = ["rad"] * 3
        self.scales = np.full(3, 1e-3)

    def target_rotation(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``flange_R_target`` (3, 3), and the right Jacobian of its rotation vector (3, 3):
        ``R(p + dp) = R(p) exp([J dp]x)``."""
        return rotvec_to_matrix(p), right_jacobian(p)

    def start_from(self, data: Dataset, tracker_R_flange: np.ndarray) -> np.ndarray:
        """Start values from measured orientations and the flange's predicted ones
        (n, 3, 3): the mean of ``flange_R_target`` over the poses (zeros without data)."""
        if data.quat is None or not data.n:
            return np.zeros(3)
        R = np.swapaxes(tracker_R_flange, 1, 2) @ quat_to_matrix(data.quat)
        return matrix_to_rotvec(mean_rotation(R))


TOOL_FRAME: dict[str, type[Effect]] = {"tool_rotation": ToolRotation}
