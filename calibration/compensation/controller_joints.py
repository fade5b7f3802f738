"""The joints a controller ends at for a program's targets: as written, compensated, or with
only the geometric deltas of the calibration (a UR's ``calibration.conf``).

What a validation run moves to (``cellcal validate``): for every target of a program, the
joints of each *variant*

- ``uncompensated``: the nominal controller running the program as written (a joint target
  as written; a pose target by the nominal inverse kinematics near its seed);
- ``compensated``: the nominal controller running the compensated program
  (:func:`~calibration.compensation.pose_compensation.compensate_targets`: the joints at which the
  calibrated robot, every effect included, is at the target);
- ``geometric``: a controller that carries the calibrated DH table (the geometric deltas,
  what ``calibration.conf`` holds: :func:`~calibration.exports.model_export.calibrated_model`)
  and runs the program as written: a pose target by that table's inverse kinematics, with
  the same TCP the compensated variant uses; a joint target as written (a controller does
  not turn joint targets through its kinematics).

Lengths mm, angles rad, poses 4x4 in the robot base frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exports.model_export import calibrated_model
from ..fit.error_model import ErrorModel
from ..model.inverse import solve_ik
from .pose_compensation import NominalTcpFK, PoseCompensation, compensate_targets

#: the variants, in the order a validation runs them
VARIANTS = ("uncompensated", "compensated", "geometric")


@dataclass
class ControllerJoints:
    """Joints per variant for n targets, N joints.

    Attributes
    ----------
    compensation : the full compensation (:class:`PoseCompensation`: targets, predictions)
    joints : variant -> (n, N) rad
    success : variant -> (n,) bool (reached by that controller)
    """

    compensation: PoseCompensation
    joints: dict[str, np.ndarray]
    success: dict[str, np.ndarray]


def geometric_joints(error_model: ErrorModel, x: np.ndarray, c: PoseCompensation,
                     is_pose: np.ndarray, flange_T_tcp: np.ndarray, measured: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """((n, N) joints, (n,) success): a controller with the calibrated DH table (no base,
    no joint-stage effects) solving the pose targets near their nominal joints; joint
    targets as written. ``measured``: rows whose TCP is the calibration's measured point
    (the identified point is used, as for the compensated variant)."""
    q, ok = c.q_nominal.copy(), np.ones(len(is_pose), bool)
    if not is_pose.any():
        return q, ok
    model, _ = calibrated_model(error_model, x)
    tcp = flange_T_tcp[is_pose]
    points = np.where(measured[is_pose, None], model.tool_mm(), tcp[:, :3, 3])
    target = c.target[is_pose]
    R_flange = target[:, :3, :3] @ np.swapaxes(tcp[:, :3, :3], 1, 2)
    res = solve_ik(NominalTcpFK(model, points), c.q_nominal[is_pose], target[:, :3, 3],
                   R_flange if model.n_joints >= 6 else None, limits=model.limits_rad(),
                   max_iter=100, success_mm=1e-6, success_rad=1e-7)
    q[is_pose], ok[is_pose] = res.q, res.success
    return q, ok


def controller_joints(error_model: ErrorModel, x: np.ndarray, joints: np.ndarray, *,
                      pose: np.ndarray | None = None, is_pose: np.ndarray | None = None,
                      flange_T_tcp: np.ndarray | None = None,
                      measured: np.ndarray | bool = False,
                      columns: dict | None = None, geometric: bool = True
                      ) -> ControllerJoints:
    """The joints of every variant (see the module docstring) for a program's targets.

    Parameters are those of :func:`~calibration.compensation.pose_compensation.compensate_targets`
    (``measured`` is its ``calibrated_tool``); ``flange_T_tcp`` (4, 4) or (n, 4, 4);
    ``geometric``: also the geometric-only variant (else left out of the result).
    """
    joints = np.atleast_2d(np.asarray(joints, float))
    n = len(joints)
    is_pose = np.zeros(n, bool) if is_pose is None else np.asarray(is_pose, bool)
    measured = np.broadcast_to(np.asarray(measured, bool), (n,))
    tcp = np.broadcast_to(np.eye(4) if flange_T_tcp is None else np.asarray(flange_T_tcp,
                                                                           float), (n, 4, 4))
    c = compensate_targets(error_model, x, joints, pose=pose, is_pose=is_pose,
                           flange_T_tcp=tcp, columns=columns, calibrated_tool=measured)
    # a pose target the compensation did not reach may have no nominal joints either
    found = c.success | ~is_pose
    out = ControllerJoints(c, {"uncompensated": c.q_nominal, "compensated": c.q},
                           {"uncompensated": found, "compensated": c.success})
    if geometric:
        q_geo, ok_geo = geometric_joints(error_model, x, c, is_pose, tcp, measured)
        out.joints["geometric"], out.success["geometric"] = q_geo, ok_geo & found
    return out
