"""Identification: :func:`identify` fits an error model to measured poses and returns a
:class:`Fit` — parameters with standard uncertainties, residuals per pose, statistics on
calibration and validation rows, identifiability and the solver's history."""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..effects import display_unit
from ..numerics.blas import blas_threads
from ..numerics.heap import keep_freed_memory
from ..numerics.linalg import cholesky_upper, triangular_inverse
from . import full_pose
from .error_model import Bound, ErrorModel
from .identifiability import Identifiability, analyse, penalised_groups
from .outliers import MODES as OUTLIER_MODES
from .outliers import BlunderScreen, screen_fit
from .solvers import SOLVERS, Problem

#: a free parameter correlated at least this much with another is weakly identified
WEAK_CORRELATION = 0.999


def error_stats(residuals: np.ndarray) -> dict:
    """Statistics of 3-D error magnitudes: n, rms, mean, max, 95th percentile (mm)."""
    e = np.linalg.norm(np.atleast_2d(residuals), axis=1) if len(residuals) else np.zeros(0)
    if e.size == 0:
        return {"n": 0, "rms_mm": None, "mean_mm": None, "max_mm": None, "p95_mm": None}
    return {
        "n": int(e.size),
        "rms_mm": float(np.sqrt(np.mean(e**2))),
        "mean_mm": float(e.mean()),
        "max_mm": float(e.max()),
        "p95_mm": float(np.percentile(e, 95)),
    }


@dataclass
class Fit:
    """The result of :func:`identify`.

    Attributes
    ----------
    error_model : the model that was fitted
    values : (p,) parameters, internal units (mm, rad, ...)
    std : (p,) standard uncertainties (0 for fixed parameters)
    covariance : (p, p) covariance (zero rows/columns for fixed parameters)
    identifiability : which parameters were free, and why the others were fixed
    residuals : (n, 3) measured minus predicted on the calibration rows, mm
    calib, valid : error statistics (see :func:`error_stats`); ``valid`` None without rows
    sigma_mm : residual standard deviation per axis after the fit
    converged, reason, iterations, history, solver, solve_s : how the solver did
    info : solver-specific extras (robust weights, ridge parameter...)
    outliers : the blunder test (:class:`~calibration.fit.outliers.BlunderScreen`): the points
        left out of ``data`` (or only named), None when not tested
    hat_factor : (m, m) M with ``covariance / sigma_mm**2 = M Mᵀ`` over the free
        parameters (from the covariance's factorisation): a point's hat-matrix block is
        ``Q_i Q_iᵀ`` with ``Q_i = J_i M`` (the blunder test's leverage)
    jacobian : (n, 3, p) the Jacobian at ``values`` on the calibration rows, kept for the
        blunder test while :func:`identify` runs (None after it, unless asked to keep it)
    orientation_residuals, valid_orientation_residuals : (n, 3) rad, the rotation vectors
        of measured times predicted-transposed orientations on calibration and validation
        rows, when the data have orientations (else None); ``orientation_fitted`` says
        whether the fit used them (full pose) or only predicts them (position only,
        :mod:`calibration.fit.full_pose`)
    """

    error_model: ErrorModel
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    identifiability: Identifiability
    data: Dataset
    residuals: np.ndarray
    calib: dict
    valid_data: Dataset | None = None
    valid_residuals: np.ndarray | None = None
    valid: dict | None = None
    sigma_mm: float = float("nan")
    solver: str = "lm"
    converged: bool = True
    reason: str = ""
    iterations: int = 0
    history: list[dict] = field(default_factory=list)
    solve_s: float = 0.0
    info: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    outliers: BlunderScreen | None = None
    hat_factor: np.ndarray | None = field(default=None, repr=False)
    jacobian: np.ndarray | None = field(default=None, repr=False)
    #: (XᵀX, XᵀX + PᵀP) over the free parameters at ``values`` (X the Jacobian's free
    #: columns, P the penalty's rows), kept with ``jacobian`` when asked
    normal: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    #: the structural identifiability of the model on every calibration row (the start
    #: at the nominal geometry and its analysis, :func:`structural_identifiability`),
    #: kept with ``jacobian`` when asked: a refit of the same model to the same data
    #: (``identify(structure=...)``) need not make it again
    structure: tuple[np.ndarray, Identifiability] | None = field(default=None, repr=False)
    orientation_residuals: np.ndarray | None = field(default=None, repr=False)
    valid_orientation_residuals: np.ndarray | None = field(default=None, repr=False)
    orientation_fitted: bool | None = None

    # ---- access --------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        return self.error_model.names

    @property
    def free(self) -> np.ndarray:
        return self.identifiability.free

    @property
    def noise_floor_mm(self) -> float | None:
        return self.data.noise_floor_mm()

    def param(self, name: str) -> tuple[float, float]:
        """(value, standard uncertainty) of one parameter, internal units."""
        k = self.error_model.index(name)
        return float(self.values[k]), float(self.std[k])

    def predict(self, data: Dataset) -> np.ndarray:
        """Predicted target centres (tracker frame, mm) for other poses, shape (n, 3)."""
        return self.error_model.evaluate(self.values, self.error_model.bind(data), False)[0]

    def correlation(self) -> np.ndarray:
        """Correlation matrix of the free parameters, (m, m)."""
        f = self.free
        C = self.covariance[np.ix_(f, f)]
        s = np.sqrt(np.diag(C))
        s[s == 0] = 1.0
        return C / np.outer(s, s)

    def strongest_correlations(self, k: int = 5) -> list[tuple[str, str, float]]:
        """The k most correlated pairs of free parameters."""
        R = self.correlation()
        names = [n for n, f in zip(self.names, self.free, strict=True) if f]
        iu = np.triu_indices(len(names), 1)
        vals = R[iu]
        order = np.argsort(-np.abs(vals))[:k]
        return [(names[iu[0][i]], names[iu[1][i]], float(vals[i])) for i in order]

    def weakly_identified(self, r_max: float = WEAK_CORRELATION) -> dict[str, str]:
        """Free parameters the data hardly determine, with the reason: a standard
        uncertainty as large as the value (the data cannot tell it from zero), or a
        correlation |r| >= ``r_max`` with another parameter (the data cannot tell the
        two apart)."""
        names = [n for n, f in zip(self.names, self.free, strict=True) if f]
        idx = np.flatnonzero(self.free)
        out: dict[str, str] = {}
        if not names:
            return out
        R = np.abs(self.correlation())
        np.fill_diagonal(R, 0.0)
        for i, k in enumerate(idx):
            why = []
            if not self.std[k] < abs(self.values[k]):
                why.append("std >= |value|")
            j = int(np.argmax(R[i])) if len(names) > 1 else -1
            if j >= 0 and R[i, j] >= r_max:
                why.append(f"|r| = {R[i, j]:.4f} with {names[j]}")
            if why:
                out[names[i]] = "; ".join(why)
        return out

    def parameter_rows(self) -> list[dict]:
        """One dict per parameter in display units (deg for angles), for files and tables;
        ``weak`` says why an identifiable parameter is only weakly determined (else None)."""
        weak = self.weakly_identified()
        rows = []
        for k, name in enumerate(self.names):
            unit, f = display_unit(self.error_model.units[k])
            rows.append(
                {
                    "name": name,
                    "value": float(self.values[k] * f),
                    "std": float(self.std[k] * f) if self.free[k] else None,
                    "unit": unit,
                    "identifiable": bool(self.free[k]),
                    "weak": weak.get(name),
                }
            )
        return rows


def covariance(J: np.ndarray, r: np.ndarray, free: np.ndarray, sigma: float | None = None,
               penalty: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, float]:
    """Parameter covariance from the final Jacobian (n, 3, p) and residuals (n, 3).

    Uses ``sigma`` (mm per axis) when given, else the residual variance
    RSS / (3 n - m). Penalty rows (regularised effects) join the normal matrix, so the
    covariance is that of the regularised estimate. Returns (covariance (p, p), sigma).
    """
    cov, s, _ = covariance_and_factor(J, r, free, sigma, penalty)
    return cov, s


def normal_matrix(J: np.ndarray, free: np.ndarray,
                  penalty: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(XᵀX, XᵀX + PᵀP) over the free parameters: X the free columns of the Jacobian
    J (n, 3, p) as rows (3 n, m), P the penalty rows' (the held-out folds' normal
    equations, :class:`calibration.diagnosis.screening._LinearProblem`, the same numbers)."""
    n, m = J.shape[0], int(free.sum())
    X = J[:, :, free].reshape(n, 3, m).reshape(-1, m)
    XtX = X.T @ X
    if penalty is None:
        return XtX, XtX
    Pf = penalty[1][:, free]
    return XtX, XtX + Pf.T @ Pf


def covariance_and_factor(J: np.ndarray, r: np.ndarray, free: np.ndarray,
                          sigma: float | None = None,
                          penalty: tuple[np.ndarray, np.ndarray] | None = None,
                          normal: np.ndarray | None = None
                          ) -> tuple[np.ndarray, float, np.ndarray]:
    """:func:`covariance`, and M (m, m) with ``M Mᵀ`` the free block of the covariance over
    sigma², from the same factorisation (see :attr:`Fit.hat_factor`). ``normal``: the
    normal matrix over the free parameters, penalty included (:func:`normal_matrix`),
    when the caller has it (the same covariance to rounding)."""
    p = J.shape[-1]
    m = int(free.sum())
    dof = max(J.shape[0] * J.shape[1] - m, 1)
    s2 = sigma**2 if sigma is not None else float(np.sum(r**2)) / dof
    cov = np.zeros((p, p))
    M = np.zeros((m, m))
    if m and normal is not None:
        d = np.sqrt(np.diag(normal))
        d[d == 0] = 1.0
        A = normal / np.outer(d, d)
    elif m:
        Jf = J[:, :, free].reshape(-1, m)
        if penalty is not None:
            Jf = np.vstack([Jf, penalty[1][:, free]])
        d = np.linalg.norm(Jf, axis=0)
        d[d == 0] = 1.0
        Jd = Jf / d
        A = Jd.T @ Jd  # one operand twice: a symmetric rank-k update
    if m:
        try:
            U = cholesky_upper(A)
            # A = Uᵀ U, so A⁻¹ = U⁻¹ U⁻ᵀ: one triangular inverse for both
            Ui = triangular_inverse(U)
            inv = Ui @ Ui.T
            M = Ui / d[:, None]
        except np.linalg.LinAlgError:
            inv = np.linalg.pinv(A)
            w, V = np.linalg.eigh(0.5 * (inv + inv.T))
            M = V * np.sqrt(np.clip(w, 0.0, None)) / d[:, None]
        cov[np.ix_(free, free)] = s2 * inv / np.outer(d, d)
    return cov, float(np.sqrt(s2)), M


def structural_identifiability(error_model: ErrorModel, calib: Dataset, rtol: float = 1e-3
                               ) -> tuple[Bound, np.ndarray, Identifiability]:
    """Which parameters the calibration poses ``calib`` (prepared) determine.

    Returns the bound data, the start parameters at the nominal geometry and the
    identifiability analysis there (pinned parameters of the effects fixed too).
    Identifiability is structural: judged at the nominal geometry, where exact
    redundancies (parallel axes) are exact, not at a warm start that blurs them.
    """
    bound, x_nominal, ident, _ = _structural(error_model, calib, rtol)
    return bound, x_nominal, ident


def _structural(error_model: ErrorModel, calib: Dataset, rtol: float) -> tuple[
        Bound, np.ndarray, Identifiability, tuple[np.ndarray, np.ndarray]]:
    """:func:`structural_identifiability`, and the evaluation at the nominal geometry
    ``(P, J)`` it made (the solver's first when it starts there)."""
    bound: Bound = error_model.bind(calib)
    x_nominal = error_model.initial(bound)
    P0, J0 = error_model.evaluate(x_nominal, bound, jacobian=True)
    families = [e.family for e, sl in zip(error_model.effects, error_model.slices, strict=True)
                for _ in range(sl.start, sl.stop)]
    J2 = J0.reshape(-1, error_model.n_params)
    rows = full_pose.structural_rows(error_model, bound, x_nominal)
    if rows is not None:  # a full-pose problem: what orientations determine too
        J2 = np.vstack([J2, rows])
    groups = penalised_groups(error_model)
    ident = analyse(
        J2,
        error_model.names,
        np.asarray(error_model.scales),
        families,
        rtol=rtol,
        n_poses=calib.n,
        penalised=groups,
        # the normal matrix (one p x p product) instead of a QR of the 3n x p J; with
        # penalised groups only while the free columns are well conditioned (else the
        # QR: their columns need not be of full rank, see analyse)
        normal=J2.T @ J2,
    )
    for e, st in zip(error_model.effects, bound.states, strict=True):
        for local, why in e.pinned(st).items():
            name = f"{e.prefix}.{local}"
            k = error_model.index(name)
            ident.free[k] = False
            ident.fixed[name] = why
    return bound, x_nominal, ident, (P0, J0)


def identify(
    error_model: ErrorModel,
    data: Dataset,
    solver: str = "lm",
    *,
    valid: Dataset | None = None,
    x0: np.ndarray | None = None,
    rtol: float = 1e-3,
    fixed: list[str] | None = None,
    solver_options: dict[str, Any] | None = None,
    outliers: str = "exclude",
    keep_jacobian: bool = False,
    structure: tuple[np.ndarray, Identifiability] | None = None,
) -> Fit:
    """Identify the parameters of ``error_model`` from ``data``.

    A small problem runs on one BLAS thread (:func:`calibration.numerics.blas.blas_threads`), so
    ``solve_s`` does not depend on what else the machine runs; the heap keeps freed
    memory for the next temporaries (:func:`calibration.numerics.heap.keep_freed_memory`).

    Parameters
    ----------
    data : measured poses; rows with ``set=valid`` are held out for validation
    solver : a name in :data:`calibration.fit.solvers.SOLVERS` (``lm`` by default)
    valid : validation poses (in addition to the ``set=valid`` rows)
    x0 : starting parameters (default: each effect's start, base by a rigid fit)
    rtol : relative pivot below which a parameter is unidentifiable (practically: an SMR
        0.03 mm off the flange axis must not make the wrist's redundancies "identifiable")
    fixed : parameter names to hold at their start value in any case
    solver_options : keyword arguments for the solver
    outliers : ``exclude`` (default): calibration points far out of line with the rest
        (blunders) are left out and the model refitted until the set settles; ``flag``:
        every point is fitted, the blunders only named; ``keep``: no test (see
        :mod:`calibration.fit.outliers`). The result's ``outliers`` says what was found.
    keep_jacobian : keep the solver's last Jacobian as the result's ``jacobian`` (for a
        caller that linearises the fit next, e.g. its held-out folds; it then drops it),
        with the normal matrix and the structural analysis (``normal``, ``structure``)
    structure : the ``structure`` of a fit of this model to these data: the structural
        identifiability is not analysed again (it depends on neither the start nor a
        table's smoothing)

    Non-convergence is reported in the result (``converged``, ``reason``), not raised.
    """
    if solver not in SOLVERS:
        raise ValueError(f"unknown solver {solver!r}; available: {', '.join(SOLVERS)}")
    if outliers not in OUTLIER_MODES:
        raise ValueError(f"outliers must be one of {', '.join(OUTLIER_MODES)}, not {outliers!r}")
    keep_freed_memory()
    with blas_threads(3 * data.n * error_model.n_params):
        fit = _identify(error_model, data, solver, valid, x0, rtol, fixed, solver_options,
                        outliers, keep_jacobian, structure)
    if not keep_jacobian and outliers != "keep":  # kept for the blunder test's refits
        fit.jacobian = None
    if not keep_jacobian:
        fit.normal = fit.structure = None
    return fit


def _identify(error_model: ErrorModel, data: Dataset, solver: str, valid: Dataset | None,
              x0: np.ndarray | None, rtol: float, fixed: list[str] | None,
              solver_options: dict[str, Any] | None, outliers: str,
              keep_jacobian: bool = False,
              structure: tuple[np.ndarray, Identifiability] | None = None) -> Fit:
    """:func:`identify` (its arguments, positionally)."""
    t0 = time.perf_counter()
    data = error_model.prepare(data)
    if any(getattr(e, "smoothing", 0.0) is None for e in error_model.effects):
        # tables whose smoothing is to be chosen: by GCV at one fit (see choose_smoothing)
        from ..effects.table import choose_smoothing

        def fit_fn(em: ErrorModel, d: Dataset) -> Fit:
            return identify(em, d, solver, x0=x0, rtol=rtol, fixed=fixed,
                            solver_options=solver_options)

        choose_smoothing(error_model, data.calib() if data.is_valid.any() else data, fit_fn)
    calib = data.calib() if data.is_valid.any() else data
    held = data.valid() if data.is_valid.any() else None
    if valid is not None:
        held = valid if held is None else held.concat(valid)
    if calib.n == 0:
        raise ValueError(f"{data.source}: no calibration rows")
    at_nominal = None
    if structure is not None:  # the same model's on the same rows (see identify)
        bound = error_model.bind(calib)
        x_nominal, ident = structure[0].copy(), copy.deepcopy(structure[1])
    else:
        bound, x_nominal, ident, at_nominal = _structural(error_model, calib, rtol)
    if keep_jacobian:
        structure = (x_nominal.copy(), copy.deepcopy(ident))
    x_start = x_nominal if x0 is None else np.asarray(x0, float).copy()
    for name in fixed or []:
        k = error_model.index(name)
        if ident.free[k]:
            ident.free[k] = False
            ident.fixed[name] = "fixed by the user"
    problem = Problem(error_model, bound, x_start, ident.free.copy(),
                      pose=full_pose.orientation_rows(error_model, calib, solver))
    if at_nominal is not None:
        problem.remember(x_nominal, *at_nominal)
    result = full_pose.solve(problem, SOLVERS[solver], solver_options or {})
    x = problem.full(result.xf)
    P, J = problem.evaluate(x)  # the solver's last evaluation: no new pass
    resid = calib.tracker_p_smr - P
    weights = result.info.get("weights")
    r_w = resid if weights is None else resid * np.sqrt(weights)[:, None]
    J_w = J if weights is None else J * np.sqrt(weights)[:, None, None]
    r_w, J_w = full_pose.with_orientation_rows(problem, x, r_w, J_w)
    penalty = error_model.penalty(x)
    normal = None
    if keep_jacobian and J_w is J and ident.free.any():
        # the normal matrix the caller's linearisation forms (its folds), once for both
        normal = normal_matrix(J, ident.free, penalty)
    cov, sigma, hat = covariance_and_factor(J_w, r_w, ident.free, penalty=penalty,
                                            normal=None if normal is None else normal[1])
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    fit = Fit(
        error_model=error_model,
        values=x,
        std=std,
        covariance=cov,
        identifiability=ident,
        data=calib,
        residuals=resid,
        calib=error_stats(resid),
        sigma_mm=sigma,
        solver=solver,
        converged=result.converged,
        reason=result.reason,
        iterations=result.iterations,
        history=result.history,
        info=result.info,
        hat_factor=hat,
        jacobian=J,
        normal=normal,
    )
    for e, st in zip(error_model.effects, bound.states, strict=True):
        fit.notes.extend(e.describe(st))
    if held is not None and held.n:
        vres = held.tracker_p_smr - error_model.evaluate(x, error_model.bind(held), False)[0]
        fit.valid_data, fit.valid_residuals, fit.valid = held, vres, error_stats(vres)
    full_pose.attach_orientations(fit, problem)
    if outliers != "keep":
        def refit(rows: Dataset, x: np.ndarray) -> Fit:
            return identify(error_model, rows, solver, valid=held, x0=x, rtol=rtol,
                            fixed=fixed, solver_options=solver_options, outliers="keep",
                            keep_jacobian=keep_jacobian)

        fit = screen_fit(fit, outliers, refit)
    if keep_jacobian:
        fit.structure = structure
    fit.solve_s = time.perf_counter() - t0
    return fit


def fit_at(error_model: ErrorModel, data: Dataset, x: np.ndarray, **kw: Any) -> Fit:
    """A :class:`Fit` for given parameters without solving (residuals, statistics,
    identifiability and covariance at ``x``), e.g. for parameters read from params.json."""
    fit = identify(error_model, data, x0=x, solver_options={"max_iter": 0}, **kw)
    fit.converged, fit.reason, fit.iterations = True, "parameters given, not fitted", 0
    return fit


def screen_for_diagnosis(fit: Fit) -> Fit:
    """``fit`` without its blunders, for a diagnosis: a fit that left them out is used as
    it is; one that kept them (``--outliers keep``/``flag``, or parameters given) is
    screened and refitted without them (same solver, warm start). Returns the fit, whose
    ``outliers`` say what was left out."""
    if fit.outliers is not None and fit.outliers.mode == "exclude":
        return fit
    def refit(rows: Dataset, x: np.ndarray) -> Fit:
        return identify(fit.error_model, rows, fit.solver, valid=fit.valid_data, x0=x,
                        outliers="keep")

    return screen_fit(fit, "exclude", refit)
