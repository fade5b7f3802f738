"""Linear screening of candidate effects at a fit: what each would explain, and how much it
would lower the error on poses it was not fitted to.

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

Columns of joint effects cost one multiplication each (dP/dq_J times the effect's partials);
candidates with the same number of columns are evaluated in batches. A table's knot spacing
and smoothing are chosen per joint by GCV on this linear problem
(:func:`~calibration.effects.table.penalised_path`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.special

from .dataset import Dataset
from .effects import Effect, EffectError
from .effects.physical import Harmonic
from .effects.table import SMOOTHING_GRID, Table, penalised_path
from .error_model import Bound, ErrorModel
from .identify import Fit
from .leverage import solve3

#: knot spacings (degrees) a table candidate is tried at; GCV picks one per joint
TABLE_SPACINGS_DEG = (10, 5, 3, 2)
#: a finer table spacing is chosen only when its GCV is lower than a coarser one's by more
#: than this (relative): the GCV of the 2 000-pose benchmark's tables moves by up to 1e-9
#: between BLAS kernels (Haswell, SkylakeX, Sandybridge), while its genuine differences
#: between spacings are 1e-7 and more; a tie within rounding goes to the coarser table
#: (fewer parameters), the same on every machine
GCV_TIE_RTOL = 1e-8
#: candidates evaluated together (memory: 3n x batch x k doubles per array)
_BATCH = 64


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
    L = _cholesky(A / np.outer(d, d))
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


def _cholesky(A: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor of a symmetric positive (semi-)definite matrix, nudged."""
    eps = 1e-12
    while True:
        try:
            return np.linalg.cholesky(A + eps * np.eye(A.shape[0]))
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


def effect_columns(effect: Effect, data: Dataset, bound: Bound, G: np.ndarray, em: ErrorModel,
                   x: np.ndarray, P: np.ndarray | None = None) -> np.ndarray:
    """A candidate's Jacobian columns at the fit ``x`` of ``em``, (n, 3, k). ``P``: the
    fit's predictions on ``data`` when the caller has them (a measure-stage effect, the
    last to act, takes its columns from them instead of a new pass along the chain)."""
    if effect.stage == "joint":
        partials = _joint_partials(effect, data, bound)
        return G[:, :, effect.joint - 1, None] * partials[:, None, :]
    if effect.stage == "measure" and P is not None:
        return effect.measure(np.zeros(effect.n_params), P)[2]
    # other stages: evaluate the extended model once
    ext = ErrorModel(em.model, em.effects + [effect])
    xe = np.concatenate([x, np.zeros(effect.n_params)])
    _, J = ext.evaluate(xe, ext.bind(data))
    return J[:, :, em.n_params :]


def _harmonic_columns(lin: Linearised, effects: list[Harmonic]) -> dict:
    """The columns of many harmonic candidates at once, ``{id(effect): (C, Cv)}``: per
    joint, the sines and cosines of every order in one call each (what
    :func:`effect_columns` gives one effect at a time: ``Harmonic.bind``'s ``K θ``)."""
    out: dict[int, tuple] = {}
    by_joint: dict[int, list[Harmonic]] = {}
    for e in effects:
        by_joint.setdefault(e.joint, []).append(e)
    sets = [(lin.calib, lin.G)] + ([] if lin.valid is None else [(lin.valid, lin.Gv)])
    for j, group in by_joint.items():
        orders = np.array([float(e.order) for e in group])
        cols = []
        for data, G in sets:
            k_theta = data.q[:, j - 1, None] * orders  # (n, K)
            basis = np.stack([np.sin(k_theta), np.cos(k_theta)], axis=-1)  # (n, K, 2)
            cols.append(G[:, :, j - 1, None, None] * basis[:, None])  # (n, 3, K, 2)
        for a, e in enumerate(group):
            out[id(e)] = (cols[0][:, :, a], cols[1][:, :, a] if len(cols) > 1 else None)
    return out


def _joint_partials(effect: Effect, data: Dataset, bound: Bound) -> np.ndarray:
    """d(joint correction)/d(parameters) of a joint effect on ``data``, (n, k)."""
    state = effect.bind(data, bound.nominal)
    return effect.delta(np.zeros(effect.n_params), data, state)[1]


def screen(lin: Linearised, effects: list[Effect], *, notes: list[str] | None = None,
           table_spacings=TABLE_SPACINGS_DEG, heldout_alpha: float | None = None
           ) -> list[Screened]:
    """Screen ``effects`` (not in the fit's model) at the linearised fit.

    A ``Table`` in ``effects`` stands for "a table on that joint": it is replaced by the
    table whose knots span the data's angles at the spacing (among ``table_spacings``) and
    smoothing GCV prefers. Effects the data cannot test are left out with a note.

    ``heldout_alpha``: the leave-one-out and validation figures (most of the work: a 3 x 3
    block per pose and candidate) only for candidates significant at this level
    (F-test, Bonferroni-corrected over every candidate screened), NaN for the others;
    what ``diagnose --auto`` ranks (it ranks only significant candidates). None: for all.
    """
    notes = [] if notes is None else notes
    fit = lin.fit
    em, x = fit.error_model, fit.values
    out: list[Screened] = []
    groups: dict[int, list[tuple[Effect, np.ndarray, np.ndarray | None]]] = {}
    periodic = _harmonic_columns(lin, [e for e in effects if type(e) is Harmonic])
    for eff in effects:
        try:
            if isinstance(eff, Table):
                s = _screen_table(lin, eff.joint, table_spacings)
                if s is not None:
                    out.append(s)
                continue
            if id(eff) in periodic:
                C, Cv = periodic[id(eff)]
            else:
                C = effect_columns(eff, lin.calib, lin.bound, lin.G, em, x, lin.P)
                Cv = (None if lin.valid is None else
                      effect_columns(eff, lin.valid, lin.bound_v, lin.Gv, em, x, lin.Pv))
        except EffectError as e:
            notes.append(f"{eff.label}: skipped ({e})")
            continue
        groups.setdefault(eff.n_params, []).append((eff, C, Cv))
    waiting = []  # (index in out, effect, C, Cv): held-out figures still to compute
    for items in groups.values():
        _evaluate_all(lin, items, out, heldout=heldout_alpha is None, waiting=waiting)
    if heldout_alpha is not None and waiting:
        bar = math.log10(heldout_alpha) - math.log10(max(len(out), 1))
        chosen = [w for w in waiting if out[w[0]].edf >= 0.5 and out[w[0]].log10_p < bar]
        by_k: dict[int, list] = {}
        for w in chosen:
            by_k.setdefault(w[1].n_params, []).append(w)
        for ws in by_k.values():
            done: list[Screened] = []
            _evaluate_all(lin, [w[1:] for w in ws], done)
            for w, s in zip(ws, done, strict=True):
                out[w[0]] = s
    return out


def _evaluate_all(lin: Linearised, items: list, out: list[Screened], heldout: bool = True,
                  waiting: list | None = None) -> None:
    """Evaluate candidates ``items`` [(effect, C, Cv)] with the same number of columns in
    batches of :data:`_BATCH`, appending their :class:`Screened` to ``out`` (and, without
    the ``heldout`` figures, ``(index, effect, C, Cv)`` to ``waiting``)."""
    for i in range(0, len(items), _BATCH):
        batch = items[i : i + _BATCH]
        C = np.stack([c for _, c, _ in batch], axis=2)
        Cv = None if lin.valid is None else np.stack([c for _, _, c in batch], axis=2)
        res = _evaluate(lin, C, Cv, heldout=heldout)
        for a, (eff, c, cv) in enumerate(batch):
            out.append(_screened(lin, eff, {k: v[a] for k, v in res.items()}))
            if not heldout and waiting is not None:
                waiting.append((len(out) - 1, eff, c, cv))


def _evaluate(lin: Linearised, C: np.ndarray, Cv: np.ndarray | None,
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
    if Cv is not None:
        nv = Cv.shape[0]
        Cvf = Cv.reshape(3 * nv, M, k)
        WtCc = np.einsum("jak,ak->ja", WtC.reshape(-1, M, k), c)  # Wᵀ C c, (m, M)
        dv = np.einsum("iak,ak->ia", Cvf, c) - lin.Wv @ WtCc
        ev = lin.rv.ravel()[:, None] - dv
        out["valid_rms"] = np.sqrt(np.sum(ev**2, axis=0) / nv)
    return out


def _screened(lin: Linearised, eff: Effect, res: dict, note: str = "", **extra) -> Screened:
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


def data_gap_deg(theta_rad: np.ndarray, trim: float = 1.0) -> float:
    """The widest gap (degrees) between consecutive angles in the middle of the data (the
    ``trim`` % at either end left out): a table's knots are no closer than this, so that no
    stretch between knots is left to the smoothness penalty alone (a table cannot predict
    across a gap in the data; a formula can)."""
    t = np.sort(np.degrees(np.asarray(theta_rad, float)))
    if t.size < 3:
        return float("inf")
    lo, hi = np.percentile(t, [trim, 100 - trim])
    mid = t[(t >= lo) & (t <= hi)]
    return float(np.diff(mid).max()) if mid.size > 1 else float("inf")


def _screen_table(lin: Linearised, joint: int, spacings) -> Screened | None:
    """The best table on ``joint``: knots over the data's angles, spacing (no finer than the
    data's widest gap, :func:`data_gap_deg`; a finer one only when its GCV is lower by more
    than :data:`GCV_TIE_RTOL`) and smoothing by GCV on the linearised problem."""
    fit = lin.fit
    em = fit.error_model
    theta = lin.calib.q[:, joint - 1]
    if lin.valid is not None:
        theta = np.concatenate([theta, lin.valid.q[:, joint - 1]])
    n = lin.n
    best = None
    curves = {}
    finest = data_gap_deg(lin.calib.q[:, joint - 1])
    products = None
    usable = [sp for sp in spacings if sp >= finest] or [max(spacings)]
    for spacing in usable:
        if np.ptp(np.degrees(theta)) < 2 * spacing:
            continue
        table = Table.covering(em.model, joint, theta, spacing)
        B = _joint_partials(table, lin.calib, lin.bound)
        if products is None:
            products = _joint_products(lin, joint)
        VtV, Ctr, Vtr = _table_normal(products, B)
        path = penalised_path(VtV, Ctr, Vtr, VtV, lin.rss0, table.penalty_matrix(),
                              SMOOTHING_GRID, 3 * n, lin.trace0)
        g = float(path["gcv"][path["best"]])
        curves[spacing] = [(float(s), float(np.sqrt(3 * v))) for s, v in
                           zip(path["grid"], path["gcv"], strict=True)]
        if best is None or g < best[0] * (1.0 - GCV_TIE_RTOL):
            best = (g, table, B, float(path["grid"][path["best"]]))
    if best is None:
        return None
    _, table, B, s = best
    C = lin.G[:, :, joint - 1, None] * B[:, None, :]  # effect_columns of a joint effect
    table.smoothing = s
    table.cv_curve = curves[int(table.spacing_deg)]
    Cv = (None if lin.valid is None else
          effect_columns(table, lin.valid, lin.bound_v, lin.Gv, em, fit.values)[:, :, None])
    res = _evaluate(lin, C[:, :, None], Cv, table.penalty_matrix(), s)
    return _screened(lin, table, {k: v[0] for k, v in res.items()},
                     gcv_by_spacing={sp: min(v for _, v in cv) for sp, cv in curves.items()})


def _joint_products(lin: Linearised, joint: int) -> tuple:
    """What every table on ``joint`` shares (a table's columns are ``C_i = g_i b_iᵀ``, g_i
    = dP_i/dq_joint, b_i its basis at pose i): U = (W_iᵀ g_i) (m, n), |g_i|² and g_iᵀ r_i
    (n,), Wᵀ r (m,) and Wᵀ W (m, m)."""
    n = lin.n
    g = lin.G[:, :, joint - 1]
    U = np.einsum("nim,ni->mn", lin.W.reshape(n, 3, -1), g)
    if lin.WtW is None:
        lin.WtW = lin.W.T @ lin.W
    return U, np.sum(g * g, axis=1), np.sum(g * lin.r, axis=1), lin.W.T @ lin.r.ravel(), \
        lin.WtW


def _table_normal(products: tuple, B: np.ndarray) -> tuple:
    """VᵀV, Cᵀr and Vᵀr of a table with basis B (n, k) from :func:`_joint_products`,
    without forming C or V = C - W WᵀC (3n x k each): with Y = WᵀC = U B,
    ``VᵀV = CᵀC - 2 YᵀY + Yᵀ (WᵀW) Y`` and ``CᵀC = Bᵀ diag(|g_i|²) B`` (n rows, not 3n),
    ``Vᵀr = Cᵀr - Yᵀ Wᵀr``. A third of the work; the same numbers to rounding."""
    U, gg, gr, Wr, WtW = products
    Y = U @ B
    VtV = B.T @ (gg[:, None] * B) - 2.0 * (Y.T @ Y) + Y.T @ (WtW @ Y)
    VtV = 0.5 * (VtV + VtV.T)
    Ctr = B.T @ gr
    return VtV, Ctr, Ctr - Y.T @ Wr


def kfold_errors(fit: Fit, folds: int = 10, seed: int = 0) -> np.ndarray:
    """Squared 3-D error (mm²) of every calibration pose when predicted by the fit refitted
    without its fold (``folds`` folds, poses assigned at random with ``seed``), on the
    problem linearised at the fit (penalties included), shape (n,)."""
    em, x, free = fit.error_model, fit.values, fit.free
    calib = fit.data
    n, m = calib.n, int(free.sum())
    P, J = em.evaluate(x, em.bind(calib), jacobian=True)
    X = J[:, :, free].reshape(n, 3, m)
    r = calib.tracker_p_smr - P
    A = np.einsum("nim,nik->mk", X, X)
    b = np.einsum("nim,ni->m", X, r)
    pen = em.penalty(x)
    if pen is not None:
        Pf = pen[1][:, free]
        A = A + Pf.T @ Pf
        b = b - Pf.T @ pen[0]
    fold_of = np.random.default_rng(seed).permutation(n) % max(2, min(folds, n))
    sq = np.zeros(n)
    for f in np.unique(fold_of):
        te = fold_of == f
        Xt, rt = X[te].reshape(-1, m), r[te].ravel()
        Af, bf = A - Xt.T @ Xt, b - Xt.T @ rt
        d = np.sqrt(np.maximum(np.diag(Af), 1e-300))
        L = _cholesky(Af / np.outer(d, d))
        delta = scipy.linalg.cho_solve((L, True), bf / d, check_finite=False) / d
        sq[te] = np.sum((rt - Xt @ delta).reshape(-1, 3) ** 2, axis=1)
    return sq


def log10_f_sf(d_rss, rss1, k, dof):
    """log10 of the F-test's p-value (explained ``d_rss`` with ``k`` degrees of freedom
    against the remaining ``rss1`` with ``dof``), with an asymptotic tail where scipy
    underflows; scalars or arrays."""
    d_rss, rss1, k, dof = np.broadcast_arrays(*(np.asarray(v, float)
                                                for v in (d_rss, rss1, k, dof)))
    F = (d_rss / k) / (rss1 / dof)
    lp = _f_logsf(F, k, dof)
    bad = ~np.isfinite(lp)
    if bad.any():
        # large dof: k F ~ chi2(k); log Q(a, x) ~ (a - 1) ln x - x - lgamma(a) for large x
        a, xx = k[bad] / 2.0, k[bad] * F[bad] / 2.0
        lp[bad] = (a - 1) * np.log(xx) - xx - scipy.special.gammaln(a)
    out = lp / math.log(10)
    return float(out) if out.ndim == 0 else out


def _f_logsf(F: np.ndarray, k: np.ndarray, dof: np.ndarray) -> np.ndarray:
    """``scipy.stats.f.logsf(F, k, dof)`` as scipy computes it (log of the upper tail above
    the median, log1p of minus the lower one below), from ``scipy.special``: scipy.stats
    takes a third of a second to import."""
    above = scipy.special.fdtri(k, dof, 0.5) < F
    with np.errstate(divide="ignore"):
        return np.where(above, np.log(scipy.special.fdtrc(k, dof, F)),
                        np.log1p(-scipy.special.fdtr(k, dof, F)))
