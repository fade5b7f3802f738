"""The blunder test's fast path against the straightforward computation: hat-matrix blocks
from the covariance's factor and the solver's last Jacobian, studentised norms by 3 x 3
solves, and the whole exclusion loop (same points named, same parameters)."""

from __future__ import annotations

import numpy as np
import pytest

import calibration.fit.outliers
from calibration import ErrorModel, identify, load_model
from calibration.fit.leverage import residual_factors, solve3, studentise, studentised_norms
from calibration.fit.simulate import add_blunders, random_joints, realistic_truth, simulate

CASES = [  # model, effects, calibration poses, blunder rate, seed
    ("ur10e", "geometric,base,tool", 400, 0.02, 5),
    ("ur10e", "geometric,base,tool,compliance:3,table:2", 300, 0.035, 7),
    ("ur5", "geometric,base,tool,compliance:2,harmonic:1", 150, 0.03, 3),
]


def _data(name, effects, n, rate, seed):
    m = load_model(name)
    em = ErrorModel(m, effects)
    rng = np.random.default_rng(seed)
    x = realistic_truth(em, rng)
    d = simulate(em, x, random_joints(m, n + 200, rng), 0.015, rng,
                 is_valid=np.arange(n + 200) >= n)
    d, _ = add_blunders(d, rate, np.random.default_rng(seed + 100), rows=~d.is_valid)
    return m, d


def straightforward_factors(fit, rows, included):
    """``I -/+ J_i C J_iᵀ`` with J evaluated anew and C the covariance over sigma²."""
    em, free = fit.error_model, fit.free
    J = em.evaluate(fit.values, em.bind(rows), jacobian=True)[1][:, :, free]
    C = fit.covariance[np.ix_(free, free)] / fit.sigma_mm**2
    G = np.einsum("nip,pq,njq->nij", J, C, J)
    sign = np.where(np.asarray(included, bool), -1.0, 1.0)[:, None, None]
    return np.eye(3) + sign * G


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[1]}")
@pytest.mark.parametrize("solver", ["lm", "ridge"])
def test_hat_blocks_from_the_covariance_factor_match_the_contraction(case, solver):
    m, d = _data(*case)
    fit = identify(ErrorModel(m, case[1]), d, solver, outliers="keep")
    rows = fit.data
    included = np.ones(rows.n, bool)
    included[::7] = False  # some predicted rows, as the exclusion loop has them
    fast = residual_factors(fit, rows, included, fit.jacobian)
    slow = straightforward_factors(fit, rows, included)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-10)
    # without the kept Jacobian and factor: the same again
    fit.jacobian = fit.hat_factor = None
    np.testing.assert_allclose(residual_factors(fit, rows, included), slow, rtol=0, atol=1e-10)


def test_studentised_norms_match_the_eigen_decomposition():
    rng = np.random.default_rng(1)
    n = 500
    Q = rng.normal(size=(n, 3, 6)) * rng.uniform(0.0, 0.45, (n, 1, 1))
    sign = np.where(rng.random(n) < 0.8, -1.0, 1.0)[:, None, None]
    factors = np.eye(3) + sign * Q @ Q.transpose(0, 2, 1)
    factors[:5] = np.diag([1.0, 0.5, 1e-4])  # a point alone determining a direction: clipped
    r = rng.normal(size=(n, 3))
    fast = studentised_norms(r, factors)
    slow = np.linalg.norm(studentise(r, factors), axis=1)
    np.testing.assert_allclose(fast, slow, rtol=1e-12)


def test_solve3_solves_stacks_of_3x3_systems():
    rng = np.random.default_rng(2)
    A = rng.normal(size=(4, 50, 3, 3)) + 3 * np.eye(3)
    b = rng.normal(size=(4, 50, 3))
    np.testing.assert_allclose(solve3(A, b), np.linalg.solve(A, b[..., None])[..., 0],
                               rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[1]}")
def test_the_exclusion_loop_names_the_same_points_as_the_straightforward_one(case,
                                                                                 monkeypatch):
    m, d = _data(*case)
    fast = identify(ErrorModel(m, case[1]), d)
    monkeypatch.setattr(calibration.fit.outliers, "residual_factors",
                        lambda fit, rows, included, jacobian=None:
                        straightforward_factors(fit, rows, included))
    monkeypatch.setattr(calibration.fit.outliers, "studentised_norms",
                        lambda r, f: np.linalg.norm(studentise(r, f), axis=1))
    slow = identify(ErrorModel(m, case[1]), d)
    assert fast.outliers.ids == slow.outliers.ids and fast.outliers.ids
    assert fast.outliers.rounds == slow.outliers.rounds
    assert fast.outliers.threshold_mm == pytest.approx(slow.outliers.threshold_mm, rel=1e-9)
    np.testing.assert_allclose(fast.values, slow.values, rtol=1e-9, atol=1e-15)
    assert fast.jacobian is None  # not kept once the test is done
