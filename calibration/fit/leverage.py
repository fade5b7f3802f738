"""Leverage: how much of each point's residual the fit itself absorbed, and residuals
studentised by it.

A point's residual ``r_i`` after a least-squares fit has covariance ``sigma² (I - H_ii)``,
``H_ii = J_i C J_iᵀ`` the point's 3 x 3 block of the hat matrix (``C`` the parameter
covariance over sigma²); a point the fit predicts without having used it, ``sigma² (I +
H_ii)``. The blocks come from the covariance's own factorisation, ``C = M Mᵀ``
(:attr:`calibration.fit.identify.Fit.hat_factor`): ``H_ii = Q_i Q_iᵀ`` with ``Q = J M`` — one
(3n, m) x (m, m) product, not a contraction over every pose — and the Jacobian the solver
evaluated last (:attr:`~calibration.fit.identify.Fit.jacobian`), not a new pass.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..data.dataset import Dataset
    from .identify import Fit

#: eigenvalues of a residual's covariance factor are clipped here (see :func:`studentise`)
MIN_FACTOR = 1e-2


def residual_factors(fit: Fit, rows: Dataset, included: np.ndarray,
                     jacobian: np.ndarray | None = None) -> np.ndarray:
    """Covariance of each residual of ``rows`` over sigma^2 at ``fit``, (n, 3, 3).

    ``I - J_i C J_i^T`` for a point the fit used (``included``), ``I + J_i C J_i^T`` for
    one it predicts, with ``C`` the fit's parameter covariance over its sigma^2 (the
    inverse normal matrix, penalty rows included; robust weights are not). With the fit's
    ``hat_factor`` M (``C = M M^T``, from the covariance's own factorisation) the block is
    ``Q_i Q_i^T``, ``Q_i = J_i M``: one (3n, m) x (m, m) product instead of a contraction
    over every pose. ``jacobian`` (n, 3, p): the Jacobian at the fit on ``rows`` when the
    caller has it (else evaluated).
    """
    em = fit.error_model
    n = rows.n
    s2 = float(fit.sigma_mm) ** 2
    eye = np.broadcast_to(np.eye(3), (n, 3, 3))
    if not np.isfinite(s2) or s2 <= 0 or not fit.free.any():
        return eye.copy()
    J = em.evaluate(fit.values, em.bind(rows), jacobian=True)[1] if jacobian is None \
        else jacobian
    J = J[:, :, fit.free]
    M = getattr(fit, "hat_factor", None)
    if M is None or M.shape[0] != J.shape[2]:
        M = hat_factor(fit.covariance[np.ix_(fit.free, fit.free)] / s2)
    Q = (J.reshape(3 * n, -1) @ M).reshape(n, 3, -1)
    G = np.einsum("nim,njm->nij", Q, Q)
    sign = np.where(np.asarray(included, bool), -1.0, 1.0)[:, None, None]
    return eye + sign * G


def hat_factor(C: np.ndarray) -> np.ndarray:
    """M with ``M M^T = C`` for a symmetric positive semi-definite C: its Cholesky factor,
    or (singular C) from its eigen-decomposition, eigenvalues below zero clipped."""
    C = 0.5 * (C + C.T)
    try:
        return np.linalg.cholesky(C)
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(C)
        return V * np.sqrt(np.clip(w, 0.0, None))


def studentise(r: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """``M_i^(-1/2) r_i`` for residuals (n, 3) with covariance factors M (n, 3, 3); the
    eigenvalues of M are clipped at 0.01 (a point that alone determines a direction
    cannot be checked in it; amplify its residual at most tenfold)."""
    w, V = np.linalg.eigh(0.5 * (factors + np.swapaxes(factors, 1, 2)))
    w = np.clip(w, MIN_FACTOR, None)
    return np.einsum("nij,nj->ni", V, np.einsum("nji,nj->ni", V, r) / np.sqrt(w))


def residuals_on(fit: Fit, full: Dataset, out: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Residuals (n, 3) and Jacobian (n, 3, p) of every row of ``full`` at ``fit``, which
    was fitted to the rows not ``out``: its own residuals and Jacobian (when it kept it)
    for those, one evaluation of the rows left out for the rest."""
    if not out.any():
        return fit.residuals, fit.jacobian
    em = fit.error_model
    if fit.jacobian is None or fit.jacobian.shape[0] != fit.data.n:
        return full.tracker_p_smr - fit.predict(full), None
    rows = full.subset(out)
    P, J_out = em.evaluate(fit.values, em.bind(rows), jacobian=True)
    resid = np.empty((full.n, 3))
    resid[~out], resid[out] = fit.residuals, rows.tracker_p_smr - P
    J = np.empty((full.n, 3, em.n_params))
    J[~out], J[out] = fit.jacobian, J_out
    return resid, J


def studentised_norms(r: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """``|M_i^(-1/2) r_i|`` (n,) for residuals (n, 3) with covariance factors M (n, 3, 3),
    as :func:`studentise` gives them: ``sqrt(r_iᵀ M_i⁻¹ r_i)`` by a 3 x 3 solve where
    every eigenvalue of M_i is surely above the clip (Gershgorin's discs), the
    eigen-decomposition elsewhere."""
    r = np.atleast_2d(r)
    M = 0.5 * (factors + np.swapaxes(factors, 1, 2))
    diag = np.diagonal(M, axis1=1, axis2=2)
    radius = np.sum(np.abs(M), axis=2) - np.abs(diag)
    safe = np.min(diag - radius, axis=1) >= MIN_FACTOR
    out = np.empty(r.shape[0])
    if safe.any():
        rs = r[safe]
        out[safe] = np.sqrt(np.maximum(np.sum(rs * solve3(M[safe], rs), axis=1), 0.0))
    if not safe.all():
        out[~safe] = np.linalg.norm(studentise(r[~safe], factors[~safe]), axis=1)
    return out


def solve3(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x = A⁻¹ b for stacks of 3 × 3 systems (Cramer's rule, vectorised), A (..., 3, 3)."""
    a = [[A[..., i, j] for j in range(3)] for i in range(3)]
    # the adjugate's columns are the cross products of A's rows: A⁻¹ = [c0 c1 c2] / det
    c0 = _cross(a[1], a[2])
    c1 = _cross(a[2], a[0])
    c2 = _cross(a[0], a[1])
    det = a[0][0] * c0[0] + a[0][1] * c0[1] + a[0][2] * c0[2]
    det = np.where(np.abs(det) > 1e-300, det, 1e-300)
    b0, b1, b2 = b[..., 0] / det, b[..., 1] / det, b[..., 2] / det
    return np.stack([c0[i] * b0 + c1[i] * b1 + c2[i] * b2 for i in range(3)], axis=-1)


def _cross(u: list, v: list) -> list:
    """Cross product of two 3-vectors given as lists of their component arrays."""
    return [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
