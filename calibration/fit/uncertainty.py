"""Uncertainty of a fit: correlations, Monte-Carlo re-identification, position uncertainty.

- :func:`correlations` — the correlation matrix of the free parameters and its
  strongest pairs (from the analytic covariance of :func:`identify`).
- :func:`position_uncertainty` — the parameter covariance propagated to target
  positions at random poses within the joint limits: the 1-sigma 3-D position
  uncertainty ``sqrt(trace(J C J^T))`` per pose (mm), its mean and maximum.
- :func:`monte_carlo` — a parametric bootstrap: the calibrated model's predictions at
  the calibration poses plus fresh instrument noise, re-identified N times; the spread
  of the parameters is compared with the analytic standard uncertainties.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .identify import Fit, identify
from .simulate import random_joints

#: families whose parameters place the robot in the tracker frame, not the robot itself
FRAME_FAMILIES = ("base",)


def correlations(fit: Fit, k: int = 5) -> dict:
    """Correlation matrix of the free parameters and the ``k`` strongest pairs.

    Returns
    -------
    dict with ``names`` (m,), ``matrix`` (m, m) nested lists, ``strongest``: a list of
    ``{"a", "b", "r"}`` sorted by decreasing |r|
    """
    names = [n for n, f in zip(fit.names, fit.free, strict=True) if f]
    R = fit.correlation()
    pairs = fit.strongest_correlations(k) if len(names) > 1 else []
    return {
        "names": names,
        "matrix": np.round(R, 6).tolist(),
        "strongest": [{"a": a, "b": b, "r": r} for a, b, r in pairs],
    }


def position_uncertainty(
    fit: Fit,
    covariance: np.ndarray | None = None,
    n_poses: int = 1000,
    seed: int = 0,
    include_frame: bool = False,
) -> dict:
    """Propagate a parameter covariance to positions over the workspace.

    Parameters
    ----------
    fit : the calibrated model (its values set the linearisation point)
    covariance : (p, p) internal units; default ``fit.covariance``
    n_poses : random poses uniform within the joint limits
    seed : seed of the pose generator
    include_frame : also count the base (tracker-to-robot) parameters; by default the
        uncertainty is that of the robot in its own base frame

    Returns
    -------
    dict with ``per_pose_mm`` (n_poses,) 1-sigma 3-D uncertainty sqrt(trace(J C J^T)),
    ``mean_mm``, ``rms_mm``, ``max_mm``, ``n_poses``
    """
    from ..data.dataset import Dataset

    em = fit.error_model
    C = fit.covariance if covariance is None else np.asarray(covariance, float)
    if not include_frame:
        frame = np.array([em.effect_of(k).family in FRAME_FAMILIES for k in range(em.n_params)])
        C = C.copy()
        C[frame, :] = 0.0
        C[:, frame] = 0.0
    rng = np.random.default_rng(seed)
    q = random_joints(em.model, n_poses, rng)
    data = Dataset(q=q, tracker_p_smr=np.zeros((n_poses, 3)), source="workspace sample")
    _, J = em.evaluate(fit.values, em.bind(data), jacobian=True)
    # trace(J C J^T) per pose, without forming the 3x3 matrices' off-diagonals
    var = np.einsum("nip,pq,niq->n", J, C, J)
    u = np.sqrt(np.clip(var, 0.0, None))
    return {
        "per_pose_mm": u,
        "mean_mm": float(u.mean()),
        "rms_mm": float(np.sqrt(np.mean(u**2))),
        "max_mm": float(u.max()),
        "n_poses": int(n_poses),
    }


@dataclass
class MonteCarlo:
    """Result of :func:`monte_carlo`.

    Attributes
    ----------
    samples : (N, p) re-identified parameters, internal units
    std_mc : (p,) their standard deviation
    std_analytic : (p,) analytic standard uncertainty at the same sigma
    ratio : (p,) std_mc / std_analytic (nan for fixed parameters)
    sigma_mm : instrument noise per axis used for the perturbations
    n_failed : replicates whose solver did not converge (kept in the samples)
    position : :func:`position_uncertainty` of the analytic covariance
    position_mc : the same from the Monte-Carlo sample covariance
    """

    samples: np.ndarray
    std_mc: np.ndarray
    std_analytic: np.ndarray
    ratio: np.ndarray
    sigma_mm: float
    n_failed: int
    position: dict
    position_mc: dict

    def rows(self, fit: Fit) -> list[dict]:
        """Per free parameter: name, analytic and Monte-Carlo std (display units), ratio."""
        from ..effects import display_unit

        out = []
        for k, name in enumerate(fit.names):
            if not fit.free[k]:
                continue
            unit, f = display_unit(fit.error_model.units[k])
            out.append({"name": name, "unit": unit, "std_analytic": float(self.std_analytic[k] * f),
                        "std_mc": float(self.std_mc[k] * f), "ratio": float(self.ratio[k])})
        return out


def monte_carlo(
    fit: Fit,
    n: int = 100,
    sigma: float | None = None,
    seed: int = 0,
    solver: str | None = None,
    solver_options: dict | None = None,
    n_poses: int = 1000,
) -> MonteCarlo:
    """Re-identify ``n`` times from the calibrated model's predictions plus instrument noise.

    Parameters
    ----------
    fit : the calibration to assess
    n : number of replicates
    sigma : instrument noise per axis, mm; default the data's tracker sigma, else the
        fit's residual sigma
    seed : seed of the noise (replicates are reproducible)
    solver : solver for the replicates (default ``lm``: the spread of the estimator the
        analytic covariance describes; pass ``fit.solver`` to assess another one)
    solver_options : passed to :func:`identify`
    n_poses : random workspace poses for the position uncertainty

    Returns
    -------
    MonteCarlo
    """
    if n < 2:
        raise ValueError("monte_carlo needs n >= 2 replicates")
    s = sigma if sigma is not None else (fit.data.sigma() or fit.sigma_mm)
    rng = np.random.default_rng(seed)
    em = fit.error_model
    P = fit.predict(fit.data)
    fixed = list(fit.identifiability.fixed)
    samples = np.empty((n, em.n_params))
    failed = 0
    for i in range(n):
        data = replace(fit.data, tracker_p_smr=P + rng.normal(0.0, s, P.shape),
                       meta=dict(fit.data.meta))
        f = identify(em, data, solver or "lm", x0=fit.values, fixed=fixed,
                     solver_options=solver_options)
        samples[i] = f.values
        failed += not f.converged
    std_mc = samples.std(axis=0, ddof=1)
    scale = s / fit.sigma_mm if fit.sigma_mm > 0 else 1.0
    std_an = fit.std * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(fit.free & (std_an > 0), std_mc / std_an, np.nan)
    C_mc = np.cov(samples, rowvar=False)
    C_mc[~fit.free, :] = 0.0
    C_mc[:, ~fit.free] = 0.0
    return MonteCarlo(
        samples=samples,
        std_mc=std_mc,
        std_analytic=std_an,
        ratio=ratio,
        sigma_mm=float(s),
        n_failed=failed,
        position=position_uncertainty(fit, fit.covariance * scale**2, n_poses, seed),
        position_mc=position_uncertainty(fit, C_mc, n_poses, seed),
    )
