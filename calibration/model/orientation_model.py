"""Predicted orientations of a 6-DoF target, and their exact Jacobian.

``tracker_R_target = tracker_R_base · base_R_flange · flange_R_target``: the base stage's
rotation, the chain's flange orientation at the joints as they really are, and the
target stage's rotation (``tool_rotation``; the flange's own without it). The drift and
measure stages move or scale points, not the target's orientation, and a length growth
(thermal) or a tool point leaves it alone too, so those columns are zero.

The Jacobian is an angular velocity in the tracker frame per parameter,
``R(x + dx) = exp([W dx]x) R(x)``: a joint correction turns the flange about that
joint's axis, a table entry about its elementary rotation's axis
(:attr:`~calibration.model.kinematics.ChainResult.dW_internal`), the base rotation vector r
about ``R_base J_r(r)`` and the target's about ``tracker_R_target J_r(r)`` (J_r the
right Jacobian of SO(3)).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .kinematics import ChainResult
from .transforms import right_jacobian


def target_orientations(em: Any, x: np.ndarray, c: Any, r: ChainResult,
                        jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """``tracker_R_target`` (n, 3, 3) and its Jacobian (n, 3, p) (None without it).

    Parameters
    ----------
    em : the :class:`~calibration.fit.error_model.ErrorModel` (a room above this one:
        typed ``Any`` here)
    x : (p,) its parameters
    c : its :class:`~calibration.fit.error_model.Perturbed` inputs at ``x``
    r : the :class:`~calibration.model.kinematics.ChainResult` of those inputs (with its
        Jacobian when ``jacobian``)
    """
    base_R_flange = r.base_R_flange
    flange_R_target = np.eye(3) if c.flange_R_target is None else c.flange_R_target
    R_base = np.eye(3) if c.tracker_T_base is None else c.tracker_T_base[0]
    base_R_target = base_R_flange @ flange_R_target
    R = R_base @ base_R_target
    if not jacobian:
        return R, None
    n = base_R_flange.shape[0]
    W = np.zeros((n, 3, em.n_params))
    eff, sls, stages = em.effects, em.slices, em._by_stage
    for i in stages["joint"]:
        j = eff[i].joint - 1
        W[:, :, sls[i]] = r.dR_dq[:, :, j][:, :, None] * c.partials[i][:, None, :]
    if stages["table"]:
        dW = r.dW_internal
        N = dW.shape[0]
        for i in stages["table"]:
            part = c.partials[i]
            block = part.reshape(N * 5, -1).T @ dW.reshape(N * 5, 3 * n)
            W[:, :, sls[i]] = block.reshape(-1, 3, n).transpose(2, 1, 0)
    for i in stages["target"]:
        W[:, :, sls[i]] = base_R_target @ c.partials[i]
    W = np.matmul(R_base, W)
    for i in stages["base"]:
        if eff[i].family == "base":
            k = sls[i].start
            W[:, :, k + 3:k + 6] = R_base @ right_jacobian(x[sls[i]][3:])
    return R, W
