"""Compensation of a program's targets: full TCP poses and joint targets, batched.

A robot program says where the tool should be as the *nominal* model sees it: a pose of
its TCP (position and orientation of the program's active TCP), or joints (meaning: where
the nominal model puts that TCP at those joints). The real robot, as the calibration
describes it, misses both. For every target this module finds the joints ``q`` at which
the **calibrated** robot's TCP is at the intended pose (six equations for a six-axis arm,
damped Newton from the nominal joints, every target at once), and the pose the nominal
controller must be given so that its own inverse kinematics lands on ``q``: the nominal
forward kinematics at ``q``.

- a joint target ``q0``: the intended pose is the nominal TCP pose at ``q0``; the program
  gets ``q``;
- a pose target ``T``: the nominal joints (the controller's IK of ``T``) are found from a
  seed, which picks the configuration as a controller's nearest solution does (the
  program's neighbouring joint target, :func:`neighbour_seeds`, or a given one); the
  program gets the nominal pose at ``q``.

The TCP is a full frame, ``flange_T_tcp``, per target (a program may change it); it
replaces the calibration's tool stage (the SMR the robot was measured with). Per-target
columns (``temp_c``, ``payload_kg``, ``dirs``) reach the effects that use them; without
``dirs``, approach directions follow the targets in the order given (program order), so a
model with backlash sees the motion the program makes. Lengths mm, angles rad, poses 4x4.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..effects.physical import derive_directions
from ..fit.error_model import ErrorModel
from ..model.inverse import IKResult, rotation_error, solve_ik, solve_ik_multistart
from ..model.kinematics import ChainResult, run_chain
from ..model.robot_model import RobotModel
from .compensation import CalibratedFK


class NominalTcpFK:
    """Nominal forward kinematics with a tool point per target, for :func:`solve_ik`.

    Parameters
    ----------
    model : the nominal RobotModel
    tool : (3,) or (n, 3) TCP point in the flange frame, mm
    """

    takes_rows = True

    def __init__(self, model: RobotModel, tool: np.ndarray) -> None:
        self.model = model
        self.table = model.dh_table()
        self.tool = np.asarray(tool, float)
        self.prismatic = model.prismatic_mask()

    def chain(self, q: np.ndarray, rows: np.ndarray | None = None) -> ChainResult:
        tool = self.tool if self.tool.ndim == 1 or rows is None else self.tool[rows]
        return run_chain(self.model.convention, self.table, np.atleast_2d(q), tool,
                         jacobian=False, prismatic=self.prismatic)

    def __call__(self, q: np.ndarray, rows: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r = self.chain(q, rows)
        return r.base_p_tcp, r.base_R_flange, r.dP_dq, r.dR_dq


@dataclass
class PoseCompensation:
    """Result of :func:`compensate_targets`, n targets, N joints.

    Attributes
    ----------
    target : (n, 4, 4) the intended TCP pose (base frame, mm)
    q_nominal : (n, N) joints the nominal controller uses for it (a joint target's own)
    q : (n, N) compensated joints: the calibrated TCP is at ``target`` there
    cmd : (n, 4, 4) the pose to give the nominal controller: its TCP pose at ``q``
    correction_mm, correction_deg : (n,) how far ``cmd`` is from ``target``
    predicted_mm, predicted_deg : (n,) the calibration's prediction of the uncompensated
        miss: the calibrated TCP at ``q_nominal`` against ``target``
    residual_mm, residual_deg : (n,) the calibrated TCP at ``q`` against ``target``
    success : (n,) bool, reached (and the nominal IK of a pose target found)
    reason : one phrase
    """

    target: np.ndarray
    q_nominal: np.ndarray
    q: np.ndarray
    cmd: np.ndarray
    correction_mm: np.ndarray
    correction_deg: np.ndarray
    predicted_mm: np.ndarray
    predicted_deg: np.ndarray
    residual_mm: np.ndarray
    residual_deg: np.ndarray
    success: np.ndarray
    reason: str


def as_poses(p: np.ndarray, R: np.ndarray) -> np.ndarray:
    """(n, 4, 4) homogeneous poses from points (n, 3) and rotations (n, 3, 3)."""
    T = np.zeros((len(p), 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = R, p, 1.0
    return T


def pose_difference(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (mm) and rotation angle (deg) between poses A and B, each (n, 4, 4)."""
    mm = np.linalg.norm(A[:, :3, 3] - B[:, :3, 3], axis=1)
    deg = np.degrees(np.linalg.norm(rotation_error(A[:, :3, :3], B[:, :3, :3]), axis=1))
    return mm, deg


def neighbour_seeds(is_pose: np.ndarray, joints: np.ndarray, default: np.ndarray
                    ) -> np.ndarray:
    """Seed joints for every target: a pose target takes the joints of the nearest joint
    target before it in the order given, else the nearest after it, else ``default``;
    a joint target keeps its own. (n, N) rad."""
    is_pose = np.asarray(is_pose, bool)
    joints = np.array(joints, float)
    n = len(is_pose)
    idx = np.where(~is_pose, np.arange(n), -1)
    before = np.maximum.accumulate(idx)
    after = np.minimum.accumulate(np.where(~is_pose, np.arange(n), n)[::-1])[::-1]
    pick = np.where(before >= 0, before, after)
    out = np.where((pick < n)[:, None], joints[np.minimum(pick, n - 1)], default)
    out[~is_pose] = joints[~is_pose]
    return out


def calibrated_points(error_model: ErrorModel, x: np.ndarray, tcp: np.ndarray,
                      measured: np.ndarray) -> np.ndarray | None:
    """The TCP point (n, 3) the calibrated robot carries: the identified one (the tool
    stage's) where ``measured``, else the TCP's own; None when every row is measured."""
    if measured.all():
        return None
    points = tcp[:, :3, 3].copy()
    if measured.any():
        points[measured] = error_model.perturb(x).tool
    return points


def _per_target(flange_T_tcp: np.ndarray | None, n: int) -> np.ndarray:
    T = np.eye(4) if flange_T_tcp is None else np.asarray(flange_T_tcp, float)
    return np.broadcast_to(T, (n, 4, 4)).copy()


def nominal_pose_ik(model: RobotModel, target: np.ndarray, seeds: np.ndarray,
                    flange_T_tcp: np.ndarray,
                    *, n_seeds: int = 24) -> IKResult:
    """The nominal controller's joints for TCP poses: pose IK from ``seeds`` ((n, N)); a
    target not reached from its seed is tried from ``n_seeds`` fixed starts over the joint
    ranges (seeded: the same answer every time), keeping the solution nearest its seed."""
    n = len(target)
    limits = model.limits_rad()
    R_flange = target[:, :3, :3] @ np.swapaxes(flange_T_tcp[:, :3, :3], 1, 2)
    tool = flange_T_tcp[:, :3, 3]
    res = solve_ik(NominalTcpFK(model, tool), seeds, target[:, :3, 3], R_flange,
                   limits=limits, max_iter=200, success_mm=1e-6, success_rad=1e-7)
    miss = np.flatnonzero(~res.success)
    if miss.size and n_seeds and n:
        lo, hi = np.maximum(limits[:, 0], -np.pi), np.minimum(limits[:, 1], np.pi)
        starts = np.random.default_rng(0).uniform(lo, hi, size=(n_seeds, model.n_joints))
        # every (target, start) pair is one row of the batch: the tool repeats with it
        fk = NominalTcpFK(model, np.repeat(tool[miss], n_seeds, axis=0))
        more = solve_ik_multistart(fk, target[miss, :3, 3], R_flange[miss], starts,
                                   reference=seeds[miss], limits=limits, max_iter=200,
                                   success_mm=1e-6, success_rad=1e-7)
        res.q[miss], res.success[miss] = more.q, more.success
        res.position_error_mm[miss] = more.position_error_mm
        res.orientation_error_rad[miss] = more.orientation_error_rad
    return res


def compensate_targets(
    error_model: ErrorModel,
    x: np.ndarray,
    joints: np.ndarray,
    *,
    pose: np.ndarray | None = None,
    is_pose: np.ndarray | None = None,
    flange_T_tcp: np.ndarray | None = None,
    columns: dict | None = None,
    calibrated_tool: bool | np.ndarray = False,
    max_iter: int = 50,
) -> PoseCompensation:
    """Compensated joints and poses for a program's targets, in program order.

    Parameters
    ----------
    error_model, x : the calibration (e.g. :func:`~calibration.exports.params_io.read_params`)
    joints : (n, N) rad: a joint target's joints; a pose target's seed (the joints near
        which the controller will solve it, e.g. :func:`neighbour_seeds`)
    pose : (n, 4, 4) the pose targets (base_T_tcp, mm; rows where ``is_pose``)
    is_pose : (n,) bool, which rows are pose targets (default: none)
    flange_T_tcp : (4, 4) or (n, 4, 4) the active TCP per target (default the flange)
    columns : per-target data for the effects (``temp_c``, ``payload_kg``: (n,);
        ``dirs``: (n, N))
    calibrated_tool : bool or (n,) bool, the TCP is the point the calibration measured (its
        tool stage): the calibrated robot carries the identified point, the nominal one
        ``flange_T_tcp``'s (default: the model's tool); per target when an array
    """
    model = error_model.model
    joints = np.atleast_2d(np.asarray(joints, float))
    n, N = joints.shape
    if model.n_joints != N:
        raise ValueError(f"targets have {N} joints, the model {model.name} has "
                         f"{model.n_joints}")
    is_pose = np.zeros(n, bool) if is_pose is None else np.asarray(is_pose, bool)
    measured = np.broadcast_to(np.asarray(calibrated_tool, bool), (n,))
    if flange_T_tcp is None and measured.all():
        flange_T_tcp = np.eye(4)
        flange_T_tcp[:3, 3] = model.tool_mm()
    tcp = _per_target(flange_T_tcp, n)
    nominal = NominalTcpFK(model, tcp[:, :3, 3])
    r = nominal.chain(joints)
    target = as_poses(r.base_p_tcp, r.base_R_flange @ tcp[:, :3, :3])
    q_nom, found = joints.copy(), np.ones(n, bool)
    if is_pose.any():
        target[is_pose] = np.asarray(pose, float)[is_pose]
        ik = nominal_pose_ik(model, target[is_pose], joints[is_pose], tcp[is_pose])
        q_nom[is_pose], found[is_pose] = ik.q, ik.success
    cols = dict(columns or {})
    if "dirs" not in cols:
        cols["dirs"] = derive_directions(q_nom)
    cal = CalibratedFK(error_model, x, cols, calibrated_points(error_model, x, tcp, measured))
    R_flange = target[:, :3, :3] @ np.swapaxes(tcp[:, :3, :3], 1, 2)
    res = solve_ik(cal, q_nom, target[:, :3, 3], R_flange if N >= 6 else None,
                   limits=model.limits_rad(), max_iter=max_iter, success_mm=1e-6,
                   success_rad=1e-7)
    rc = nominal.chain(res.q)
    cmd = as_poses(rc.base_p_tcp, rc.base_R_flange @ tcp[:, :3, :3])
    rr = [cal.chain(q) for q in (q_nom, res.q)]
    before, after = (as_poses(c.base_p_tcp, c.base_R_flange @ tcp[:, :3, :3]) for c in rr)
    success = res.success & found
    bad = int((~success).sum())
    reason = (f"all {n} targets reached" if not bad else
              f"{bad} of {n} targets not reached" + (
                  f" ({int((~found).sum())} pose targets out of the nominal robot's reach)"
                  if (~found).any() else ""))
    return PoseCompensation(target, q_nom, res.q, cmd, *pose_difference(cmd, target),
                            *pose_difference(before, target), *pose_difference(after, target),
                            success, reason)


def compensate_joint_targets(error_model: ErrorModel, x: np.ndarray, q: np.ndarray,
                             flange_T_tcp: np.ndarray | None = None, **options: Any
                             ) -> PoseCompensation:
    """:func:`compensate_targets` for joint targets only: ``q`` (n, N) rad."""
    return compensate_targets(error_model, x, q, flange_T_tcp=flange_T_tcp, **options)


def compensate_pose_targets(error_model: ErrorModel, x: np.ndarray, base_T_tcp: np.ndarray,
                            seeds: np.ndarray, flange_T_tcp: np.ndarray | None = None,
                            **options: Any) -> PoseCompensation:
    """:func:`compensate_targets` for pose targets only: ``base_T_tcp`` (n, 4, 4), each
    solved near its seed (``seeds`` (N,) or (n, N) rad)."""
    T = np.asarray(base_T_tcp, float).reshape(-1, 4, 4)
    seeds = np.broadcast_to(np.asarray(seeds, float), (len(T), error_model.model.n_joints))
    return compensate_targets(error_model, x, seeds, pose=T, is_pose=np.ones(len(T), bool),
                              flange_T_tcp=flange_T_tcp, **options)
