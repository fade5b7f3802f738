"""Automatic diagnosis: add the best missing effect, refit, repeat while the held-out error
falls; stop by itself and say why.

Every step (see :func:`auto_diagnose`):

1. **Screen** every candidate effect at the current fit, linearised
   (:mod:`calibration.diagnosis.screening`): what it would explain (F-test, Bonferroni-corrected for
   the number screened) and how much it would lower the leave-one-pose-out error of the
   calibration poses. Tables are tried at several knot spacings over the angles the data
   cover, spacing and smoothing chosen by GCV.
2. **Rank** the significant candidates by that held-out gain (the F-test alone flags a
   dozen effects every round on a real robot, whose residuals are not white; held-out gain
   ranks what generalises) and **refit** the best few (one per family and joint),
   warm-started, with the table smoothing from the screening.
3. **Accept** the refit with the lowest held-out error (validation rows when there are at
   least :data:`~calibration.diagnosis.diagnosis.MIN_HELDOUT`, else k-fold cross-validation of the
   linearised fit on the calibration rows) only if it lowers the held-out mean squared
   error by more than its standard error (paired over the held-out poses), and does not
   raise the **range-blocked** error by more than its standard error; else stop.

Random folds and validation rows drawn from the same workspace sit inside the calibrated
ranges: they cannot see what a model does beyond them. The range-blocked folds
(:func:`~calibration.diagnosis.screening.blocked_errors`) leave out the tenth of the
poses at either end of each joint's range, refit without them (every table constant
beyond the knots the rest support, as it would be fitted) and predict them: an effect
that helps inside but hurts just beyond the data is not added. Both figures are shown.

It also stops when no candidate is significant (saying whether the residual sits at the
instrument's noise floor, by a chi-square test when the tracker's uncertainty is known), after
``max_steps`` steps or when ``budget_s`` seconds are spent. It never adds an effect that
does not lower the held-out error.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np

from ..data.dataset import Dataset
from ..effects import Effect, EffectError, parse_effect
from ..effects.physical import derive_directions
from ..effects.table import Table, gcv_smoothing
from ..fit.identify import Fit, identify
from ..model.robot_model import RobotModel
from .diagnosis import ALPHA, MIN_HELDOUT, candidate_names
from .screening import (
    Linearised,
    Screened,
    _LinearProblem,
    blocked_errors,
    kfold_with,
    linear_problem,
    linearise,
    screen,
)


@dataclass
class Heldout:
    """Held-out error of a fit: per pose squared 3-D error (mm²) and how it was measured;
    ``ids`` the poses (fits that left out other blunders are compared on the poses both
    kept)."""

    sq: np.ndarray
    method: str
    ids: np.ndarray | None = None
    #: the range-blocked folds' squared errors (mm²) and their labels (pose and fold), or
    #: None when not computed
    blocked: Heldout | None = None
    #: the fit linearised for the folds (its Jacobian's free columns: dropped once used)
    linear: _LinearProblem | None = field(default=None, repr=False)

    @property
    def rms_mm(self) -> float:
        return float(np.sqrt(self.sq.mean()))

    @property
    def blocked_rms_mm(self) -> float | None:
        """RMS of the range-blocked folds (mm), None without them."""
        b = self.blocked
        return None if b is None or not b.sq.size else b.rms_mm


@dataclass
class Tried:
    """A candidate refitted in a step: its screening and what the refit achieved."""

    screened: Screened
    fit: Fit
    heldout: Heldout
    gain: float
    gain_se: float
    #: the same over the range-blocked folds
    blocked_gain: float = 0.0
    blocked_gain_se: float = 0.0

    @property
    def effect(self) -> str:
        return self.screened.label

    @property
    def hurts_beyond(self) -> bool:
        """It raises the range-blocked error by more than its standard error."""
        return self.blocked_gain + self.blocked_gain_se < 0


@dataclass
class AutoStep:
    """One accepted step of the automatic diagnosis."""

    effect: str
    n_params: int
    calib_rms_mm: float
    heldout_rms_mm: float
    seconds: float
    explanation: str
    #: the range-blocked folds' RMS after this step (mm), None without them
    blocked_rms_mm: float | None = None
    #: held-out mean-squared-error drop (mm²) and its standard error
    gain: float = 0.0
    gain_se: float = 0.0
    #: every candidate refitted in this step (effect, held-out RMS mm)
    tried: list[tuple[str, float]] = field(default_factory=list)
    screen_s: float = 0.0
    refit_s: list[float] = field(default_factory=list)
    #: the fit after this step
    fit: Fit | None = field(default=None, repr=False)

    def to_json(self) -> dict:
        return {"effect": self.effect, "n_params": self.n_params,
                "calib_rms_mm": self.calib_rms_mm, "heldout_rms_mm": self.heldout_rms_mm,
                "range_blocked_rms_mm": self.blocked_rms_mm,
                "seconds": self.seconds, "explanation": self.explanation}


@dataclass
class AutoDiagnosis:
    """The result of :func:`auto_diagnose`: the steps taken, the final fit, why it stopped."""

    start: Fit
    fit: Fit
    start_heldout_rms_mm: float
    heldout_method: str
    steps: list[AutoStep]
    stop_reason: str
    noise_floor_mm: float | None
    total_s: float
    #: a step that was tried last and rejected: (effect, held-out RMS mm) per candidate
    rejected: list[tuple[str, float]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: the start model's range-blocked RMS (mm), None without range-blocked folds
    start_blocked_rms_mm: float | None = None

    @property
    def effects(self) -> list[str]:
        return list(self.fit.error_model.labels)

    def to_json(self, params_file: str | None = None) -> dict:
        """The ``diagnose --auto --json`` object (docs/formats.md §4)."""
        return {
            "model": self.start.error_model.model.name,
            "start_effects": list(self.start.error_model.labels),
            "steps": [s.to_json() for s in self.steps],
            "effects": self.effects,
            "stop_reason": self.stop_reason,
            "params_file": params_file,
            "outliers": self.outliers_json(),
        }

    def outliers_json(self) -> list[dict]:
        """The blunders left out before ranking (the starting fit's screen; a later refit
        that names more adds them), as in ``calibrate --json``."""
        seen, out = set(), []
        for f in (self.start, self.fit):
            screen = getattr(f, "outliers", None)
            for o in (screen.to_json() if screen else []):
                if o["pose_id"] not in seen:
                    seen.add(o["pose_id"])
                    out.append(o)
        return out


# ---- physics in one line ------------------------------------------------------------
_PER_TURN = {1: "once", 2: "twice"}


def explain_effect(effect: Effect | str, model: RobotModel | None = None) -> str:
    """One line of physics for an effect: what it is and where it typically comes from."""
    if isinstance(effect, str):
        if model is None:
            raise ValueError(f"explain_effect({effect!r}): an effect's name needs its model")
        effect = parse_effect(effect, model)
    j, fam = effect.joint, effect.family
    if fam == "harmonic":
        k = effect.order or 1
        if k == 1:
            return (f"a once-per-turn error of joint {j} — typical of an eccentric gear, "
                    "bearing or encoder disc")
        if k == 2:
            return (f"a twice-per-turn error of joint {j} — typical of an oval (elliptic) "
                    "part: a strain-wave gear's wave generator or a tilted encoder disc")
        return (f"a {k}-per-turn periodic error of joint {j} — typical of a strain-wave "
                "gear's tooth meshing or a cyclic error of the motor-side encoder")
    if fam == "table":
        table = cast(Table, effect)
        lo, hi = table.knots_deg[0], table.knots_deg[-1]
        return (f"an irregular error of joint {j} that follows its angle (knots every "
                f"{table.spacing_deg:g}° from {lo:g}° to {hi:g}°) — local gear or "
                "encoder defects no formula captures")
    texts = {
        "compliance": f"joint {j} yields in proportion to the gravity torque on it — the "
                      "elasticity of its gear and bearings under the arm's own weight",
        "scale": f"joint {j} turns a constant fraction more or less than it reports — a "
                 "gear-ratio or encoder-resolution (scale) error",
        "backlash": f"joint {j} stops short by a constant amount against its direction of "
                    "approach — backlash (lost motion) in its drive",
        "coupling": f"joint {j}'s angle error follows joint {(j or 2) - 1}'s angle — "
                    "mechanical coupling or cable wind-up in the wrist",
        "thermal": "every link grows in proportion to the temperature — thermal expansion "
                   "of the arm",
        "tracker_scale": "every measured distance is off by a constant factor — the "
                         "tracker's scale (wrong air temperature or pressure compensation)",
    }
    if fam in texts:
        return texts[fam]
    what = effect.summary or f"effect {effect.label}"
    return f"{what} (joint {j})" if j else what


# ---- held-out error ---------------------------------------------------------------------
def heldout_errors(fit: Fit, folds: int = 10, seed: int = 0, blocked: bool = True,
                   keep_linear: bool = False) -> Heldout:
    """Per pose squared error on held-out poses: the validation rows when there are at
    least :data:`MIN_HELDOUT`, else ``folds``-fold cross-validation of the linearised fit;
    with ``blocked`` also the range-blocked folds'
    (:func:`~calibration.diagnosis.screening.blocked_errors`). ``keep_linear``: the
    result keeps the linearised fit (``linear``) for a next use at the same fit."""
    lp = None
    if (fit.valid is not None and fit.valid["n"] >= MIN_HELDOUT
            and fit.valid_residuals is not None and fit.valid_data is not None):
        ho = Heldout(np.sum(fit.valid_residuals**2, axis=1), "validation poses",
                     np.asarray(fit.valid_data.pose_id, dtype=object))
    else:
        lp = linear_problem(fit)
        ho = Heldout(kfold_with(lp, folds, seed), f"{folds}-fold cross-validation",
                     np.asarray(fit.data.pose_id, dtype=object),
                     linear=lp if keep_linear else None)
    if blocked:
        sq, labels = blocked_errors(fit, lp=lp)
        if sq.size:
            ho.blocked = Heldout(sq, "range-blocked folds", labels)
    return ho


def blocked_gain(before: Heldout, after: Heldout) -> tuple[float, float]:
    """:func:`paired_gain` over the range-blocked folds; (0, 0) without them."""
    if before.blocked is None or after.blocked is None:
        return 0.0, 0.0
    return paired_gain(before.blocked, after.blocked)


def paired_gain(before: Heldout, after: Heldout) -> tuple[float, float]:
    """Mean drop of the squared held-out error per pose (mm²) and its standard error, over
    the poses both held out (a refit may leave out other blunders)."""
    b, a = before.sq, after.sq
    if (before.ids is not None and after.ids is not None
            and not np.array_equal(before.ids, after.ids)):
        _, ib, ia = np.intersect1d(before.ids, after.ids, return_indices=True)
        b, a = b[ib], a[ia]
    d = b - a
    se = float(d.std(ddof=1) / math.sqrt(d.size)) if d.size > 1 else float("inf")
    return float(d.mean()), se


# ---- candidates -------------------------------------------------------------------------
def candidate_effects(fit: Fit, data: Dataset) -> list[Effect]:
    """Every candidate effect not in the model that these data can test; a
    :class:`~calibration.effects.table.Table` stands for "a table on that joint" (the
    screening chooses its knots)."""
    em = fit.error_model
    model = em.model
    have = set(em.labels)
    tables = {e.joint for e in em.effects if e.family == "table"}
    out: list[Effect] = []
    for name in candidate_names(em, data):
        try:
            eff = parse_effect(name, model)
        except EffectError:
            continue
        if eff.family == "table":
            if eff.joint in tables:
                continue
        elif eff.label in have:
            continue
        out.append(eff)
    return out


def _picks(ranked: list[Screened], confirm: int) -> list[Screened]:
    """The best ``confirm`` candidates, one per family and joint."""
    picks, seen = [], set()
    for s in ranked:
        key = (s.effect.family, s.effect.joint)
        if key not in seen:
            seen.add(key)
            picks.append(s)
        if len(picks) >= confirm:
            break
    return picks


def _parsimonious(tried: list[Tried]) -> Tried:
    """The refit with the lowest held-out error, or one with fewer effective parameters
    whose held-out error is within a standard error of it (the one-standard-error rule)."""
    best = min(tried, key=lambda t: t.heldout.sq.mean())
    equivalent = [t for t in tried
                  if t is best or np.subtract(*paired_gain(t.heldout, best.heldout)) < 0]
    return min(equivalent, key=lambda t: (t.screened.edf, t.heldout.sq.mean()))


def _retune_tables(fit: Fit, ho: Heldout, data: Dataset, folds: int,
                   seed: int) -> tuple[Fit, Heldout]:
    """Re-choose the tables' smoothing by GCV at the new fit (what a table should smooth
    changes as other effects take their share) and refit; kept when the held-out error
    does not grow."""
    tables: list[Any] = [e for e in fit.error_model.effects if hasattr(e, "penalty_matrix")]
    before = [e.smoothing for e in tables]
    lp, ho.linear = ho.linear, None
    linear = None
    if lp is not None and lp.XtX is not None and lp.fit is fit:
        linear = (lp.X.reshape(-1, lp.m), lp.r, lp.XtX)
    if not gcv_smoothing(fit, tables, linear=linear):
        return fit, ho
    # the same model on the same data: its structural analysis is the candidate's
    refit, ho2 = _refit(fit.error_model, data, fit.solver, fit.values, folds, seed,
                        fit.structure)
    ho2.linear = None
    if ho2.sq.mean() <= ho.sq.mean():
        return refit, ho2
    for e, s in zip(tables, before, strict=True):
        e.smoothing = s
    return fit, ho


def _refit(em: Any, data: Dataset, solver: str, x0: np.ndarray, folds: int, seed: int,
           structure: Any = None) -> tuple[Fit, Heldout]:
    """:func:`identify` warm-started at ``x0`` and its :func:`heldout_errors`, which
    linearise the fit at the solver's last Jacobian (the same numbers, no new evaluation;
    the fit drops it then, the held-out errors keep the free columns for the tables'
    GCV: ``Heldout.linear``, dropped by whoever is done with it). ``structure``: that of a
    fit of ``em`` to ``data`` (:attr:`Fit.structure`)."""
    fit = identify(em, data, solver, x0=x0, keep_jacobian=True, structure=structure)
    # a step holds its candidates' linearisations until it chooses: only small ones
    small = 24 * fit.data.n * int(fit.free.sum()) <= KEEP_LINEAR_BYTES
    ho = heldout_errors(fit, folds, seed, keep_linear=small)
    fit.jacobian = fit.normal = None
    return fit, ho


#: a candidate's linearisation (its Jacobian's free columns, 24 bytes a pose and
#: parameter) is kept for the step's table GCV only up to this size (else evaluated again)
KEEP_LINEAR_BYTES = 64 << 20


def _without_blunders(calib: Dataset, fit: Fit) -> Dataset:
    """``calib`` without the rows ``fit`` left out as blunders."""
    screen = getattr(fit, "outliers", None)
    if screen is None or not screen.excluded:
        return calib
    return calib.subset(~np.isin(np.asarray(calib.pose_id, dtype=object),
                                 np.asarray(screen.ids, dtype=object)))


def _significant(s: Screened, n_screened: int, alpha: float) -> bool:
    return s.edf >= 0.5 and s.log10_p + math.log10(max(n_screened, 1)) < math.log10(alpha)


def at_noise_floor(lin: Linearised, sigma: float | None,
                   alpha: float = ALPHA) -> tuple[bool, float | None]:
    """(at the floor, p-value): the residual is consistent with the instrument's noise."""
    import scipy.special  # here: scipy's import is half of `cellcal calibrate`'s start-up

    if sigma is None:
        return False, None
    p = float(scipy.special.chdtrc(max(lin.dof0, 1.0), lin.rss0 / sigma**2))  # chi2.sf
    return p > alpha, p


# ---- the loop -----------------------------------------------------------------------------
def auto_diagnose(
    fit: Fit,
    data: Dataset | None = None,
    *,
    max_steps: int = 12,
    budget_s: float | None = None,
    confirm: int = 3,
    folds: int = 10,
    alpha: float = ALPHA,
    seed: int = 0,
    progress: Callable[[AutoStep], None] | None = None,
) -> AutoDiagnosis:
    """Add missing effects to ``fit``'s model one at a time while the held-out error falls.

    Parameters
    ----------
    fit : the starting model's fit
    data : the whole data set (calibration and validation rows, in capture order);
        default the fit's own rows
    max_steps : at most this many effects are added
    budget_s : stop (keeping what was accepted) once this many seconds are spent
    confirm : candidates refitted per step (the best by linearised held-out gain, one per
        family and joint)
    folds : k of the cross-validation when there are too few validation rows
    alpha : significance level of the screening's F-test after the Bonferroni correction
    progress : called with every accepted step
    """
    from threadpoolctl import threadpool_limits

    # small dense problems: one BLAS thread is faster, and far faster on a busy machine
    with threadpool_limits(limits=1, user_api="blas"):
        return _auto(fit, data, max_steps, budget_s, confirm, folds, alpha, seed, progress)


def _auto(fit: Fit, data: Dataset | None, max_steps: int, budget_s: float | None, confirm: int,
          folds: int, alpha: float, seed: int,
          progress: Callable[[AutoStep], None] | None) -> AutoDiagnosis:
    t0 = time.perf_counter()
    if data is None:
        data = fit.data if fit.valid_data is None else fit.data.concat(fit.valid_data)
    notes: list[str] = []
    if data.dirs is None:  # approach directions from capture order, for backlash candidates
        data = replace(data, dirs=derive_directions(data.q),
                       meta={**data.meta, "dirs_derived": "consecutive rows in capture order"})
        notes.append("backlash candidates: approach directions derived from consecutive "
                     "rows in capture order (the data have no dir columns)")
    calib = data.calib() if data.is_valid.any() else data
    # screen without the starting fit's blunders (else a few millimetre blunders swamp
    # every candidate's F-test and the loop stops early); points a later, more flexible
    # fit leaves out stay in: they may be a local effect still to be found
    calib = _without_blunders(calib, fit)
    valid = data.valid() if data.is_valid.any() else None
    sigma = calib.sigma()
    floor = None if sigma is None else math.sqrt(3.0) * sigma
    start, cur = fit, fit
    cur_ho = heldout_errors(cur, folds, seed)
    start_ho = cur_ho
    steps: list[AutoStep] = []
    rejected: list[tuple[str, float]] = []

    def over_budget() -> bool:
        return budget_s is not None and time.perf_counter() - t0 > budget_s

    while True:
        if len(steps) >= max_steps:
            reason = f"reached the maximum of {max_steps} steps (--max-steps)"
            break
        if over_budget():
            reason = f"time budget of {budget_s:g} s spent (--budget-s)"
            break
        ts = time.perf_counter()
        lin = linearise(cur, calib, valid)
        effects = candidate_effects(cur, data)
        if not effects:
            reason = "no candidate effects left to try"
            break
        screened = screen(lin, effects, notes=notes, heldout_alpha=alpha)
        n_screened = len(screened)
        good = [s for s in screened if _significant(s, n_screened, alpha) and s.loo_gain > 0]
        if not good:
            if at_noise_floor(lin, sigma, alpha)[0]:
                reason = (f"the residual is at the instrument's noise floor ({floor:.4f} mm) "
                          "and no candidate explains any of it")
            else:
                reason = ("no candidate explains more of the remaining error than noise "
                          "would (F-test, Bonferroni-corrected)")
            break
        good.sort(key=lambda s: -s.loo_gain)
        screen_s = time.perf_counter() - ts
        tried: list[Tried] = []
        refit_s: list[float] = []
        best = None
        picks = _picks(good, confirm)
        for s in picks:
            if tried and over_budget():
                break
            tr = time.perf_counter()
            ext = cur.error_model.with_effects([s.effect])
            x0 = np.concatenate([cur.values, np.zeros(s.effect.n_params)])
            refit, ho = _refit(ext, data, cur.solver, x0, folds, seed)
            tried.append(Tried(s, refit, ho, *paired_gain(cur_ho, ho),
                               *blocked_gain(cur_ho, ho)))
            refit_s.append(time.perf_counter() - tr)
        helps = [t for t in tried if t.gain > t.gain_se and t.gain > 0]
        ok = [t for t in helps if not t.hurts_beyond]
        for t in helps:
            if t.hurts_beyond:
                notes.append(
                    f"{t.effect} lowers the held-out error ({cur_ho.rms_mm:.4f} -> "
                    f"{t.heldout.rms_mm:.4f} mm) but raises it beyond the data's range "
                    f"(range-blocked folds {cur_ho.blocked_rms_mm:.4f} -> "
                    f"{t.heldout.blocked_rms_mm:.4f} mm): not added")
        best = _parsimonious(ok) if ok else None
        for t in tried:  # only the step's own fit is linearised again (its tables' GCV)
            if t is not best:
                t.heldout.linear = None
        if best is None:
            rejected = [(t.effect, t.heldout.rms_mm) for t in tried]
            reason = ("no candidate lowers the held-out error by more than its standard "
                      "error" + (" without raising it beyond the data's range "
                                 "(range-blocked folds)" if helps else ""))
            break
        step = AutoStep(
            effect=best.effect, n_params=best.screened.n_params,
            calib_rms_mm=best.fit.calib["rms_mm"], heldout_rms_mm=best.heldout.rms_mm,
            blocked_rms_mm=best.heldout.blocked_rms_mm,
            seconds=time.perf_counter() - ts, explanation=explain_effect(best.screened.effect),
            gain=best.gain, gain_se=best.gain_se,
            tried=[(t.effect, t.heldout.rms_mm) for t in tried], screen_s=screen_s,
            refit_s=refit_s,
        )
        cur, cur_ho = _retune_tables(best.fit, best.heldout, data, folds, seed)
        step.calib_rms_mm, step.heldout_rms_mm = cur.calib["rms_mm"], cur_ho.rms_mm
        step.blocked_rms_mm = cur_ho.blocked_rms_mm
        step.seconds, step.fit = time.perf_counter() - ts, cur
        steps.append(step)
        if progress is not None:
            progress(step)
    return AutoDiagnosis(start, cur, start_ho.rms_mm, start_ho.method, steps, reason, floor,
                         time.perf_counter() - t0, rejected, notes,
                         start_blocked_rms_mm=start_ho.blocked_rms_mm)
