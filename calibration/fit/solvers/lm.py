"""Levenberg-Marquardt with Marquardt's diagonal scaling and Nielsen's damping update.

The normal equations are formed from the column-equilibrated Jacobian (so the
conditioning does not depend on units) and solved by Cholesky; a failed
factorisation only raises the damping.
"""

from __future__ import annotations

import numpy as np

from ...numerics.linalg import cho_solve, cholesky_upper
from .common import Problem, SolverResult


def solve_lm(
    problem: Problem,
    max_iter: int = 100,
    xtol: float = 1e-10,
    ftol: float = 1e-12,
    gtol: float = 1e-12,
    lambda0: float = 1e-7,
    xf0: np.ndarray | None = None,
) -> SolverResult:
    """Minimise the sum of squared residuals of ``problem`` over its free parameters.

    Stops when the scaled step is below ``xtol``, the relative cost decrease below
    ``ftol``, or the scaled gradient below ``gtol``. The initial damping ``lambda0``
    (relative to the largest diagonal of the equilibrated normal matrix) is small: a
    calibration starts close to linear (base from a rigid fit, nominal geometry), and
    heavy damping would crawl along weakly determined directions; a step that does
    not lower the cost raises it.
    """
    x = problem.xf0.copy() if xf0 is None else np.asarray(xf0, float).copy()
    if x.size == 0:
        r = problem.residual(x)
        return SolverResult(x, True, "no free parameters", 0, [{"iter": 0, "cost": float(r @ r)}])
    r, J = problem.residual_and_jacobian(x)
    cost = float(r @ r)
    history = [{"iter": 0, "rms_mm": float(np.sqrt(cost / max(len(r) // 3, 1))), "lambda": None}]
    if not np.isfinite(cost):
        return SolverResult(x, False, "non-finite residuals at the start", 0, history)
    mu = None
    nu = 2.0
    reason, converged = f"stopped after {max_iter} iterations without converging", False
    it = 0
    for it in range(1, max_iter + 1):
        # the equilibrated normal matrix (J D⁻¹)ᵀ(J D⁻¹), D the column norms, from JᵀJ
        # (no scaled copy of J)
        JtJ = J.T @ J
        d = np.sqrt(np.diag(JtJ))
        d[d == 0] = 1.0
        A = JtJ / np.outer(d, d)
        g = (J.T @ r) / d
        if np.max(np.abs(g)) < gtol * max(np.sqrt(cost), 1e-300):
            reason, converged = "gradient below tolerance", True
            break
        if mu is None:
            mu = lambda0 * float(np.max(np.diag(A)))
        while True:
            try:
                U = cholesky_upper(A + mu * np.eye(A.shape[0]))
                step_s = -cho_solve(U, g)
            except np.linalg.LinAlgError:
                mu *= nu
                nu *= 2
                continue
            step = step_s / d
            x_new = x + step
            # most steps are accepted: evaluate the Jacobian with the residual in one pass
            r_new, J_new = problem.residual_and_jacobian(x_new)
            cost_new = float(r_new @ r_new)
            predicted = float(step_s @ (mu * step_s - g))
            rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
            if np.isfinite(cost_new) and rho > 0:
                break
            if predicted <= ftol * cost or not np.isfinite(predicted):
                history.append({"iter": it, "rms_mm": float(np.sqrt(cost / (len(r) // 3)))})
                reason = "at the minimum: no step reduces the cost"
                return SolverResult(x, True, reason, it, history)
            mu *= nu
            nu *= 2
            if mu > 1e30:
                history.append({"iter": it, "rms_mm": float(np.sqrt(cost / (len(r) // 3)))})
                return SolverResult(x, False, "no step reduces the cost", it, history)
        small_step = np.linalg.norm(step_s) < xtol * (np.linalg.norm(d * x) + xtol)
        rel_drop = (cost - cost_new) / max(cost, 1e-300)
        x, r, J, cost = x_new, r_new, J_new, cost_new
        mu *= max(1 / 3, 1 - (2 * rho - 1) ** 3)
        nu = 2.0
        history.append(
            {"iter": it, "rms_mm": float(np.sqrt(cost / (len(r) // 3))), "lambda": float(mu)}
        )
        if small_step:
            reason, converged = "step below tolerance", True
            break
        if rel_drop < ftol:
            reason, converged = "cost change below tolerance", True
            break
    return SolverResult(x, converged, reason, it, history)
