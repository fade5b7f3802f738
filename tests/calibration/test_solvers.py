"""The seed solvers against LM on the same simulated data: ridge (IGG3 + ridge), Be-SA, SA."""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.fit.solvers import SOLVERS, igg3_weights
from calibration.fit.solvers.ridge import condition_class
from presentation.ridge_plot import plot_ridge

SIGMA = 0.015  # mm per axis


def _data(seed, n_cal=200, n_val=300, n_outliers=0):
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(seed)
    x_true = realistic_truth(em, rng)
    q = random_joints(m, n_cal + n_val, rng)
    data = simulate(em, x_true, q, SIGMA, rng, is_valid=np.arange(n_cal + n_val) >= n_cal)
    bad = np.sort(rng.choice(n_cal, n_outliers, replace=False))
    direction = rng.normal(size=(n_outliers, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    data.tracker_p_smr[bad] += direction * rng.uniform(1.0, 3.0, (n_outliers, 1))
    return em, data, [data.pose_id[i] for i in bad]


@pytest.fixture(scope="module")
def clean():
    em, data, _ = _data(11)
    return em, data, identify(em, data, "lm")


def test_registered():
    assert {"lm", "ridge", "besa", "sa", "besa+lm"} <= set(SOLVERS)


def test_igg3_weight_function_segments():
    # residuals along x with a known scale: v = |r| / (sqrt(3) s)
    s = 1.0 / np.sqrt(3.0)
    r = np.zeros((5, 3))
    r[:, 0] = [0.5, 1.5, 2.0, 3.0, 4.0]
    w, v, scale = igg3_weights(r, 1.5, 3.0, scale=s)
    np.testing.assert_allclose(v, r[:, 0])
    assert scale == s
    np.testing.assert_allclose(w, [1.0, 1.0, 1.5 / 2.0 * (1.0 / 1.5) ** 2, 0.0, 0.0])


def test_condition_classes():
    assert [condition_class(c) for c in (10, 500, 5e4, np.inf)] == [
        "weak", "moderate", "strong", "strong"]


def test_ridge_with_xi_zero_and_no_weights_is_least_squares(clean):
    em, data, lm = clean
    fit = identify(em, data, "ridge", solver_options={"xi": 0.0, "robust": False})
    assert fit.converged, fit.reason
    free = lm.free
    z = (fit.values[free] - lm.values[free]) / lm.std[free]
    assert np.abs(z).max() < 1e-4
    assert fit.calib["rms_mm"] == pytest.approx(lm.calib["rms_mm"], rel=1e-8)


def test_ridge_matches_lm_on_clean_data(clean):
    em, data, lm = clean
    fit = identify(em, data, "ridge")
    assert fit.converged, fit.reason
    assert fit.info["rejected"] == []
    assert fit.valid["rms_mm"] < 1.02 * lm.valid["rms_mm"]
    assert fit.info["condition_class"] in ("weak", "moderate", "strong")
    assert fit.info["xi_method"] == "gcv" and fit.info["xi"] >= 0


def test_igg3_rejects_exactly_the_injected_outliers():
    em, data, injected = _data(12, n_outliers=10)
    # IGG3 itself, on every point (by default the blunders are left out before it runs)
    lm = identify(em, data, "lm", outliers="keep")
    fit = identify(em, data, "ridge", outliers="keep")
    assert fit.converged, fit.reason
    assert sorted(identify(em, data, "ridge").outliers.ids) == sorted(injected)
    assert sorted(fit.info["rejected"]) == sorted(injected)
    w = fit.info["weights"]
    assert w.shape == (200,)
    keep = ~np.isin(fit.data.pose_id, injected)
    assert (w[keep] > 0).all() and (w[~keep] == 0).all()
    floor = data.noise_floor_mm()
    assert fit.valid["rms_mm"] < 1.1 * floor < lm.valid["rms_mm"]


def test_ridge_plot_is_a_png(clean, tmp_path):
    em, data, _ = clean
    fit = identify(em, data, "ridge")
    path = tmp_path / "ridge.png"
    plot_ridge(fit.info, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_besa_is_reproducible_and_close_to_lm(clean):
    em, data, lm = clean
    a = identify(em, data, "besa", solver_options={"seed": 3})  # default budget, 6000
    b = identify(em, data, "besa", solver_options={"seed": 3})
    np.testing.assert_array_equal(a.values, b.values)
    assert a.info["evaluations"] <= 6000
    assert a.calib["rms_mm"] < 2.0 * lm.calib["rms_mm"]
    c = identify(em, data, "besa", solver_options={"max_evals": 300, "seed": 4})
    assert not np.array_equal(a.values, c.values)


def test_sa_returns_its_best_state(clean):
    em, data, _ = clean
    fit = identify(em, data, "sa", solver_options={"max_evals": 1500})
    assert fit.converged
    hist = [h["f_best"] for h in fit.history]
    assert all(b <= a for a, b in zip(hist, hist[1:], strict=False))
    # the returned state is the best seen: its objective is the last best value
    assert fit.calib["rms_mm"] ** 2 == pytest.approx(hist[-1], rel=1e-9)
    assert hist[-1] <= hist[0]
    assert fit.info["evaluations"] <= 1500


def test_besa_beats_sa_on_the_same_budget(clean):
    em, data, _ = clean
    opts = {"max_evals": 1500, "seed": 1}
    besa = identify(em, data, "besa", solver_options=opts)
    sa = identify(em, data, "sa", solver_options=opts)
    assert besa.calib["rms_mm"] < sa.calib["rms_mm"]


def test_besa_lm_polishes_to_lm(clean):
    em, data, lm = clean
    fit = identify(em, data, "besa+lm", solver_options={"max_evals": 500})
    assert fit.converged, fit.reason
    assert fit.calib["rms_mm"] == pytest.approx(lm.calib["rms_mm"], rel=1e-6)
