"""Diagnosis: where a fitted model fails, and which missing physical effect explains it.

:func:`diagnose` takes a :class:`~calibration.fit.identify.Fit` and ranks every candidate
effect that is not in the model (every family on every joint where it makes sense):

1. **Linear screening.** At the fitted parameters, each candidate's Jacobian columns are
   projected out of the span of the current model's free columns (what the current
   parameters could already absorb); the remaining residual's projection onto what is
   left is the error the candidate would explain. Joint effects act through dP/dq_j, so
   their columns cost one multiplication each; harmonics are scanned for orders
   K = 1 ... 60 on every joint (a periodogram of the residual against the joint angle).
2. **Significance.** An F-test of the explained against the remaining sum of squares
   (robust to other missing effects, which inflate the denominator), Bonferroni-corrected
   for the number of candidates screened (each harmonic order counts). When the
   instrument's noise is known and the residual is statistically at the noise floor
   (chi-square test), no candidate is significant.
3. **Confirmation.** The most convincing candidates are added and the model refitted
   (nonlinear), and judged on held-out poses (the validation rows when there are at
   least 100, else k-fold cross-validation): one that does not lower the held-out
   error only overfits and is not recommended.

Blunders first: the fit's blunders (:mod:`calibration.fit.outliers`; a fit that kept them is
screened and refitted without them) are left out of everything below and reported
(``Diagnosis.outliers``), and a candidate whose explained error sits in one or two points
(:func:`~calibration.fit.outliers.concentration`) is not significant: no effect is added to
explain a blunder.

"Where it fails" (:class:`WhereItFails`) gives per-pose errors and the worst poses, and
the residual seen from each joint (the joint correction that would explain it) against
the joint angle, capture order, temperature and gravity torque.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..effects import Effect, EffectError, parse_effect
from ..effects.physical import derive_directions
from ..fit.error_model import Bound, ErrorModel
from ..fit.identify import Fit, identify, screen_for_diagnosis
from ..fit.outliers import BlunderScreen, concentration, concentration_of
from ..model.gravity import gravity_torques, has_mass_model
from .candidate_columns import effect_columns, joint_partials
from .f_test import log10_f_sf

#: harmonic orders scanned on every joint
HARMONIC_ORDERS = range(1, 61)
#: drift orders (polynomial in time) screened when the data have times
DRIFT_ORDERS = (1, 2, 3)
#: significance level after the multiple-comparison correction
ALPHA = 0.01
#: fewer validation rows than this: confirm by k-fold cross-validation instead
MIN_HELDOUT = 100
#: a candidate whose two largest points carry more than this share of what it explains
#: explains points, not an effect
MAX_CONCENTRATION = 0.5


@dataclass
class Candidate:
    """One candidate effect and what it would do."""

    effect: str
    family: str
    joint: int | None
    order: int | None
    n_params: int
    explained_fraction: float
    rms_after_mm: float
    p_value: float
    log10_p: float
    p_adjusted: float
    significant: bool
    confirmed: bool | None = None
    refit_rms_mm: float | None = None
    heldout_before_mm: float | None = None
    heldout_after_mm: float | None = None
    note: str = ""
    #: BIC gain of adding it (larger is better), the ranking key
    score: float = 0.0

    def to_json(self) -> dict:
        out = {
            "effect": self.effect,
            "family": self.family,
            "joint": self.joint,
            "rms_after_mm": self.refit_rms_mm if self.refit_rms_mm else self.rms_after_mm,
            "explained_fraction": self.explained_fraction,
            "p_value": self.p_value,
            "significant": self.significant,
            "n_params": self.n_params,
            "log10_p": self.log10_p,
            "p_adjusted": self.p_adjusted,
            "rms_after_linear_mm": self.rms_after_mm,
            "confirmed": self.confirmed,
            "heldout_before_mm": self.heldout_before_mm,
            "heldout_after_mm": self.heldout_after_mm,
        }
        if self.family == "harmonic":
            out["order"] = self.order
        if self.note:
            out["note"] = self.note
        return out


@dataclass
class WhereItFails:
    """Where the fitted model fails, per pose and per joint.

    Attributes
    ----------
    error_mm : (n,) 3-D error per calibration pose
    worst : the worst poses as (pose_id, file line, error mm), worst first
    joint_residual_rad : (n, N) the correction of joint j that would explain each pose's
        residual on its own (least squares along dP/dq_j), rad
    q : (n, N) joint angles (rad); order : (n,) capture order; t_s, temp_c : (n,) or None
    torque_nm : (n, N) gravity torques, or None without a mass model
    correlations : name -> Spearman correlation of the error magnitude with that quantity
    periodogram : joint (1-based) -> (orders, explained fraction per order)
    """

    error_mm: np.ndarray
    worst: list[tuple[str, int, float]]
    joint_residual_rad: np.ndarray
    q: np.ndarray
    order: np.ndarray
    t_s: np.ndarray | None
    temp_c: np.ndarray | None
    torque_nm: np.ndarray | None
    correlations: dict[str, float] = field(default_factory=dict)
    periodogram: dict[int, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`."""

    fit: Fit
    rms_mm: float
    noise_floor_mm: float | None
    at_floor: bool
    floor_p_value: float | None
    candidates: list[Candidate]
    where: WhereItFails
    n_screened: int
    screen_s: float
    confirm_s: float
    notes: list[str] = field(default_factory=list)
    #: the blunder test: the points left out of the ranking
    outliers: BlunderScreen | None = None

    @property
    def best(self) -> Candidate | None:
        c = self.candidates[0] if self.candidates else None
        return c if c is not None and c.significant else None

    def next_effects(self) -> str:
        """The ``--effects`` to use next (the current ones plus the best candidate)."""
        labels = list(self.fit.error_model.labels)
        if self.best is not None:
            labels.append(self.best.effect)
        return ",".join(labels)

    def recommendation(self) -> str:
        """The diagnosis in words."""
        floor = self.noise_floor_mm
        if self.at_floor:
            return (f"The model sits at the instrument's noise floor (RMS {self.rms_mm:.4f} mm "
                    f"vs {floor:.4f} mm): no missing effect is supported by the data.")
        b = self.best
        if b is None:
            tail = f" (noise floor {floor:.4f} mm)" if floor else ""
            return (f"No candidate effect explains the remaining error significantly "
                    f"(RMS {self.rms_mm:.4f} mm{tail}); the cause may be outside the "
                    "candidate families (e.g. a wrong nominal model or non-repeatable motion).")
        after = b.refit_rms_mm or b.rms_after_mm
        return (f"{describe_effect(b)} explains {100 * b.explained_fraction:.0f} % of the "
                f"remaining error; adding it should bring the RMS on the calibration poses "
                f"from {self.rms_mm:.3f} to {after:.3f} mm"
                + (f" (noise floor {floor:.3f} mm)." if floor else "."))

    def to_json(self) -> dict:
        """The ``diagnose --json`` object (docs/formats.md §4), extended."""
        em = self.fit.error_model
        return {
            "model": em.model.name,
            "effects": em.labels,
            "rms_mm": self.rms_mm,
            "noise_floor_mm": self.noise_floor_mm,
            "at_noise_floor": self.at_floor,
            "candidates": [c.to_json() for c in self.candidates],
            "recommendation": self.recommendation(),
            "next_effects": self.next_effects(),
            "n_screened": self.n_screened,
            "worst_poses": [
                {"pose_id": p, "line": int(line), "error_mm": e} for p, line, e in self.where.worst
            ],
            "correlations": self.where.correlations,
            "screen_s": self.screen_s,
            "confirm_s": self.confirm_s,
            "outliers": self.outliers.to_json() if self.outliers else [],
            **({"outlier_check": self.outliers.check_json("ranking")} if self.outliers
               else {}),
        }


def describe_effect(c: Candidate) -> str:
    """The effect in words: "Compliance of joint 3", "A 12-per-turn periodic error of joint 4"."""
    names = {
        "compliance": "compliance",
        "harmonic": (f"a {c.order}-per-turn periodic error" if c.order and c.order > 1
                     else "a once-per-turn periodic error"),
        "table": "an irregular angle-dependent error (correction table)",
        "scale": "an angle scale (gear ratio) error",
        "backlash": "backlash",
        "coupling": "coupling to the previous joint",
        "thermal": "thermal growth",
        "tracker_scale": "a tracker scale error",
        "thermal_growth": "thermal growth with the joint temperatures",
        "thermal_zero": "a zero drift with temperature",
        "base_drift": "a drift of the base over time",
        "time_growth": "thermal growth over time",
    }
    what = names.get(c.family, f"effect {c.effect}")
    if c.joint:
        what = f"{what} of joint {c.joint}"
    return what[0].upper() + what[1:]


# ---- candidates -------------------------------------------------------------------
def candidate_names(error_model: ErrorModel, data: Dataset) -> list[str]:
    """Every candidate effect (not already in the model) that these data can test."""
    model = error_model.model
    have = set(error_model.labels)
    out = []
    for j in range(1, model.n_joints + 1):
        if has_mass_model(model):
            out.append(f"compliance:{j}")
        out += [f"harmonic{k}:{j}" if k > 1 else f"harmonic:{j}" for k in HARMONIC_ORDERS]
        out += [f"table:{j}", f"scale:{j}", f"backlash:{j}"]
        if j >= 2:
            out.append(f"coupling:{j}")
    if data.temp_c is not None and np.ptp(data.temp_c) > 0:
        out.append("thermal")
    out.append("tracker_scale")
    out += drift_candidates(error_model, data)
    return [c for c in out if c not in have]


def drift_candidates(error_model: ErrorModel, data: Dataset) -> list[str]:
    """The drift effects these data can test: ``thermal_growth`` and ``thermal_zero:J``
    where the joint temperatures change, ``time_growth`` and ``base_drift`` orders where the
    time does (a growth only when no other effect acts at the length stage)."""
    out = []
    free_length = not any(e.stage == "length" for e in error_model.effects)
    if data.joint_temp is not None and np.ptp(data.joint_temp) > 0:
        if free_length:
            out.append("thermal_growth")
        out += [f"thermal_zero:{j + 1}" for j in range(data.n_joints)
                if np.ptp(data.joint_temp[:, j]) > 0]
    if data.t_s is not None and np.ptp(data.t_s) > 0:
        for family in ("time_growth", "base_drift"):
            if family == "base_drift" or free_length:
                out += [f"{family}{k}" if k > 1 else family for k in DRIFT_ORDERS]
    return out


def diagnose(
    fit: Fit,
    data: Dataset | None = None,
    *,
    candidates: list[str] | None = None,
    confirm: int = 3,
    folds: int = 5,
    alpha: float = ALPHA,
    seed: int = 0,
) -> Diagnosis:
    """Rank the candidate effects missing from ``fit``'s model.

    Parameters
    ----------
    fit : the current model's fit
    data : the whole data set the fit came from (calibration and validation rows, in
        capture order); used for derived columns and the held-out check. Default: the
        fit's own calibration (and validation) rows.
    candidates : effect names to screen (default :func:`candidate_names`)
    confirm : how many of the best candidates to refit and check on held-out data
    folds : k for cross-validation when there are no validation rows
    alpha : significance level after the multiple-comparison correction
    """
    import scipy.special  # here: scipy's import is half of `cellcal calibrate`'s start-up

    t0 = time.perf_counter()
    if data is None:
        data = fit.data if fit.valid_data is None else fit.data.concat(fit.valid_data)
    if data.dirs is None:  # approach directions from capture order, for backlash candidates
        data = replace(data, dirs=derive_directions(data.q),
                       meta={**data.meta, "dirs_derived": "consecutive rows in capture order"})
    fit = screen_for_diagnosis(fit)
    if fit.outliers is not None and fit.outliers.excluded:  # set by the screening
        data = data.subset(~np.isin(data.pose_id, fit.outliers.ids))
    em = fit.error_model
    calib = data.calib() if data.is_valid.any() else data
    if calib.n != fit.data.n:
        calib = fit.data
    bound = em.bind(calib)
    x = fit.values
    P, J, G = em.evaluate(x, bound, jacobian=True, joints=True)
    r = (calib.tracker_p_smr - P).ravel()
    n = calib.n
    free = fit.free
    Jf = J[:, :, free].reshape(3 * n, -1)
    Q = np.linalg.qr(Jf)[0] if Jf.shape[1] else np.zeros((3 * n, 0))
    r = r - Q @ (Q.T @ r)  # the fit's residual is already orthogonal; make it exact
    rss0 = float(r @ r)
    m = int(free.sum())
    dof0 = 3 * n - m
    rms = math.sqrt(rss0 / n)

    names = candidate_names(em, data) if candidates is None else list(candidates)
    effects: list[Effect] = []
    notes: list[str] = []
    for name in names:
        try:
            effects.append(parse_effect(name, em.model))
        except EffectError as e:
            notes.append(f"{name}: skipped ({e})")
    n_screened = len(effects)

    # screen: every candidate's explained sum of squares
    screened = _screen(effects, calib, bound, G, em, x, Q, r, notes)

    # significance (F-test, Bonferroni over everything screened)
    sigma = calib.sigma() if fit.data.sigma() is None else fit.data.sigma()
    floor = None if sigma is None else math.sqrt(3.0) * sigma
    floor_p = None
    at_floor = False
    if sigma is not None:
        floor_p = float(scipy.special.chdtrc(max(dof0, 1), rss0 / sigma**2))  # chi2.sf
        at_floor = floor_p > alpha
    M = max(len(screened), 1)
    cands: list[Candidate] = []
    for eff, k, d_rss, note in screened:
        rss1 = max(rss0 - d_rss, 1e-300)
        logp = 0.0 if k == 0 else log10_f_sf(d_rss, rss1, k, max(dof0 - k, 1))
        p = 10.0**logp
        # BIC gain: explained error against the parameters it costs (ranks a 2-parameter
        # harmonic above a 37-knot table that explains the same)
        score = 3 * n * math.log(rss0 / rss1) - k * math.log(3 * n) if k else -math.inf
        p_adj = min(1.0, p * M)
        cands.append(Candidate(
            effect=eff.label, family=eff.family, joint=eff.joint,
            order=getattr(eff, "order", None) if eff.family == "harmonic" else None,
            n_params=k, explained_fraction=d_rss / rss0 if rss0 > 0 else 0.0,
            rms_after_mm=math.sqrt(rss1 / n), p_value=p, log10_p=logp, p_adjusted=p_adj,
            significant=(not at_floor) and k > 0 and (logp + math.log10(M) < math.log10(alpha))
            and not note,
            note=note, score=score,
        ))

    # one harmonic per joint in the table: the best order (the periodogram keeps them all)
    seen: dict[int, tuple[list[int | None], list[float]]] = {}
    best_harmonic: dict[int, Candidate] = {}
    for c in cands:
        if c.family == "harmonic" and c.joint is not None:  # a harmonic has its joint
            orders, frac = seen.get(c.joint, ([], []))
            seen[c.joint] = ([*orders, c.order], [*frac, c.explained_fraction])
            if c.joint not in best_harmonic or c.score > best_harmonic[c.joint].score:
                best_harmonic[c.joint] = c
    periodogram = {j: (np.array(o), np.array(f)) for j, (o, f) in seen.items()}
    cands = [c for c in cands if c.family != "harmonic"
             or (c.joint is not None and best_harmonic.get(c.joint) is c)]
    # a table only when no single harmonic does the job (parsimony): the p-value ranks
    cands.sort(key=lambda c: (not c.significant, -c.score))
    screen_s = time.perf_counter() - t0

    # confirm the best few with a refit and a held-out check
    t1 = time.perf_counter()
    n_confirmed = 0
    before: dict[int, float] = {}  # the current model's k-fold errors, shared
    for c in [c for c in cands if c.significant][: 2 * confirm]:
        if n_confirmed >= confirm:
            c.note = f"significant, not refitted (only the best {confirm} are)"
            continue
        _confirm(c, fit, data, folds, seed, before)
        if c.confirmed:
            n_confirmed += 1
        else:
            c.significant = False
            c.note = "does not lower the held-out error: it only fits noise"
    # confirmed candidates first, ordered by their held-out error (the figure to trust);
    # then the other significant ones by BIC gain, then the rest
    cands.sort(key=lambda c: (not c.significant, not c.confirmed,
                              c.heldout_after_mm if c.confirmed else -c.score))
    confirm_s = time.perf_counter() - t1

    where = where_it_fails(fit, calib, G, r.reshape(n, 3), periodogram)
    if "dirs_derived" in data.meta and fit.data.dirs is None:
        notes.append("backlash candidates: approach directions derived from consecutive rows "
                     "in capture order (the data have no dir columns)")
    return Diagnosis(fit, rms, floor, at_floor, floor_p, cands, where, n_screened, screen_s,
                     confirm_s, notes, fit.outliers)


#: a joint candidate is judged from per-pose products (never forming its 3n x k columns)
#: when every projected column keeps more than this share of its squared norm (no
#: cancellation) and their Gram matrix is better conditioned than :data:`_GRAM_RCOND`;
#: else from its columns, projected, by their SVD
_KEPT_SHARE = 1e-6
_GRAM_RCOND = 1e-4


def _screen(effects: list[Effect], calib: Dataset, bound: Bound, G: np.ndarray,
            em: ErrorModel, x: np.ndarray, Q: np.ndarray, r: np.ndarray, notes: list[str]
            ) -> list[tuple]:
    """Every candidate's (effect, columns kept, explained sum of squares, note): its
    columns projected out of the span of Q (the current model's), the residual ``r``
    projected on what is left.

    A joint effect's columns are ``C_i = g_i p_iᵀ`` (g_i = dP_i/dq_J, p_i its partials at
    pose i), so QᵀC, CᵀC and Cᵀr come from per-pose products: ``U_i = Q_iᵀ g_i``,
    ``|g_i|²``, ``g_i·r_i`` (once per joint), at O(n k) per candidate instead of O(3n m k).
    """
    n, m = calib.n, Q.shape[1]
    Q3 = Q.reshape(n, 3, m)
    Rq = np.einsum("nim,ni->nm", Q3, r.reshape(n, 3))  # Q_iᵀ r_i
    Qtr = Rq.sum(axis=0)
    per_joint: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    out: list[tuple] = []
    for eff in effects:
        try:
            if eff.stage == "joint" and eff.family != "table":
                partials = joint_partials(eff, calib, bound)
                assert eff.joint is not None  # a joint effect
                j = eff.joint - 1
                if j not in per_joint:
                    g = G[:, :, j]
                    per_joint[j] = (np.einsum("nim,ni->nm", Q3, g), np.sum(g * g, axis=1),
                                    np.sum(g * r.reshape(n, 3), axis=1))
                res = _explained_joint(eff, partials, *per_joint[j], Rq, Qtr, n)
                if res is not None:
                    out.append(res)
                    continue
            C = effect_columns(eff, calib, bound, G, em, x).reshape(3 * n, -1)
        except EffectError as e:
            notes.append(f"{eff.label}: skipped ({e})")
            continue
        if eff.family == "table":
            C = C[:, np.abs(C).sum(axis=0) > 0]  # knots without data
        out.append(_explained(eff, C, Q, r, n))
    return out


def _explained_joint(eff: Effect, Pj: np.ndarray, U: np.ndarray, gg: np.ndarray,
                     gr: np.ndarray, Rq: np.ndarray, Qtr: np.ndarray, n: int
                     ) -> tuple | None:
    """:func:`_explained` of a joint effect with partials ``Pj`` (n, k) from per-pose
    products (see :func:`_screen`); None when they cannot decide it to rounding (a column
    almost absorbed, or nearly dependent ones): then its columns are formed."""
    Y = U.T @ Pj  # QᵀC (m, k)
    CtC = Pj.T @ (gg[:, None] * Pj)
    gram = CtC - Y.T @ Y  # CpᵀCp
    col2 = np.diag(CtC)
    kept2 = np.diag(gram)
    if not (kept2 > _KEPT_SHARE * col2).all():
        return None
    norms = np.sqrt(kept2)
    keep = norms > 1e-9 * max(math.sqrt(float(col2.sum())), 1e-300)
    if not keep.any():
        return eff, 0, 0.0, "no effect beyond what the model already absorbs"
    d = 1.0 / norms[keep]
    gram = gram[np.ix_(keep, keep)] * np.outer(d, d)
    w = np.linalg.eigvalsh(gram)
    if not w[0] > _GRAM_RCOND * w[-1]:
        return None
    b = (Pj[:, keep].T @ gr - Y[:, keep].T @ Qtr) * d  # Cpᵀ r, columns normalised
    coef = np.linalg.solve(gram, b)
    z = coef * d  # the fitted correction Cp z: per pose r_i·(g_i p_iᵀz - Q_i Y z)
    c = gr * (Pj[:, keep] @ z) - Rq @ (Y[:, keep] @ z)
    conc = concentration_of(c)
    note = (f"two points carry {100 * conc:.0f} % of what it explains: it fits points, "
            "not an effect" if conc > MAX_CONCENTRATION else "")
    return eff, int(keep.sum()), float(b @ coef), note


def _explained(eff: Effect, C: np.ndarray, Q: np.ndarray, r: np.ndarray, n: int) -> tuple:
    """(effect, rank, explained sum of squares, note) of one candidate with columns ``C``
    (3n, k): projected out of the span of ``Q``, the residual on what is left."""
    Cp = C - Q @ (Q.T @ C)
    norms = np.linalg.norm(Cp, axis=0)
    keep = norms > 1e-9 * max(float(np.linalg.norm(C)), 1e-300)
    if not keep.any():
        return eff, 0, 0.0, "no effect beyond what the model already absorbs"
    Cp = Cp[:, keep] / norms[keep]
    U, s, _ = np.linalg.svd(Cp, full_matrices=False)
    U = U[:, s > 1e-6 * s[0]]
    proj = U.T @ r
    conc = concentration(r, U @ proj, n)
    note = (f"two points carry {100 * conc:.0f} % of what it explains: it fits points, "
            "not an effect" if conc > MAX_CONCENTRATION else "")
    return eff, U.shape[1], float(proj @ proj), note


def _confirm(c: Candidate, fit: Fit, data: Dataset, folds: int, seed: int,
             before: dict | None = None) -> None:
    """Refit with the candidate; judge it on held-out poses."""
    em = fit.error_model
    ext = em.with_effects(c.effect)
    effects: list[Any] = ext.effects  # tables have a ``smoothing``
    for e in effects:
        if getattr(e, "smoothing", 0.0) is None:
            e.smoothing = 1.0  # screening only: the final fit chooses it by cross-validation
    refit = identify(ext, data, fit.solver)
    c.refit_rms_mm = refit.calib["rms_mm"]
    if fit.valid is not None and refit.valid is not None and fit.valid["n"] >= MIN_HELDOUT:
        c.heldout_before_mm = fit.valid["rms_mm"]
        c.heldout_after_mm = refit.valid["rms_mm"]
    else:
        calib = data.calib() if data.is_valid.any() else data
        fold_of = np.random.default_rng(seed).permutation(calib.n) % folds
        sq = np.zeros(2)
        before = {} if before is None else before  # the current model's folds: fitted once
        for f in range(folds):
            train, test = calib.subset(fold_of != f), calib.subset(fold_of == f)
            for i, model in enumerate((em, ext)):
                if i == 0 and f in before:
                    sq[i] += before[f]
                    continue
                ft = identify(model, train, fit.solver)
                err = float(np.sum((test.tracker_p_smr - ft.predict(test)) ** 2))
                sq[i] += err
                if i == 0:
                    before[f] = err
        c.heldout_before_mm, c.heldout_after_mm = np.sqrt(sq / calib.n)
    # a real effect lowers the held-out error by more than estimation noise does
    c.confirmed = bool(c.heldout_after_mm < c.heldout_before_mm * 0.995)


def where_it_fails(fit: Fit, calib: Dataset, G: np.ndarray, resid: np.ndarray,
                   periodogram: dict[int, tuple[np.ndarray, np.ndarray]]) -> WhereItFails:
    """Per-pose errors, worst poses, and the residual seen from every joint."""
    err = np.linalg.norm(resid, axis=1)
    worst_idx = np.argsort(-err)[:5]
    worst = [(calib.pose_id[i], int(calib.lines[i]), float(err[i])) for i in worst_idx]
    g2 = np.einsum("nij,nij->nj", G, G)
    jr = np.einsum("nij,ni->nj", G, resid) / np.where(g2 > 1e-12, g2, np.inf)
    torque = None
    if has_mass_model(fit.error_model.model):
        torque = gravity_torques(fit.error_model.model, fit.error_model.bind(calib).nominal,
                                 calib.payload_kg)
    import scipy.stats  # here: loading it costs a third of a second at every command's start

    corr = {}
    order = np.arange(calib.n)
    series = {"capture order": order, "time": calib.t_s, "temperature": calib.temp_c}
    if torque is not None:
        for j in range(torque.shape[1]):
            series[f"torque j{j + 1}"] = np.abs(torque[:, j])
    for name, v in series.items():
        if v is not None and np.ptp(v) > 0 and calib.n > 3:
            corr[name] = float(scipy.stats.spearmanr(err, v)[0])
    return WhereItFails(err, worst, jr, calib.q, order, calib.t_s, calib.temp_c, torque, corr,
                        periodogram)
