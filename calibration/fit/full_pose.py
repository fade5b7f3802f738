"""Full-pose identification: what :func:`calibration.fit.identify.identify` adds when the data
carry a 6-DoF target's orientations.

A calibration is *full pose* when its error model says where the target's frame sits on
the flange (the ``tool_rotation`` effect, the ``target`` stage) and its calibration rows
have orientations: the orientation rows then join the position rows of the
least-squares problem (:class:`~calibration.fit.orientation_residuals.OrientationRows`),
weighted by their own uncertainty. An uncertainty the data do not give (no
``sigma_deg``, no ``sigma_mm``) is estimated from the residuals, and the problem solved
again, until it settles (:func:`solve`).

A *position-only* calibration of data that have orientations still says how well it
predicts them (:func:`predicted_orientations`): the target's mounting on the flange,
which positions cannot know, is fitted to the calibration rows' orientations with every
other parameter held, and the orientation error left on calibration and validation rows
is what the calibrated robot would get wrong.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from ..data.dataset import Dataset
from ..effects import NestedTool, ToolRotation
from ..effects.tool_frame import mean_rotation
from ..errors import InputError
from ..model.transforms import quat_to_matrix
from .error_model import ErrorModel
from .orientation_residuals import OrientationRows, orientation_stats, rotation_residuals
from .solvers import Problem, SolverResult

if TYPE_CHECKING:
    from .error_model import Bound
    from .identify import Fit

#: variance-component rounds when the data lack an uncertainty
REWEIGHT_ROUNDS = 3
#: solvers that fit orientation rows (ridge weighs and regularises positions only)
FULL_POSE_SOLVERS = ("lm", "besa", "sa", "besa+lm")


def is_full_pose(error_model: ErrorModel, data: Dataset) -> bool:
    """True when the model has a target orientation and the data orientations."""
    return data.quat is not None and any(e.stage == "target" for e in error_model.effects)


def orientation_rows(error_model: ErrorModel, data: Dataset,
                     solver: str) -> OrientationRows | None:
    """The orientation rows of a full-pose problem, None for a position-only one.

    Raises
    ------
    InputError
        A solver that cannot fit orientations (``ridge``).
    """
    if not is_full_pose(error_model, data):
        return None
    if solver not in FULL_POSE_SOLVERS:
        raise InputError(f"{data.source}: solver {solver!r} fits positions only; a full-pose "
                         f"calibration (tool_rotation with orientation data) needs one of "
                         f"{', '.join(FULL_POSE_SOLVERS)}")
    return OrientationRows.of(data)


def solve(problem: Problem, solver_fn: Callable[..., SolverResult],
          options: dict[str, Any]) -> SolverResult:
    """Run ``solver_fn`` on ``problem``; with orientation rows whose uncertainty was
    estimated, re-estimate it from the residuals and solve again from there (a few
    rounds, until the weights settle within 1 %)."""
    result = solver_fn(problem, **options)
    pose = problem.pose
    if pose is None or not pose.estimated:
        return result
    for _ in range(REWEIGHT_ROUNDS):
        x = problem.full(result.xf)
        P, _, R, _ = problem.evaluate_pose(x)
        before = pose.weight.copy()
        pose.reweight(problem.bound.data.tracker_p_smr - P, R)
        if np.allclose(pose.weight, before, rtol=1e-2):
            break
        problem.x0 = x
        problem.seen, problem.seen_pose = [], []
        result = solver_fn(problem, **options)
    return result


def with_orientation_rows(problem: Problem, x: np.ndarray, r_w: np.ndarray,
                          J_w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position rows (n, 3) and Jacobian (n, 3, p) for the covariance, followed by the
    problem's orientation rows at ``x`` when it has them (so the parameters' uncertainty
    reflects what orientations add)."""
    if problem.pose is None:
        return r_w, J_w
    _, _, R, W = problem.evaluate_pose(x)
    ro, Jo = problem.pose.residual_and_jacobian(R, W)
    return np.vstack([r_w, ro]), np.concatenate([J_w, Jo])


def attach_orientations(fit: Fit, problem: Problem) -> None:
    """Orientation residuals and statistics on ``fit`` (calibration and validation rows)
    when its data have orientations: fitted (full pose) or predicted (position only)."""
    if fit.data.quat is None:
        return
    em, x = fit.error_model, fit.values
    held = fit.valid_data if fit.valid_data is not None and fit.valid_data.quat is not None \
        else None
    if problem.pose is not None:
        R = problem.evaluate_pose(x)[2]
        fit.orientation_residuals = rotation_residuals(problem.pose.R, R)
        fit.orientation_fitted = True
        if held is not None and held.quat is not None:
            Rv = em.evaluate_pose(x, em.bind(held), jacobian=False)[2]
            fit.valid_orientation_residuals = rotation_residuals(quat_to_matrix(held.quat), Rv)
    else:
        fit.orientation_residuals, vres = predicted_orientations(em, x, fit.data, held)
        fit.orientation_fitted = False
        fit.valid_orientation_residuals = vres
    fit.calib.update(orientation_stats(fit.orientation_residuals))
    if fit.valid is not None and fit.valid_orientation_residuals is not None:
        fit.valid.update(orientation_stats(fit.valid_orientation_residuals))


def predicted_orientations(em: ErrorModel, x: np.ndarray, calib: Dataset,
                           held: Dataset | None = None
                           ) -> tuple[np.ndarray, np.ndarray | None]:
    """Orientation residuals (rad) of the model ``(em, x)`` on ``calib`` and ``held``
    rows (None when absent), with the target's mounting on the flange fitted to the
    calibration rows' orientations (a model that already has it keeps its own)."""
    if calib.quat is None:
        raise ValueError(f"{calib.source}: no orientations to predict")
    R = em.evaluate_pose(x, em.bind(calib), jacobian=False)[2]
    meas = quat_to_matrix(calib.quat)
    mount = np.eye(3)
    if not any(e.stage == "target" for e in em.effects):
        mount = mean_rotation(np.swapaxes(R, 1, 2) @ meas)
    res = rotation_residuals(meas, R @ mount)
    vres = None
    if held is not None and held.n and held.quat is not None:
        Rv = em.evaluate_pose(x, em.bind(held), jacobian=False)[2]
        vres = rotation_residuals(quat_to_matrix(held.quat), Rv @ mount)
    return res, vres


def structural_rows(error_model: ErrorModel, bound: Bound,
                    x: np.ndarray) -> np.ndarray | None:
    """The orientation rows' Jacobian (3 n, p), mm-equivalent, at ``x`` for the
    identifiability analysis of a full-pose problem (None for a position-only one)."""
    if not is_full_pose(error_model, bound.data):
        return None
    W = error_model.evaluate_pose(x, bound, jacobian=True)[3]
    w = OrientationRows.of(bound.data).weight
    return (W * w[:, None, None]).reshape(-1, error_model.n_params)


def for_data(error_model: ErrorModel, data: Dataset,
             position_only: bool = False) -> tuple[ErrorModel, list[str]]:
    """The error model the data call for, and notes saying what changed.

    Rows naming several targets (``tool_id``) get a tool point per SMR nest
    (:class:`~calibration.effects.NestedTool`); orientations get the target's
    orientation in the flange (``tool_rotation``), unless ``position_only`` (which also
    drops a ``tool_rotation`` the effects name).
    """
    effects, notes = list(error_model.effects), list[str]()
    nests = list(dict.fromkeys(data.tool_id)) if data.tool_id is not None else []
    for i, e in enumerate(effects):
        if e.family == "tool" and len(nests) > 1 and getattr(e, "nests", None) != nests:
            effects[i] = NestedTool(error_model.model, nests)
            notes.append(f"{data.source}: {len(nests)} targets on the tool (tool_id "
                         f"{', '.join(nests)}): each nest's point is identified")
    has_target = any(e.stage == "target" for e in effects)
    if position_only and has_target:
        effects = [e for e in effects if e.stage != "target"]
    elif data.quat is not None and not position_only and not has_target and any(
            e.family == "tool" for e in effects):
        effects.append(ToolRotation(error_model.model))
        notes.append(f"{data.source}: the rows have orientations (a 6-DoF target): full-pose "
                     "calibration, the target's orientation in the flange (tool_rotation) "
                     "added to the effects (--position-only fits positions only)")
    if effects == error_model.effects:
        return error_model, notes
    return ErrorModel(error_model.model, effects), notes
