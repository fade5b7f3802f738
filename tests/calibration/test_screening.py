"""Linear screening and the table machinery, checked against brute force and refits."""

import json

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.screening import _loo, data_gap_deg, kfold_errors, linearise, screen
from calibration.effects import parse_effect
from calibration.effects.table import (
    MIN_KNOT_POSES,
    MIN_KNOT_SHARE,
    Table,
    _low_rank_path,
    gcv_smoothing,
    penalised_path,
)
from calibration.exports.params_io import fit_to_dict, params_from_dict
from calibration.fit.identify import fit_at
from calibration.fit.simulate import random_joints, realistic_truth, simulate

UR10E = load_model("ur10e")


def _data(hidden: str, n: int = 400, seed: int = 1, **kw):
    em = ErrorModel(UR10E, "geometric,base,tool" + ("," + hidden if hidden else ""))
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    return simulate(em, x, random_joints(UR10E, n, rng, **kw), 0.015, rng,
                    is_valid=np.arange(n) % 2 == 1)


def test_penalised_path_matches_direct_solves():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(60, 8))
    y = rng.normal(size=60)
    D = np.diff(np.eye(8), 2, axis=0)
    omega = D.T @ D
    grid = [1e-3, 0.1, 10.0]
    path = penalised_path(X.T @ X, X.T @ y, X.T @ y, X.T @ X, float(y @ y), omega, grid, 60)
    for i, s in enumerate(grid):
        A = X.T @ X + s * omega
        c = np.linalg.solve(A, X.T @ y)
        H = X @ np.linalg.solve(A, X.T)
        assert path["rss"][i] == pytest.approx(np.sum((y - X @ c) ** 2), rel=1e-8)
        assert path["edf"][i] == pytest.approx(np.trace(H), rel=1e-8)
        assert np.allclose(path["solve"](s), c, rtol=1e-6, atol=1e-10)


def test_leave_one_pose_out_formula_matches_refits():
    # a linear least-squares problem in pose blocks of 3 rows
    rng = np.random.default_rng(1)
    n, m = 20, 4
    X = rng.normal(size=(3 * n, m))
    y = rng.normal(size=3 * n)
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    e = (y - X @ beta).reshape(n, 3)
    H = X @ np.linalg.solve(X.T @ X, X.T)
    blocks = np.stack([H[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] for i in range(n)])
    loo = _loo(blocks, e)
    for i in (0, 7, 19):
        keep = np.ones(3 * n, bool)
        keep[3 * i : 3 * i + 3] = False
        b = np.linalg.lstsq(X[keep], y[keep], rcond=None)[0]
        assert np.allclose(loo[i], y[3 * i : 3 * i + 3] - X[3 * i : 3 * i + 3] @ b)


def test_screening_predicts_the_refit_of_a_hidden_harmonic():
    data = _data("harmonic12:4", n=600)
    fit = identify(ErrorModel(UR10E), data)
    lin = linearise(fit, data.calib(), data.valid())
    eff = parse_effect("harmonic12:4", UR10E)
    (s,) = screen(lin, [eff])
    refit = identify(ErrorModel(UR10E, "geometric,base,tool,harmonic12:4"), data)
    assert s.rms_after_mm == pytest.approx(refit.calib["rms_mm"], rel=0.01)
    assert s.valid_rms_after_mm == pytest.approx(refit.valid["rms_mm"], rel=0.01)
    assert s.log10_p < -10 and s.loo_gain > 3 * s.loo_gain_se



def test_screening_rows_the_fit_left_out_are_judged_against_the_model_refitted_to_them():
    """The auto diagnosis screens rows a later fit left out as blunders (a local effect may
    explain them): the linearisation re-centres on the model refitted to every row, so a
    table (whose constant part the joint offset already spans) is screened as its refit
    turns out, not as rounding noise over a zero pivot (GCV came out 0, the table unsmoothed,
    depending on the BLAS kernels)."""
    data = _data("table:2", n=400, max_abs_deg=150)
    calib = data.calib()
    left_out = np.abs(np.degrees(calib.q[:, 1]) - 30.0) < 8.0  # what a bump would flag
    assert 5 <= left_out.sum() <= 40
    fit = identify(ErrorModel(UR10E), calib.subset(~left_out), outliers="keep")
    lin = linearise(fit, calib, data.valid())
    assert np.linalg.norm(lin.W.T @ lin.r.ravel()) < 1e-8 * np.linalg.norm(lin.r)
    (s,) = screen(lin, [parse_effect("table:2", UR10E)])
    assert all(g > 0 for _, g in s.effect.cv_curve)
    em = ErrorModel(UR10E, [*ErrorModel(UR10E).effects, s.effect])
    refit = identify(em, calib, outliers="keep")
    assert s.rms_after_mm == pytest.approx(refit.calib["rms_mm"], rel=0.01)
    assert s.loo_gain > 3 * s.loo_gain_se

def test_kfold_errors_match_brute_force_on_the_linear_problem():
    data = _data("", n=120)
    fit = identify(ErrorModel(UR10E), data.calib())
    sq = kfold_errors(fit, folds=4, seed=3)
    assert sq.shape == (fit.data.n,)
    # the fit's own residual is a lower bound on average; held-out is larger
    assert sq.mean() > np.mean(np.sum(fit.residuals**2, axis=1))
    # brute force: nonlinear refits without each fold agree to well within the noise
    fold_of = np.random.default_rng(3).permutation(fit.data.n) % 4
    te = fold_of == 0
    sub = identify(ErrorModel(UR10E), fit.data.subset(~te), x0=fit.values)
    held = fit.data.subset(te)
    brute = np.sum((held.tracker_p_smr - sub.predict(held)) ** 2, axis=1)
    assert np.allclose(sq[te], brute, rtol=0.02, atol=1e-6)


def test_table_knots_cover_only_the_data_and_round_trip_through_params():
    data = _data("table:2", n=400, max_abs_deg=60)
    t = Table.covering(UR10E, 2, data.q[:, 1], 5)
    assert t.label == "table5:2" and t.spacing_deg == 5
    deg = np.degrees(data.q[:, 1])
    assert t.knots_deg[0] <= deg.min() < t.knots_deg[0] + 5
    assert t.knots_deg[-1] - 5 < deg.max() <= t.knots_deg[-1]
    assert t.with_parameter_names(t.param_names).param_names == t.param_names
    t.smoothing = 0.1
    em = ErrorModel(UR10E, [*ErrorModel(UR10E).effects, t])
    fit = identify(em, data)
    ident = fit.identifiability
    # the penalty determines the knots: only the constant part is held (it is the joint's
    # zero offset, geometric.j2.theta)
    held = [n for n in ident.fixed if n.startswith("table5")]
    assert len(held) == 1 and "constant part" in ident.fixed[held[0]]
    assert len(ident.penalised) == t.n_params - 1
    doc = json.loads(json.dumps(fit_to_dict(fit)))
    em2, x2, _ = params_from_dict(doc)
    assert em2.names == em.names and em2.effects[-1].smoothing == 0.1
    again = fit_at(em2, data, x2)
    assert again.valid["rms_mm"] == pytest.approx(fit.valid["rms_mm"], rel=1e-9)


def test_table_spacing_is_no_finer_than_the_widest_gap_in_the_data():
    theta = np.radians(np.concatenate([np.linspace(-90, -10, 200), np.linspace(-4, 90, 200)]))
    assert data_gap_deg(theta) == pytest.approx(6.0, abs=0.5)
    data = _data("table:3", n=500, max_abs_deg=90)
    fit = identify(ErrorModel(UR10E), data)
    lin = linearise(fit, data.calib(), data.valid())
    (s,) = screen(lin, [parse_effect("table:3", UR10E)])
    assert s.effect.spacing_deg >= data_gap_deg(data.calib().q[:, 2])
    assert s.effect.smoothing is not None and s.loo_gain > 0


def test_gcv_smoothing_reports_a_change_and_a_curve():
    data = _data("table:2", n=400, max_abs_deg=150)
    em = ErrorModel(UR10E, "geometric,base,tool,table:2")
    em.effects[-1].smoothing = 1e4  # far too stiff for the hidden table
    fit = identify(em, data)
    assert gcv_smoothing(fit)
    table = em.effects[-1]
    assert table.smoothing < 1e4 and len(table.cv_curve) == 25
    refit = identify(em, data, x0=fit.values)
    assert refit.valid["rms_mm"] < fit.valid["rms_mm"]


def test_low_rank_path_matches_the_general_one():
    # gcv_smoothing's path for one table among others (penalties of low rank) against
    # penalised_path on the same problem: rss, edf and GCV to rounding, the same choice
    rng = np.random.default_rng(3)
    X = rng.normal(size=(300, 40))
    y = X @ rng.normal(size=40) + rng.normal(size=300)
    Q, b = X.T @ X, X.T @ y
    F1, F2 = np.zeros((8, 40)), np.zeros((6, 40))
    F1[:, 10:20] = 3.0 * Table(UR10E, 2, 10)._D2[:8, :10]
    F2[:, 25:33] = 2.0 * Table(UR10E, 3, 10)._D2[:6, :8]
    N0 = Q + 0.7 * (F2.T @ F2)
    grid = np.logspace(-6, 6, 25)
    ref = penalised_path(N0, b, b, Q, float(y @ y), F1.T @ F1, grid, 300)
    low = _low_rank_path(N0, b, Q, float(y @ y), F1.T @ F1, F1, [(0.7, F2)], grid, 300)
    assert low is not None and low["best"] == ref["best"]
    for key in ("rss", "edf", "gcv"):
        np.testing.assert_allclose(low[key], ref[key], rtol=1e-9)


def test_knot_support_sums_the_basis_columns_exactly():
    # knot_support sums each pose's two hat weights without forming basis(): the same sums
    rng = np.random.default_rng(5)
    for spacing, n in ((2, 40), (3, 500), (10, 5000)):
        t = Table(UR10E, 2, spacing, knots_deg=np.arange(-60, 61, spacing))
        theta = rng.uniform(np.radians(-70), np.radians(70), n)
        B = t.basis(theta)
        w, count = B.sum(axis=0), (B > 1e-12).sum(axis=0)
        ref = (w >= MIN_KNOT_SHARE * np.median(w[w > 0])) & (count >= MIN_KNOT_POSES)
        np.testing.assert_array_equal(t.knot_support(theta), ref)


def test_knot_support_remembers_its_answers_without_sharing_them():
    t = Table(UR10E, 2, 5, knots_deg=np.arange(-60, 61, 5))
    theta = np.random.default_rng(6).uniform(np.radians(-50), np.radians(50), 300)
    first = t.knot_support(theta)
    first[:] = False  # the caller's copy
    again = t.knot_support(theta)
    np.testing.assert_array_equal(again, t._knot_support(theta))
    assert again.any()
