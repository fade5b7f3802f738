"""The plain reference the speed benchmarks print beside each figure: a textbook
Levenberg-Marquardt in numpy on the same problem.

Same model, same analytic Jacobian (``ErrorModel.evaluate``), same start (each effect's
own, base and tool by the rigid fit) and the same free parameters; the damped step by
``np.linalg.lstsq`` on ``[J; sqrt(lambda) D] step = [r; 0]`` (D the column norms),
lambda divided by 10 after a step that lowers the cost and multiplied by 10 otherwise.
Nothing else: no identifiability analysis, covariance, validation or blunder test, no
reuse of an evaluation.
"""

from __future__ import annotations

import time

import numpy as np


def textbook_lm(em, data, free: np.ndarray, max_iter: int = 100, ftol: float = 1e-12):
    """Fit ``em`` to ``data`` over the parameters ``free`` (penalty rows of regularised
    effects included, as measurements of zero); returns (x, iterations, seconds)."""
    t0 = time.perf_counter()
    bound = em.bind(data)

    def linearise(x):
        P, J = em.evaluate(x, bound)
        r, A = (data.tracker_p_smr - P).ravel(), J[:, :, free].reshape(-1, int(free.sum()))
        pen = em.penalty(x)
        if pen is not None:
            r, A = np.concatenate([r, -pen[0]]), np.vstack([A, pen[1][:, free]])
        return r, A

    x = em.initial(bound)
    r, A = linearise(x)
    cost, lam, iterations = r @ r, 1e-3, 0
    while iterations < max_iter:
        iterations += 1
        D = np.sqrt(lam) * np.linalg.norm(A, axis=0)
        rhs = np.concatenate([r, np.zeros(D.size)])
        step = np.linalg.lstsq(np.vstack([A, np.diag(D)]), rhs, rcond=None)[0]
        x_new = x.copy()
        x_new[free] += step
        r_new, A_new = linearise(x_new)
        cost_new = r_new @ r_new
        if cost_new < cost:
            done = cost - cost_new <= ftol * cost
            x, r, A, cost, lam = x_new, r_new, A_new, cost_new, lam / 10
            if done:
                break
        else:
            lam *= 10
    return x, iterations, time.perf_counter() - t0
