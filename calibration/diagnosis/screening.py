"""Linear screening of candidate effects at a fit: what each would explain, and how much it
would lower the error on poses it was not fitted to (:func:`screen`), and the k-fold
errors of a linearised fit (:func:`kfold_errors`).

The pieces: the fit linearised and the formulas (:mod:`calibration.diagnosis.linear_screen`), the
candidates' columns (:mod:`calibration.diagnosis.candidate_columns`), tables with their spacing and
smoothing by GCV (:mod:`calibration.diagnosis.table_screening`), the F-test
(:mod:`calibration.diagnosis.f_test`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..data.dataset import Dataset
from ..effects import Effect, EffectError
from ..effects.physical import Harmonic
from ..effects.table import Table
from ..fit.identify import Fit
from .candidate_columns import effect_columns, harmonic_columns, valid_columns
from .linear_screen import (  # noqa: F401 - _loo, linearise: with screen, this API
    Linearised,
    Screened,
    _loo,
    as_screened,
    cholesky_nudged,
    evaluate_candidates,
    linearise,
)
from .table_screening import TABLE_SPACINGS_DEG, data_gap_deg, screen_table  # noqa: F401

#: candidates evaluated together (memory: 3n x batch x k doubles per array), and the
#: memory their arrays may take at once (fewer together on many poses)
_BATCH = 64
_BATCH_BYTES = 256 << 20


def screen(lin: Linearised, effects: list[Effect], *, notes: list[str] | None = None,
           table_spacings: Sequence[int] = TABLE_SPACINGS_DEG, heldout_alpha: float | None = None
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
    groups: dict[int, list[tuple[Effect, np.ndarray | None, np.ndarray | None]]] = {}
    for eff in effects:
        try:
            if isinstance(eff, Table):
                s = screen_table(lin, eff.joint, table_spacings)
                if s is not None:
                    out.append(s)
                continue
            if type(eff) is Harmonic:  # its columns when its batch is evaluated
                C = Cv = None
            else:
                C = effect_columns(eff, lin.calib, lin.bound, lin.G, em, x, lin.P)
                Cv = valid_columns(eff, lin, em, x, lin.Pv)
        except EffectError as e:
            notes.append(f"{eff.label}: skipped ({e})")
            continue
        groups.setdefault(eff.n_params, []).append((eff, C, Cv))
    # (index in out, effect, C, Cv): held-out figures still to compute
    waiting: list[tuple[int, Effect, np.ndarray | None, np.ndarray | None]] = []
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


def batch_size(n: int, k: int) -> int:
    """Candidates of ``k`` columns evaluated together on ``n`` poses: :data:`_BATCH`, fewer
    when their arrays (about 90 doubles a pose each, with the held-out figures) would pass
    :data:`_BATCH_BYTES`."""
    return max(1, min(_BATCH, _BATCH_BYTES // max(8 * n * (72 + 18 * k), 1)))


def _evaluate_all(lin: Linearised, items: list, out: list[Screened], heldout: bool = True,
                  waiting: list | None = None) -> None:
    """Evaluate candidates ``items`` [(effect, C, Cv)] with the same number of columns in
    batches (:func:`batch_size`), appending their :class:`Screened` to ``out`` (and,
    without the ``heldout`` figures, ``(index, effect, C, Cv)`` to ``waiting``). A
    harmonic's columns (C None) are made with its batch."""
    if not items:
        return
    size = batch_size(lin.n, items[0][0].n_params)
    for i in range(0, len(items), size):
        chunk = items[i : i + size]
        # the harmonics' columns, every order of a joint in one call (harmonic_columns)
        periodic = harmonic_columns(lin, [eff for eff, c, _ in chunk if c is None])
        batch: list[tuple[Effect, np.ndarray, Any]] = []  # Cv: None without validation
        for eff, c, cv in chunk:
            if c is None:  # a harmonic
                c, cv = periodic[id(eff)]
            batch.append((eff, c, cv))
        C = np.stack([c for _, c, _ in batch], axis=2)
        Cv = None if lin.valid is None else np.stack([c for _, _, c in batch], axis=2)
        res = evaluate_candidates(lin, C, Cv, heldout=heldout)
        for a, (eff, c, cv) in enumerate(batch):
            out.append(as_screened(lin, eff, {k: v[a] for k, v in res.items()}))
            if not heldout and waiting is not None:
                held = (None, None) if type(eff) is Harmonic else (c, cv)
                waiting.append((len(out) - 1, eff, *held))



def kfold_errors(fit: Fit, folds: int = 10, seed: int = 0) -> np.ndarray:
    """Squared 3-D error (mm²) of every calibration pose when predicted by the fit refitted
    without its fold (``folds`` folds, poses assigned at random with ``seed``), on the
    problem linearised at the fit (penalties included), shape (n,)."""
    return kfold_with(_LinearProblem(fit), folds, seed)


def kfold_with(lp: _LinearProblem, folds: int = 10, seed: int = 0) -> np.ndarray:
    """:func:`kfold_errors` of a linearised fit (shared with :func:`blocked_errors`)."""
    n = lp.n
    fold_of = np.random.default_rng(seed).permutation(n) % max(2, min(folds, n))
    sq = np.zeros(n)
    for f in np.unique(fold_of):
        te = fold_of == f
        sq[te] = lp.heldout_sq(te)
    return sq


#: the share of the calibration poses at each end of a joint's range that a range-blocked
#: fold leaves out (:func:`blocked_errors`)
BLOCK_SHARE = 0.1
#: a joint whose calibration angles span less than this (deg) has no range-blocked folds
MIN_BLOCK_SPAN_DEG = 10.0
#: the ties of a range-blocked fold (own, tied, c, drop: see ``_ties``)
_Ties = tuple[np.ndarray, list[tuple[int, int]], np.ndarray, np.ndarray]


def range_blocks(data: Dataset, share: float = BLOCK_SHARE) -> list[tuple[str, np.ndarray]]:
    """The range-blocked folds of ``data``'s rows: for each joint whose angles span at least
    :data:`MIN_BLOCK_SPAN_DEG`, the ``share`` of the poses at the low end of its range and
    the ``share`` at the high end, as (name ``q2<`` / ``q2>``, (n,) bool)."""
    out = []
    deg = np.degrees(data.q)
    for j in range(deg.shape[1]):
        t = deg[:, j]
        if np.ptp(t) < MIN_BLOCK_SPAN_DEG:
            continue
        lo, hi = np.quantile(t, [share, 1.0 - share])
        out += [(f"q{j + 1}<", t <= lo), (f"q{j + 1}>", t >= hi)]
    return out


def blocked_errors(fit: Fit, share: float = BLOCK_SHARE, lp: _LinearProblem | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Squared 3-D error (mm²) of the calibration poses at either end of each joint's range
    when predicted by the fit refitted without them (:func:`range_blocks`), on the problem
    linearised at the fit: what the model does just beyond the angles it was fitted to.

    In a fold, every table holds only the knots the remaining poses support
    (``Table.knot_support``), its value beyond them that of its last supported knot, as a
    table fitted to those poses would (the knots beyond are tied to it). Returns (squared
    errors, labels ``"<pose_id>|q2>"``), one per pose and fold that holds it out. ``lp``:
    the fit linearised already (:func:`linear_problem`)."""
    lp = _LinearProblem(fit, blas=True) if lp is None else lp
    sq, labels = [], []
    ids = np.asarray(fit.data.pose_id, dtype=object)
    for name, te in range_blocks(fit.data, share):
        if te.all() or not te.any():
            continue
        sq.append(lp.heldout_sq(te, tie=True))
        labels.append(np.array([f"{p}|{name}" for p in ids[te]], dtype=object))
    if not sq:
        return np.zeros(0), np.zeros(0, dtype=object)
    return np.concatenate(sq), np.concatenate(labels)


def linear_problem(fit: Fit) -> _LinearProblem:
    """``fit``'s calibration problem linearised (for :func:`kfold_with` and
    :func:`blocked_errors` on one evaluation), its normal matrix by BLAS (the k-fold
    errors the same to ~1e-15: the auto loop's choices and figures unchanged)."""
    return _LinearProblem(fit, blas=True)


class _LinearProblem:
    """A fit's calibration problem linearised at its parameters (penalties included): the
    normal equations ``A δ = b`` over the free parameters, from which a fold's refit is
    ``A - X_tᵀ X_t``, ``b - X_tᵀ r_t``. ``blas``: XᵀX as one matrix product (else the
    per-pose sum of einsum's loops: a tenth of the speed at a few hundred parameters)."""

    def __init__(self, fit: Fit, blas: bool = False):
        em, x, free = fit.error_model, fit.values, fit.free
        calib = fit.data
        self.fit, self.n, self.m = fit, calib.n, int(free.sum())
        J = fit.jacobian  # the solver's last one, when the fit kept it: the same numbers
        kept = J is not None and J.shape == (calib.n, 3, em.n_params)
        if J is not None and kept:
            self.r = fit.residuals
        else:
            P, J = em.evaluate(x, em.bind(calib), jacobian=True)
            self.r = calib.tracker_p_smr - P
        # in C order: each fold gathers its poses' rows (J[:, :, free] is not: its rows
        # strided, a gather thirty times slower)
        self.X = J.take(np.flatnonzero(free), axis=2)
        #: XᵀX without the penalty (BLAS only), for the tables' GCV at the same fit
        self.XtX: np.ndarray | None = None
        # the fit's normal matrices (identify's normal_matrix: these products, once)
        normal = fit.normal if kept and blas else None
        if blas:
            X2 = self.X.reshape(-1, self.m)
            self.A = self.XtX = X2.T @ X2 if normal is None else normal[0]
            self.b = X2.T @ self.r.ravel()
        else:
            self.A = np.einsum("nim,nik->mk", self.X, self.X)
            self.b = np.einsum("nim,ni->m", self.X, self.r)
        pen = em.penalty(x)
        #: the penalty rows (value, Jacobian over the free parameters) and, per effect
        #: index, the slice of its rows
        self.pen, self.pen_rows = None, {}
        if pen is not None:
            Pf = pen[1][:, free]
            self.A = self.A + Pf.T @ Pf if normal is None else normal[1]
            self.b = self.b - Pf.T @ pen[0]
            self.pen = (pen[0], Pf)
            k = 0
            for i, (e, sl) in enumerate(zip(em.effects, em.slices, strict=True)):
                if hasattr(e, "penalty"):
                    rows = e.penalty(np.asarray(x, float)[sl])[0].size
                    self.pen_rows[i] = slice(k, k + rows)
                    k += rows

    def heldout_sq(self, te: np.ndarray, tie: bool = False) -> np.ndarray:
        """Squared errors of the poses ``te`` predicted by the refit without them; ``tie``:
        the tables' unsupported end knots tied to their last supported one."""
        import scipy.linalg  # here: scipy's import is half of `cellcal calibrate`'s start-up

        m = self.m
        idx = np.flatnonzero(te)
        Xt, rt = self.X.take(idx, axis=0).reshape(-1, m), self.r.take(idx, axis=0).ravel()
        Af = Xt.T @ Xt
        np.subtract(self.A, Af, out=Af)
        bf = self.b - Xt.T @ rt
        ties = self._ties(~te) if tie else None
        if ties is not None:
            own, tied, c, drop = ties
            if drop.size:  # smoothness rows beyond the edge: a table ending there has none
                assert self.pen is not None  # rows to drop are penalty rows
                v, Pf = self.pen[0][drop], self.pen[1][drop]
                Af, bf = Af - Pf.T @ Pf, bf + Pf.T @ v
            # δ = T δ' + c, T one 1 a row at most: Tᵀ M sums the tied rows into their
            # leader's
            bf = _fold(bf - Af @ c, own, tied)
            Af = _fold(_fold(Af, own, tied).T, own, tied)
            Af = 0.5 * (Af + Af.T)
        d = np.sqrt(np.maximum(np.diag(Af), 1e-300))
        scaled = np.outer(d, d)
        np.divide(Af, scaled, out=scaled)
        L = cholesky_nudged(scaled, overwrite=True)
        delta = scipy.linalg.cho_solve((L, True), bf / d, check_finite=False) / d
        if ties is not None:
            full = c.copy()
            full[own] += delta
            for k, col in tied:
                full[k] += delta[col]
            delta = full
        return np.sum((rt - Xt @ delta).reshape(-1, 3) ** 2, axis=1)

    def _ties(self, keep: np.ndarray) -> _Ties | None:
        """The free parameters' step δ = T δ' + c under which each table is constant
        beyond the knots the poses ``keep`` support (every knot beyond ends at its edge
        knot's value; where one of them is held, at the held value), as (``own``: the free
        columns that stay, in δ' order; ``tied``: (free column, column of δ' it follows)
        pairs; c (m,); the smoothness rows that reach beyond the edge knot, which a table
        fitted to those poses does not have). None when no knot is tied."""
        fit = self.fit
        em, x, free = fit.error_model, fit.values, fit.free
        pos = np.cumsum(free) - 1  # full index -> free column
        keep_col = free.copy()
        follows: dict[int, int] = {}  # full index of a tied knot -> its leader's
        c = np.zeros(len(x))
        drop: list[int] = []
        for i_e, (e, sl) in enumerate(zip(em.effects, em.slices, strict=True)):
            if not isinstance(e, Table):
                continue
            idx = np.flatnonzero(e.knot_support(fit.data.q[keep, e.joint - 1]))
            if idx.size == 0:
                continue
            rows = self.pen_rows.get(i_e)
            if rows is not None and (idx[0] > 0 or idx[-1] < e.n_params - 1):
                r = np.arange(rows.stop - rows.start)  # row r spans knots r..r+2
                drop += list(rows.start + r[(r < idx[0]) | (r + 2 > idx[-1])])
            for edge, beyond in ((idx[0], range(0, idx[0])),
                                 (idx[-1], range(idx[-1] + 1, e.n_params))):
                group = [sl.start + k for k in beyond]
                if not group:
                    continue
                lead = sl.start + int(edge)
                held = [k for k in (lead, *group) if not free[k]]
                if held:  # the group ends at the held value: its free members are set
                    for k in (lead, *group):
                        if free[k]:
                            c[k] = x[held[0]] - x[k]
                            keep_col[k] = False
                else:
                    for k in group:
                        c[k] = x[lead] - x[k]
                        keep_col[k] = False
                        follows[k] = lead
        if (keep_col == free).all() and not (c != 0).any():
            return None
        cols = np.flatnonzero(keep_col)  # full indices of the free parameters that stay
        col_of = {int(k): i for i, k in enumerate(cols)}
        tied = []
        for k, lead in follows.items():
            if lead in col_of:
                tied.append((int(pos[k]), col_of[lead]))
            else:  # the leader is set itself (held by the other end's group)
                c[k] += c[lead]
        return pos[cols], tied, c[free], np.array(drop, int)


def _fold(M: np.ndarray, own: np.ndarray, tied: list[tuple[int, int]]) -> np.ndarray:
    """Tᵀ M for the 0/1 matrix T of a fold's ties (:meth:`_LinearProblem._ties`): the rows
    ``own`` in order, each tied row added to the row of the column it follows."""
    out = M[own]  # a copy (fancy indexing)
    for k, col in tied:
        out[col] += M[k]
    return out
