"""Compensation: joints that reach target points on the real robot, from a calibration.

Targets are points of the tool (the calibrated tool point) in the **robot base frame**,
mm. The calibrated chain is the error model without its base (tracker_T_base) and
without measurement effects (tracker scale): those belong to the cell and the
instrument, not to the robot.

For each target, the nominal solution q_nom (given, or found by IK on the nominal
model) fixes the configuration and the orientation. Compensation then solves, by
batched damped Newton from q_nom, for the joints q_c that put the calibrated tool
point on the target with the flange in the orientation the nominal model has at q_nom
(a 6-axis arm: 6 equations, 6 unknowns); with ``keep_orientation=False`` (or fewer than
6 joints) it is a minimum-norm correction from q_nom for the position alone.

A controller that knows only its nominal model is then sent the *corrected Cartesian
target*: the nominal forward kinematics of q_c (point of the nominal tool and flange
orientation); its own IK gives back q_c.

Lengths mm, angles rad.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..fit.error_model import ErrorModel
from ..model.inverse import ChainFK, IKResult, solve_ik, solve_ik_multistart
from ..model.kinematics import ChainResult, run_chain
from ..model.robot_model import RobotModel


class CalibratedFK:
    """Forward kinematics of the calibrated robot in its base frame, for :func:`solve_ik`.

    Every effect at the joint, table, length and tool stages is applied (joint
    corrections are evaluated at the commanded joints); base and measure stages are
    left out. The joint Jacobian is that of the chain at the corrected joints (the
    small derivative of pose-dependent joint corrections is neglected: Newton still
    converges to the exact solution because the residual is exact).

    Parameters
    ----------
    error_model, x : the calibration (internal units)
    columns : extra per-pose data some effects need (``temp_c``, ``payload_kg``, ...),
        arrays of shape (n,) for n targets
    tool : (3,) or (n, 3) the tool point (flange frame, mm) to use instead of the
        calibrated one: a program's TCP (``set_tcp``) rather than the calibration's SMR;
        None keeps the tool stage's point
    """

    #: :func:`~calibration.model.inverse.solve_ik` passes the target rows it evaluates
    takes_rows = True

    def __init__(self, error_model: ErrorModel, x: np.ndarray,
                 columns: dict[str, Any] | None = None,
                 tool: np.ndarray | None = None) -> None:
        self.em = error_model
        self.x = np.asarray(x, float)
        self.columns = columns or {}
        self.tool = None if tool is None else np.asarray(tool, float)

    def chain(self, q: np.ndarray, rows: np.ndarray | None = None) -> ChainResult:
        """The :class:`~calibration.model.kinematics.ChainResult` of the calibrated robot."""
        em = self.em
        q = np.atleast_2d(np.asarray(q, float))
        bound = None
        if any(e.stage in ("joint", "length") for e in em.effects):
            cols = {k: (v if rows is None else np.asarray(v)[rows])
                    for k, v in self.columns.items()}
            bound = em.bind(Dataset(q=q, tracker_p_smr=np.zeros((len(q), 3)), source="compensation",
                                    **cols))
        c = em.perturb(self.x, bound)
        tool = c.tool
        if self.tool is not None:
            tool = self.tool if self.tool.ndim == 1 or rows is None else self.tool[rows]
        return run_chain(em.model.convention, c.table, q if c.q is None else c.q, tool,
                         c.length_scale, jacobian=False,
                         prismatic=em.model.prismatic_mask())

    def __call__(self, q: np.ndarray, rows: np.ndarray | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        r = self.chain(q, rows)
        return r.base_p_tcp, r.base_R_flange, r.dP_dq, r.dR_dq

    def point(self, q: np.ndarray) -> np.ndarray:
        """Calibrated tool point (base frame) for commanded joints q (rad), (n, 3) mm."""
        return self.chain(q).base_p_tcp


@dataclass
class Compensation:
    """Result of :func:`compensate`, n targets, N joints.

    Attributes
    ----------
    target : (n, 3) desired tool point, robot base frame, mm
    q_nominal : (n, N) nominal solution, rad
    q : (n, N) compensated joints (send these to reach the target), rad
    cmd_point : (n, 3) corrected Cartesian target: nominal FK of ``q`` (nominal tool), mm
    cmd_R : (n, 3, 3) flange orientation of that corrected target
    residual_mm : (n,) calibrated model's distance from the target at ``q`` (solver
        accuracy), mm
    correction_mm : (n,) how far the corrected Cartesian target moved from the nominal, mm
    success : (n,) bool, the calibrated tool point reaches the target
    orientation_kept : (n,) bool, the nominal flange orientation is held as well
    iterations : damped-Newton iterations (largest over the targets)
    reason : solver summary
    """

    target: np.ndarray
    q_nominal: np.ndarray
    q: np.ndarray
    cmd_point: np.ndarray
    cmd_R: np.ndarray
    residual_mm: np.ndarray
    correction_mm: np.ndarray
    success: np.ndarray
    orientation_kept: np.ndarray
    iterations: int
    reason: str


def nominal_solution(model: RobotModel, target: np.ndarray, q_start: np.ndarray | None = None, *,
                     limits: np.ndarray | None = None, n_seeds: int = 24) -> IKResult:
    """Nominal joints for target points: minimum-norm position IK on the nominal model.

    Every target is tried from ``q_start`` first; a target not reached from there is
    tried again from ``n_seeds`` fixed starts spread over the joint ranges (seeded: the
    same answer every time), keeping the reached solution nearest ``q_start``.

    Parameters
    ----------
    model : the nominal RobotModel (its tool is the controller's TCP)
    target : (n, 3) mm, base frame
    q_start : (N,) starting joints (the configuration to stay in), rad; default all zeros
    limits : (N, 2) joint limits, rad
    n_seeds : further starts for the targets not reached from ``q_start``
    """
    fk = ChainFK.from_model(model)
    target = np.atleast_2d(np.asarray(target, float))
    N = model.n_joints
    start = np.zeros(N) if q_start is None else np.asarray(q_start, float).reshape(N)
    res = solve_ik(fk, start, target, None, limits=limits, max_iter=200)
    miss = np.flatnonzero(~res.success)
    if miss.size and n_seeds:
        lim = limits if limits is not None else np.tile([-np.pi, np.pi], (N, 1))
        lo, hi = np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi)
        seeds = np.random.default_rng(0).uniform(lo, hi, size=(n_seeds, N))
        more = solve_ik_multistart(fk, target[miss], None, np.vstack([start, seeds]),
                                   reference=start, limits=limits, max_iter=200)
        res.q[miss] = more.q
        res.success[miss] = more.success
        res.position_error_mm[miss] = more.position_error_mm
        res.iterations = max(res.iterations, more.iterations)
    return res


def _reason(success: np.ndarray, residual_mm: np.ndarray, n_position_only: int) -> str:
    """What the compensation achieved, in one phrase (consistent with ``success``)."""
    n, bad = len(success), int((~success).sum())
    text = (f"all {n} targets reached" if not bad else
            f"{bad} of {n} targets not reached (worst {residual_mm[~success].max():.3g} mm)")
    if n_position_only:
        text += f"; {n_position_only} solved for position only (orientation not held)"
    return text


def compensate(
    error_model: ErrorModel,
    x: np.ndarray,
    target: np.ndarray,
    q_nominal: np.ndarray | None = None,
    *,
    q_start: np.ndarray | None = None,
    keep_orientation: bool = True,
    columns: dict | None = None,
    max_iter: int = 50,
) -> Compensation:
    """Compensated joints and corrected Cartesian targets for target points.

    Parameters
    ----------
    error_model, x : the calibration (e.g. from :func:`~calibration.exports.params_io.load_params`)
    target : (n, 3) desired tool points, robot base frame, mm
    q_nominal : (n, N) nominal joints (rad), e.g. the joints the program uses today; when
        None they are found by :func:`nominal_solution` from ``q_start``
    q_start : (N,) starting configuration for the nominal IK (default all zeros, then
        fixed starts over the joint ranges, :func:`nominal_solution`), rad
    keep_orientation : hold the nominal flange orientation (6 joints); else minimum-norm
    columns : per-target data for effects that need it (``temp_c``...), arrays (n,)
    """
    model = error_model.model
    target = np.atleast_2d(np.asarray(target, float))
    n, N = len(target), model.n_joints
    limits = model.limits_rad()
    nominal = ChainFK.from_model(model)
    if q_nominal is None:
        q_nominal = nominal_solution(model, target, q_start, limits=limits).q
    q_nominal = np.atleast_2d(np.asarray(q_nominal, float))
    if q_nominal.shape != (n, N):
        raise ValueError(f"q_nominal has shape {q_nominal.shape}, expected ({n}, {N})")
    fk = CalibratedFK(error_model, x, columns)
    R_nom = nominal(q_nominal)[1]

    orient = keep_orientation and N >= 6
    res = solve_ik(fk, q_nominal, target, R_nom if orient else None, limits=limits,
                   max_iter=max_iter, success_mm=1e-6, success_rad=1e-7)
    q = res.q
    kept = res.success & orient
    n_position_only = 0
    if orient and not res.success.all():
        # near a singularity the orientation cannot be held exactly: fall back to the
        # minimum-norm position correction from the nominal joints for those targets
        bad = np.flatnonzero(~res.success)
        sub = CalibratedFK(error_model, x, {k: np.asarray(v)[bad] for k, v in
                                           (columns or {}).items()})
        fb = solve_ik(sub, q_nominal[bad], target[bad], None, limits=limits,
                      max_iter=max_iter, success_mm=1e-6)
        q[bad] = fb.q
        res.success[bad] = fb.success
        n_position_only = len(bad)
    P_cmd, R_cmd, _, _ = nominal(q)
    P_nom = nominal.point(q_nominal)
    residual = np.linalg.norm(fk.chain(q).base_p_tcp - target, axis=1)
    return Compensation(target, q_nominal, q, P_cmd, R_cmd, residual,
                        np.linalg.norm(P_cmd - P_nom, axis=1), res.success, kept,
                        res.iterations, _reason(res.success, residual, n_position_only))


@dataclass
class Targets:
    """Target points read from a targets CSV.

    Attributes
    ----------
    base_p_tcp : (n, 3) desired tool points in the robot base frame, mm
    q : (n, N) nominal joints, rad, or None
    pose_id : n labels
    columns : optional per-target data: ``temp_c``, ``payload_kg``, ``t_s`` (n,),
        ``dirs`` (n, N) approach directions (for backlash), ``joint_temp`` (n, N) °C
    lines : n line numbers in the file (None: not read from a file)
    """

    base_p_tcp: np.ndarray
    q: np.ndarray | None
    pose_id: list[str]
    columns: dict
    lines: list[int] | None = None


def load_targets(path: str | Path, model: RobotModel) -> Targets:
    """Read a targets CSV: ``x, y, z`` (mm, robot base frame) required; optional
    ``pose_id``, ``q1..qN`` (deg, nominal/seed joints, all or none), ``dir1..dirN`` (the
    direction each joint will approach the target from, -1/0/+1, all or none: for a model
    with backlash), ``temp_c``, ``payload_kg``, and the thermal state a target will be
    reached at: ``joint_temp1..N`` (°C, all or none) and ``t_s`` (s, the measurement
    CSV's clock). Strict like the measurement CSV: errors name file, line and column."""
    from ..data.columns import CsvContext, column
    from ..data.dataset import MAX_LENGTH_MM, PLAUSIBLE_LENGTH, CsvTable

    t = CsvTable(path)
    N = model.n_joints
    t.require(["x", "y", "z"])
    has_q = t.all_or_none([f"q{j + 1}" for j in range(N)], "joint columns")
    xyz = np.column_stack([t.numeric(c) for c in "xyz"])
    for k, c in enumerate("xyz"):
        t.within(c, xyz[:, k], -MAX_LENGTH_MM, MAX_LENGTH_MM, PLAUSIBLE_LENGTH)
    q = np.radians(t.joints_deg(model)) if has_q else None
    pose_id = t.ids("pose_id")
    ctx = CsvContext(N, model)
    columns: dict[str, Any] = {}
    for name in ("temp_c", "payload_kg", "dirs", "joint_temp", "t_s"):  # the table's readers
        columns.update(column(name).read_csv(t, ctx, columns))
    columns = {k: v for k, v in columns.items() if v is not None}
    return Targets(xyz, q, pose_id, columns, [int(v) for v in t.lines])
