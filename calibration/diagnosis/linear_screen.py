"""A fit linearised (:class:`Linearised`) and candidate effects judged against it without a
refit (:func:`evaluate_candidates`, :class:`Screened`).

Near a fit the pose errors are linear in the parameters to well within the noise, so the
refit with a candidate added is a linear least-squares update. Let X (3n × m) be the fit's
free Jacobian columns and P its penalty rows (correction tables), A = XᵀX + PᵀP = L Lᵀ and
W = X L⁻ᵀ, so the fit's hat matrix is H₀ = W Wᵀ. A candidate with columns C (3n × k) and
penalty s Ω (a table; none otherwise) gives, with V = (I - H₀) C:

    M = Cᵀ V + s Ω,    c = M⁻¹ Cᵀ r,    e = r - V c,    H = H₀ + V M⁻¹ Vᵀ

(r the fit's residual, c the candidate's parameters, e the new residual; the current
parameters move by -A⁻¹ XᵀC c). From these, per candidate and without a refit:

- the explained sum of squares and an F-test against the remaining one;
- the leave-one-pose-out residuals e₋ᵢ = (I₃ - Hᵢᵢ)⁻¹ eᵢ (exact for a linear smoother;
  Hᵢᵢ the 3 × 3 block of pose i): the held-out gain per pose against the fit's own
  leave-one-out error, its mean and standard error;
- on validation poses (if given) the predicted residual rᵥ - (Cᵥ - Wᵥ WᵀC) c.

Candidates with the same number of columns are evaluated together: one product per
candidate, not one per pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..effects import Effect
from ..fit.error_model import Bound
from ..fit.identify import Fit
from ..fit.leverage import solve3
from .f_test import log10_f_sf


@dataclass
class Linearised:
    """A fit, linearised: what every candidate is judged against (see the module docstring).

    Attributes
    ----------
    r : (n, 3) residuals of the calibration poses, mm; ``W`` (3n, m); ``h0`` (n, 3, 3)
    trace0 : tr H₀ (degrees of freedom of the fit)
    loo0 : (n,) squared leave-one-out error of every pose, mm²
    G : (n, 3, N) dP/dq_j at the fit (what a joint correction acts through)
    P : (n, 3) the fit's predictions (what a measure-stage effect acts on)
    rv, Wv, Gv, Pv : the same for the validation poses (None without them)
    """

    fit: Fit
    calib: Dataset
    bound: Bound
    r: np.ndarray
    W: np.ndarray
    h0: np.ndarray
    trace0: float
    loo0: np.ndarray
    G: np.ndarray
    P: np.ndarray | None = None
    valid: Dataset | None = None
    bound_v: Bound | None = None
    rv: np.ndarray | None = None
    Wv: np.ndarray | None = None
    Gv: np.ndarray | None = None
    Pv: np.ndarray | None = None
    #: Wᵀ W (m, m), made when a table is first screened (not I when the fit has penalty
    #: rows)
    WtW: np.ndarray | None = None

    @property
    def n(self) -> int:
        return self.calib.n

    @property
    def rss0(self) -> float:
        return float(np.sum(self.r**2))

    @property
    def dof0(self) -> float:
        return 3 * self.n - self.trace0


def linearise(fit: Fit, calib: Dataset, valid: Dataset | None = None) -> Linearised:
    """Linearise ``fit`` on its calibration poses ``calib`` (and validation poses)."""
    import scipy.linalg  # here: scipy's import is half of `cellcal calibrate`'s start-up

    em, x, free = fit.error_model, fit.values, fit.free
    bound = em.bind(calib)
    P, J, G = em.evaluate(x, bound, jacobian=True, joints=True)
    n, m = calib.n, int(free.sum())
    X = J[:, :, free].reshape(3 * n, m)
    pen = em.penalty(x)
    A = X.T @ X
    if pen is not None:
        Pf = pen[1][:, free]
        A = A + Pf.T @ Pf
    d = np.sqrt(np.maximum(np.diag(A), 1e-300))
    L = cholesky_nudged(A / np.outer(d, d))
    W = scipy.linalg.solve_triangular(L, (X / d).T, lower=True, check_finite=False).T
    W3 = W.reshape(n, 3, m)
    h0 = np.einsum("nim,njm->nij", W3, W3)
    r = calib.tracker_p_smr - P
    # The formulas above hold at the least-squares optimum on *these* rows (Xᵀr = Pᵀ p, the
    # penalty's pull). When the fit left out rows that ``calib`` keeps (blunders a later,
    # more flexible fit excluded: they may be a local effect still to be found), it is not:
    # re-centre on the current model refitted to these rows (one linear step δ₀). Else a
    # candidate direction the model already spans (a table's constant part is the joint's
    # offset: V = 0 there) gets Cᵀr ≠ 0 over a zero pivot, and its result is rounding noise.
    g = (X / d).T @ r.ravel()
    if pen is not None:
        g = g - (Pf / d).T @ pen[0]
    u = scipy.linalg.solve_triangular(L, g, lower=True, check_finite=False)  # X δ₀ = W u
    r = r - (W @ u).reshape(n, 3)
    loo0 = np.sum(_loo(h0, r) ** 2, axis=-1)
    lin = Linearised(fit, calib, bound, r, W, h0, float(np.sum(W * W)), loo0, G, P)
    if valid is not None and valid.n:
        bound_v = em.bind(valid)
        Pv, Jv, Gv = em.evaluate(x, bound_v, jacobian=True, joints=True)
        Xv = Jv[:, :, free].reshape(3 * valid.n, m)
        lin.Wv = scipy.linalg.solve_triangular(L, (Xv / d).T, lower=True,
                                               check_finite=False).T
        rv = valid.tracker_p_smr - Pv - (lin.Wv @ u).reshape(valid.n, 3)
        lin.valid, lin.bound_v, lin.rv, lin.Gv, lin.Pv = valid, bound_v, rv, Gv, Pv
    return lin


def cholesky_nudged(A: np.ndarray, overwrite: bool = False) -> np.ndarray:
    """Lower Cholesky factor of a symmetric positive (semi-)definite matrix, nudged
    (``A + ε I``, ε from 1e-12 up by a hundred until it factors); ``overwrite``: A may be
    used as the work array (its diagonal then holds the nudge)."""
    eps = 1e-12
    B = A if overwrite else A.copy()
    diag = np.diagonal(A).copy()
    step = B.shape[0] + 1
    while True:
        B.flat[::step] = diag + eps  # A + eps I: the diagonal alone changes
        try:
            return np.linalg.cholesky(B)
        except np.linalg.LinAlgError:
            eps *= 100


def _loo(H: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Leave-one-pose-out residuals (I - H_ii)⁻¹ e_i for blocks H (..., 3, 3), e (..., 3)."""
    return solve3(np.eye(3) - H + 1e-12 * np.eye(3), e)


@dataclass
class Screened:
    """One candidate effect, screened at a fit (linear; no refit).

    Attributes
    ----------
    effect : the effect object (for a table: with its knots and smoothing)
    n_params : its parameters; ``edf`` the degrees of freedom it adds (tables: fewer)
    d_rss : explained sum of squares on the calibration poses, mm²
    rms_after_mm : calibration RMS after adding it
    log10_p : log10 of the F-test's p-value (explained against remaining)
    loo_gain, loo_gain_se : mean drop of the squared leave-one-out error per pose (mm²)
        and its standard error; ``loo_rms_after_mm`` the leave-one-out RMS after
    valid_rms_after_mm : predicted validation RMS after (None without validation poses)
    """

    effect: Effect
    n_params: int
    edf: float
    d_rss: float
    rms_after_mm: float
    log10_p: float
    loo_gain: float
    loo_gain_se: float
    loo_rms_after_mm: float
    valid_rms_after_mm: float | None = None
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return self.effect.label

    @property
    def loo_z(self) -> float:
        return self.loo_gain / self.loo_gain_se if self.loo_gain_se > 0 else 0.0


def evaluate_candidates(lin: Linearised, C: np.ndarray, Cv: np.ndarray | None,
              omega: np.ndarray | None = None, s: float = 0.0, heldout: bool = True) -> dict:
    """Evaluate candidates C (n, 3, M, k) together; penalty s Ω (k, k) for all of them.
    Without ``heldout``, the leave-one-out and validation figures are NaN (not computed)."""
    n, _, M, k = C.shape
    r = lin.r.ravel()
    Cf = C.reshape(3 * n, M * k)
    WtC = lin.W.T @ Cf
    V = Cf - lin.W @ WtC
    # columns the fit already absorbs: nothing beyond it (zero them, c = 0 there)
    absorbed = np.linalg.norm(V, axis=0) <= 1e-7 * np.maximum(np.linalg.norm(Cf, axis=0),
                                                               1e-300)
    V[:, absorbed] = 0.0
    C3 = Cf.reshape(3 * n, M, k).transpose(1, 0, 2)  # (M, 3n, k)
    V3 = V.reshape(3 * n, M, k).transpose(1, 0, 2)
    CtV = C3.transpose(0, 2, 1) @ V3
    CtV = 0.5 * (CtV + CtV.transpose(0, 2, 1))
    VtV = V3.transpose(0, 2, 1) @ V3
    Mm = CtV + (0.0 if omega is None else s * omega)
    scale = np.trace(Mm, axis1=1, axis2=2) / k
    scale = np.where(scale > 1e-200, scale, 1e10)  # nothing beyond the model: c = 0
    Mm = Mm + 1e-10 * scale[:, None, None] * np.eye(k)
    Minv = np.linalg.inv(Mm)
    Ctr = (C3.transpose(0, 2, 1) @ r)  # (M, k)
    Ctr[absorbed.reshape(M, k)] = 0.0
    c = (Minv @ Ctr[:, :, None])[:, :, 0]
    e = r[:, None] - (V3 @ c[:, :, None])[:, :, 0].T  # (3n, M)
    edf = np.sum(Minv * VtV.transpose(0, 2, 1), axis=(1, 2))
    rss = np.sum(e**2, axis=0)
    d_rss = np.maximum(lin.rss0 - rss, 0.0)
    ok = (edf >= 0.5) & (d_rss > 0)
    logp = np.zeros(M)
    if ok.any():
        logp[ok] = log10_f_sf(d_rss[ok], np.maximum(rss[ok], 1e-300), edf[ok],
                              np.maximum(lin.dof0 - edf[ok], 1.0))
    nan = np.full(M, np.nan)
    out = {"logp": logp, "rss": rss, "edf": edf, "loo_gain": nan, "loo_gain_se": nan,
           "loo_rms": nan, "valid_rms": nan}
    if not heldout:
        return out
    V4 = V3.reshape(M, n, 3, k)
    Y = (V3 @ Minv).reshape(M, n, 3, k)  # one product per candidate, not one per pose
    dH = Y @ V4.transpose(0, 1, 3, 2)  # (M, n, 3, 3)
    e3 = e.T.reshape(M, n, 3)
    loo = np.sum(_loo(lin.h0[None] + dH, e3) ** 2, axis=-1).T  # (n, M)
    gain = lin.loo0[:, None] - loo
    out["loo_gain"] = gain.mean(axis=0)
    out["loo_gain_se"] = gain.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros(M)
    out["loo_rms"] = np.sqrt(loo.mean(axis=0))
    if Cv is not None and lin.rv is not None and lin.Wv is not None:  # validation rows
        nv = Cv.shape[0]
        Cvf = Cv.reshape(3 * nv, M, k)
        WtCc = np.einsum("jak,ak->ja", WtC.reshape(-1, M, k), c)  # Wᵀ C c, (m, M)
        dv = np.einsum("iak,ak->ia", Cvf, c) - lin.Wv @ WtCc
        ev = lin.rv.ravel()[:, None] - dv
        out["valid_rms"] = np.sqrt(np.sum(ev**2, axis=0) / nv)
    return out


def as_screened(lin: Linearised, eff: Effect, res: dict[str, Any], note: str = "",
                **extra: Any) -> Screened:
    rss1 = max(float(res["rss"]), 1e-300)
    d_rss = max(lin.rss0 - rss1, 0.0)
    k_eff = float(res["edf"])
    logp = float(res["logp"])
    if k_eff < 0.5 or d_rss <= 0:
        note = note or "no effect beyond what the model already absorbs"
    vr = float(res["valid_rms"])
    return Screened(
        effect=eff, n_params=eff.n_params, edf=k_eff, d_rss=d_rss,
        rms_after_mm=math.sqrt(rss1 / lin.n), log10_p=logp,
        loo_gain=float(res["loo_gain"]), loo_gain_se=float(res["loo_gain_se"]),
        loo_rms_after_mm=float(res["loo_rms"]),
        valid_rms_after_mm=None if not np.isfinite(vr) else vr, note=note, extra=extra,
    )
