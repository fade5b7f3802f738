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

import numpy as np

from ..effects import Effect, EffectError
from ..effects.physical import Harmonic
from ..effects.table import Table
from ..fit.identify import Fit
from .candidate_columns import effect_columns, harmonic_columns
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
        batch = [(eff, c, cv) if c is not None else (eff, *_harmonic(lin, eff))
                 for eff, c, cv in items[i : i + size]]
        C = np.stack([c for _, c, _ in batch], axis=2)
        Cv = None if lin.valid is None else np.stack([c for _, _, c in batch], axis=2)
        res = evaluate_candidates(lin, C, Cv, heldout=heldout)
        for a, (eff, c, cv) in enumerate(batch):
            out.append(as_screened(lin, eff, {k: v[a] for k, v in res.items()}))
            if not heldout and waiting is not None:
                held = (None, None) if type(eff) is Harmonic else (c, cv)
                waiting.append((len(out) - 1, eff, *held))


def _harmonic(lin: Linearised, eff: Harmonic) -> tuple[np.ndarray, np.ndarray | None]:
    """(C, Cv) of one harmonic candidate (what :func:`harmonic_columns` gives it)."""
    return harmonic_columns(lin, [eff])[id(eff)]


def kfold_errors(fit: Fit, folds: int = 10, seed: int = 0) -> np.ndarray:
    """Squared 3-D error (mm²) of every calibration pose when predicted by the fit refitted
    without its fold (``folds`` folds, poses assigned at random with ``seed``), on the
    problem linearised at the fit (penalties included), shape (n,)."""
    import scipy.linalg  # here: scipy's import is half of `cellcal calibrate`'s start-up

    em, x, free = fit.error_model, fit.values, fit.free
    calib = fit.data
    n, m = calib.n, int(free.sum())
    P, J = em.evaluate(x, em.bind(calib), jacobian=True)
    X = J[:, :, free].reshape(n, 3, m)
    r = calib.tracker_p_smr - P
    X2 = X.reshape(3 * n, m)
    A = X2.T @ X2  # BLAS, not einsum's loops
    b = X2.T @ r.ravel()
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
        L = cholesky_nudged(Af / np.outer(d, d))
        delta = scipy.linalg.cho_solve((L, True), bf / d, check_finite=False) / d
        sq[te] = np.sum((rt - Xt @ delta).reshape(-1, 3) ** 2, axis=1)
    return sq
