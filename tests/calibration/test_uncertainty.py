"""Correlations, position uncertainty and the Monte-Carlo check of the analytic covariance."""

import numpy as np
import pytest

from calibration import ErrorModel, identify, load_model
from calibration.exports.params_io import fit_to_dict
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.fit.uncertainty import correlations, monte_carlo, position_uncertainty

SIGMA = 0.015


@pytest.fixture(scope="module")
def fit():
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(21)
    data = simulate(em, realistic_truth(em, rng), random_joints(m, 120, rng), SIGMA, rng)
    return identify(em, data)


def test_correlations_and_params_json(fit):
    c = correlations(fit, 4)
    m = int(fit.free.sum())
    R = np.array(c["matrix"])
    assert R.shape == (m, m) and len(c["names"]) == m
    np.testing.assert_allclose(np.diag(R), 1.0, atol=1e-6)
    assert len(c["strongest"]) == 4
    rs = [abs(p["r"]) for p in c["strongest"]]
    assert rs == sorted(rs, reverse=True)
    d = fit_to_dict(fit)
    assert d["correlation"]["names"] == c["names"]
    assert d["strongest_correlations"][0]["a"] == c["strongest"][0]["a"]
    assert "parameters" in d and "stats" in d  # existing keys kept


def test_position_uncertainty_scales_with_the_covariance(fit):
    u = position_uncertainty(fit, n_poses=200)
    assert u["per_pose_mm"].shape == (200,)
    assert 0 < u["mean_mm"] <= u["max_mm"] < 0.1
    u4 = position_uncertainty(fit, fit.covariance * 4, n_poses=200)
    assert u4["mean_mm"] == pytest.approx(2 * u["mean_mm"])
    assert position_uncertainty(fit, n_poses=200, include_frame=True)["mean_mm"] > u["mean_mm"]


def test_monte_carlo_spread_matches_the_analytic_std(fit):
    n = 50
    mc = monte_carlo(fit, n, sigma=SIGMA, seed=2, n_poses=200)
    assert mc.samples.shape == (n, fit.error_model.n_params)
    assert mc.n_failed == 0
    r = mc.ratio[fit.free]
    # the relative standard error of a sample std from n draws is about 1 / sqrt(2 (n - 1))
    se = 1.0 / np.sqrt(2 * (n - 1))
    assert np.abs(r - 1).max() < 4.5 * se, r
    assert abs(r.mean() - 1) < 3 * se
    assert mc.position_mc["mean_mm"] == pytest.approx(mc.position["mean_mm"], rel=0.3)
    assert np.isnan(mc.ratio[~fit.free]).all()
    again = monte_carlo(fit, 3, sigma=SIGMA, seed=2, n_poses=10)
    np.testing.assert_array_equal(again.samples, mc.samples[:3])
