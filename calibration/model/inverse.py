"""Inverse kinematics, batched over targets: damped Newton (Levenberg–Marquardt).

Every target is solved at once: the iteration works on arrays of shape
(n_targets, ...), each target with its own damping, and stops per target. A
forward function (:class:`ChainFK`, or anything with the same call signature)
gives the point, the flange orientation and the joint axes; the Jacobian of the
point with respect to joint j is ``axis_j x (P - origin_j)`` and that of the
orientation is ``axis_j`` (exact for a revolute chain).

Two kinds of target:

- **pose** (``target_R`` given): the target point of the tool and the flange
  orientation, 6 equations; for a 6-axis arm a square problem with isolated
  solutions (the start picks the configuration).
- **position** only: 3 equations; for a redundant arm the damped steps
  ``Jᵀ(JJᵀ + λI)⁻¹ e`` are minimum-norm corrections, so the solution stays near
  the start (the nominal joints).

Lengths mm, angles rad. Solvers return results, not exceptions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .kinematics import run_chain
from .robot_model import RobotModel

#: a forward function: joints q (n, N) (and, when it ``takes_rows``, the rows of the
#: targets evaluated) -> (P (n, 3), R (n, 3, 3), Jp (n, 3, N), Jw (n, 3, N))
ForwardFn = Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


@dataclass
class IKResult:
    """Result of :func:`solve_ik`.

    Attributes
    ----------
    q : (n, N) joint angles, rad
    success : (n,) bool, the target reached within the tolerances
    position_error_mm : (n,) distance of the reached point from the target, mm
    orientation_error_rad : (n,) angle between reached and target orientation, rad
        (zeros for position-only targets)
    iterations : the largest number of iterations any target took
    reason : a short summary ("all 20 targets reached", "3 of 20 not reached: ...")
    """

    q: np.ndarray
    success: np.ndarray
    position_error_mm: np.ndarray
    orientation_error_rad: np.ndarray
    iterations: int
    reason: str


class ChainFK:
    """Forward kinematics of a fixed chain (table and tool), with joint Jacobians.

    Parameters
    ----------
    convention : "dh" or "mdh"
    table : array, shape (N, 5), theta_offset, d, a, alpha, beta (rad, mm)
    tool : array, shape (3,), tool point in the flange frame, mm
    joint_offsets : array, shape (N,), optional
        added to the joint angles before the chain (zero-point corrections), rad
    prismatic : array of bool, shape (N,), optional
        the prismatic joints (None: all revolute)
    """

    def __init__(self, convention: str, table: np.ndarray, tool: np.ndarray,
                 joint_offsets: np.ndarray | None = None,
                 prismatic: np.ndarray | None = None) -> None:
        self.convention = convention
        self.prismatic = prismatic
        self.table = np.asarray(table, float)
        self.tool = np.asarray(tool, float)
        self.offsets = (np.zeros(len(self.table)) if joint_offsets is None
                        else np.asarray(joint_offsets, float))

    @classmethod
    def from_model(cls, model: RobotModel, tool: np.ndarray | None = None) -> ChainFK:
        """The nominal chain of a :class:`~calibration.model.robot_model.RobotModel`."""
        return cls(model.convention, model.dh_table(), model.tool_mm() if tool is None else tool,
                   prismatic=model.prismatic_mask())

    @property
    def n_joints(self) -> int:
        return self.table.shape[0]

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Point, flange orientation and joint Jacobians for joint angles q (rad), (n, N).

        Returns
        -------
        P : (n, 3) tool point, base frame, mm
        R : (n, 3, 3) flange orientation (columns are the flange axes)
        Jp : (n, 3, N) dP/dq, mm/rad
        Jw : (n, 3, N) angular velocity per joint rate (the joint axes), 1
        """
        r = run_chain(self.convention, self.table, np.atleast_2d(q) + self.offsets, self.tool,
                      jacobian=False, prismatic=self.prismatic)
        return r.base_p_tcp, r.base_R_flange, r.dP_dq, r.dR_dq

    def point(self, q: np.ndarray) -> np.ndarray:
        """Tool point for joint angles q (rad), shape (n, 3), mm."""
        return run_chain(self.convention, self.table, np.atleast_2d(q) + self.offsets,
                         self.tool, jacobian=False, prismatic=self.prismatic).base_p_tcp


def rotation_error(R: np.ndarray, R_target: np.ndarray) -> np.ndarray:
    """Rotation vector (base frame) that turns R into R_target: log(R_target Rᵀ), (n, 3) rad.

    Exact away from 180°; near 180° (where the log is ill-defined) the direction of the
    skew part is kept, which is enough to steer a damped Newton iteration.
    """
    M = R_target @ np.swapaxes(R, -1, -2)
    w = 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                        M[..., 1, 0] - M[..., 0, 1]], axis=-1)
    c = np.clip((np.trace(M, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    th = np.arccos(c)
    s = np.linalg.norm(w, axis=-1)
    f = np.where(s > 1e-12, th / np.maximum(s, 1e-300), 1.0)
    f = np.where(th > 3.0, np.pi / np.maximum(s, 1e-300) * (s > 1e-12), f)
    return w * f[..., None]


def wrap_to_pi(q: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(q) + np.pi) % (2 * np.pi) - np.pi


def solve_ik(
    fk: ForwardFn,
    q0: np.ndarray,
    target_p: np.ndarray,
    target_R: np.ndarray | None = None,
    *,
    limits: np.ndarray | None = None,
    rot_weight_mm: float = 100.0,
    max_iter: int = 100,
    tol_mm: float = 1e-9,
    tol_rad: float = 1e-12,
    success_mm: float = 1e-6,
    success_rad: float = 1e-8,
    max_step_rad: float = 0.5,
    mu0: float = 1e-3,
) -> IKResult:
    """Batched damped-Newton inverse kinematics.

    Parameters
    ----------
    fk : callable q (n, N) -> (P (n, 3), R (n, 3, 3), Jp (n, 3, N), Jw (n, 3, N))
        e.g. a :class:`ChainFK`; one with ``takes_rows = True`` is called as
        ``fk(q, rows)`` with the indices of the targets evaluated (per-target data).
    q0 : array, shape (n, N) or (N,), starting joints, rad
    target_p : array, shape (n, 3) or (3,), target tool point, mm
    target_R : array, shape (n, 3, 3) or (3, 3), optional
        target flange orientation; None for position-only targets
    limits : array, shape (N, 2), optional, joint limits (rad); steps are clipped to them
    rot_weight_mm : weight of an orientation error (mm per rad) against a position error
    max_iter : iterations at most
    tol_mm, tol_rad : a target stops iterating once within both
    success_mm, success_rad : a target counts as reached within these
    max_step_rad : largest joint step per iteration (norm over the joints), rad
    mu0 : initial relative damping

    Returns
    -------
    IKResult
    """
    target_p = np.atleast_2d(np.asarray(target_p, float))
    q = np.array(np.atleast_2d(q0), float)
    n = max(len(q), len(target_p))
    q = np.broadcast_to(q, (n, q.shape[1])).copy()
    target_p = np.broadcast_to(target_p, (n, 3))
    if target_R is not None:
        target_R = np.broadcast_to(np.asarray(target_R, float), (n, 3, 3))
    pose_R = target_R
    pose = pose_R is not None
    N = q.shape[1]

    rows = getattr(fk, "takes_rows", False)

    def residual(idx: np.ndarray, qq: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        P, R, Jp, Jw = fk(qq, idx) if rows else fk(qq)
        e = target_p[idx] - P
        if pose_R is not None:
            er = rotation_error(R, pose_R[idx])
            r = np.concatenate([e, rot_weight_mm * er], axis=1)
            J = np.concatenate([Jp, rot_weight_mm * Jw], axis=1)
        else:
            er = np.zeros_like(e)
            r, J = e, Jp
        return r, J, np.linalg.norm(e, axis=1), np.linalg.norm(er, axis=1)

    idx_all = np.arange(n)
    r, J, pe, oe = residual(idx_all, q)
    cost = np.einsum("ij,ij->i", r, r)
    mu = np.full(n, mu0)
    done = (pe <= tol_mm) & (oe <= tol_rad)
    iters = 0
    for _ in range(max_iter):
        act = np.flatnonzero(~done)
        if act.size == 0:
            break
        iters += 1
        Ja, ra = J[act], r[act]
        m = Ja.shape[1]
        if m < N:  # minimum-norm damped step Jᵀ(JJᵀ + λI)⁻¹ r
            A = Ja @ np.swapaxes(Ja, 1, 2)
            lam = mu[act] * np.trace(A, axis1=1, axis2=2) / m
            A = A + lam[:, None, None] * np.eye(m)
            dq = np.einsum("kmj,km->kj", Ja, np.linalg.solve(A, ra[..., None])[..., 0])
        else:
            A = np.swapaxes(Ja, 1, 2) @ Ja
            lam = mu[act] * np.trace(A, axis1=1, axis2=2) / N
            A = A + lam[:, None, None] * np.eye(N)
            g = np.einsum("kmj,km->kj", Ja, ra)
            dq = np.linalg.solve(A, g[..., None])[..., 0]
        norm = np.linalg.norm(dq, axis=1)
        dq *= np.minimum(1.0, max_step_rad / np.maximum(norm, 1e-300))[:, None]
        q_new = q[act] + dq
        if limits is not None:
            q_new = np.clip(q_new, limits[:, 0], limits[:, 1])
        r_new, J_new, pe_new, oe_new = residual(act, q_new)
        cost_new = np.einsum("ij,ij->i", r_new, r_new)
        ok = cost_new < cost[act]
        acc = act[ok]
        q[acc], r[acc], J[acc] = q_new[ok], r_new[ok], J_new[ok]
        pe[acc], oe[acc], cost[acc] = pe_new[ok], oe_new[ok], cost_new[ok]
        mu[acc] = np.maximum(mu[acc] * 0.2, 1e-12)
        mu[act[~ok]] *= 10.0
        tiny = np.linalg.norm(dq, axis=1) < 1e-15
        done[act] = ((pe[act] <= tol_mm) & (oe[act] <= tol_rad)) | (mu[act] > 1e10) | (ok & tiny)
    success = (pe <= success_mm) & (oe <= success_rad if pose else True)
    bad = int((~success).sum())
    reason = (f"all {n} targets reached" if not bad else
              f"{bad} of {n} targets not reached (worst {pe.max():.3g} mm, {oe.max():.3g} rad)")
    return IKResult(q, success, pe, oe, iters, reason)


def solve_ik_multistart(
    fk: ForwardFn,
    target_p: np.ndarray,
    target_R: np.ndarray | None,
    seeds: np.ndarray,
    *,
    reference: np.ndarray | None = None,
    **options: Any,
) -> IKResult:
    """Pose or position IK from several starts per target, keeping the best solution.

    Every (target, seed) pair is solved in one batch. Among the successful
    solutions of a target, the one nearest ``reference`` (wrapped joint distance,
    rad) wins; without a reference, the one nearest the first seed.

    Parameters
    ----------
    seeds : array, shape (k, N), starting joints, rad
    reference : array, shape (N,) or (n, N), optional
    options : passed to :func:`solve_ik`
    """
    target_p = np.atleast_2d(np.asarray(target_p, float))
    n, k = len(target_p), len(seeds)
    N = seeds.shape[1]
    tp = np.repeat(target_p, k, axis=0)
    tR = None if target_R is None else np.repeat(
        np.broadcast_to(np.asarray(target_R, float), (n, 3, 3)), k, axis=0)
    q0 = np.tile(seeds, (n, 1))
    res = solve_ik(fk, q0, tp, tR, **options)
    ref = seeds[0] if reference is None else np.asarray(reference, float)
    ref = np.broadcast_to(ref, (n, N))
    qs = res.q.reshape(n, k, N)
    dist = np.linalg.norm(wrap_to_pi(qs - ref[:, None, :]), axis=2)
    score = np.where(res.success.reshape(n, k), dist, np.inf)
    err = res.position_error_mm.reshape(n, k) + res.orientation_error_rad.reshape(n, k)
    best = np.where(np.isfinite(score).any(axis=1), np.argmin(score, axis=1),
                    np.argmin(err, axis=1))
    pick = np.arange(n) * k + best
    success = res.success[pick]
    bad = int((~success).sum())
    reason = f"all {n} targets reached" if not bad else f"{bad} of {n} targets not reached"
    return IKResult(res.q[pick], success, res.position_error_mm[pick],
                    res.orientation_error_rad[pick], res.iterations, reason)
