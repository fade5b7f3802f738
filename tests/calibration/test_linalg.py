"""The numpy-only linear algebra and chi(3) quantile of the default calibrate path agree
with scipy's to rounding (calibration/numerics/linalg.py, calibration/numerics/chi3.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.special

from calibration.numerics.chi3 import chi3_isf, chi3_sf
from calibration.numerics.linalg import cho_solve, cholesky_upper, qr_pivoted, triangular_inverse


def _matrices(rng, count=300):
    """Random matrices: tall, wide, square, with exactly dependent and tiny columns."""
    for t in range(count):
        m, n = int(rng.integers(1, 30)), int(rng.integers(1, 20))
        A = rng.standard_normal((m, n))
        if t % 3 == 0 and n > 2:
            A[:, 1] = 2.0 * A[:, 0]
            A[:, -1] = A[:, 0] - 0.3 * A[:, 1]
        if t % 5 == 0:
            A[:, : n // 2] *= np.exp(rng.uniform(-10, 0, n // 2))
        yield A


def test_pivoted_qr_ranks_columns_as_lapack():
    rng = np.random.default_rng(0)
    for A in _matrices(rng):
        _, R1, p1 = scipy.linalg.qr(A, mode="economic", pivoting=True)
        R2, p2 = qr_pivoted(A)
        assert R2.shape == R1.shape
        np.testing.assert_allclose(R2.T @ R2, (A[:, p2]).T @ A[:, p2], atol=1e-12)
        d1, d2 = np.abs(np.diag(R1)), np.abs(np.diag(R2))
        np.testing.assert_allclose(d2, d1, rtol=1e-9, atol=1e-12 * max(d1.max(), 1.0))
        big = d1 > 1e-9 * max(d1.max(), 1e-300)  # below: rounding decides the order
        assert list(p2[: d2.size][big]) == list(p1[: d1.size][big])


def test_pivoted_qr_takes_the_first_of_equal_columns_and_stops_at_zero():
    A = np.array([[1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])
    R, piv = qr_pivoted(A)
    assert list(piv[:1]) == [0] and abs(R[0, 0]) == 1.0 and R[1, 1] == 0.0
    R, piv = qr_pivoted(np.zeros((3, 2)))
    assert not R.any() and list(piv) == [0, 1]


def test_cholesky_solves_as_scipy():
    rng = np.random.default_rng(1)
    B = rng.standard_normal((12, 12))
    A = B @ B.T + 1e-3 * np.eye(12)
    U = cholesky_upper(A)
    np.testing.assert_allclose(U, np.triu(scipy.linalg.cho_factor(A)[0]), atol=1e-12)
    b = rng.standard_normal((12, 3))
    np.testing.assert_allclose(cho_solve(U, b), scipy.linalg.cho_solve((U, False), b),
                               rtol=1e-9)
    np.testing.assert_allclose(triangular_inverse(U) @ U, np.eye(12), atol=1e-9)
    with pytest.raises(np.linalg.LinAlgError):
        cholesky_upper(-A)


def test_chi3_quantile_and_tail_match_scipy():
    for p in [*np.logspace(-300, -0.01, 400), 0.5, 0.01 / 150, 0.9]:
        k = math.sqrt(scipy.special.chdtri(3, p))
        assert chi3_isf(p) == pytest.approx(k, rel=1e-14), p
        assert chi3_sf(k) == pytest.approx(scipy.special.chdtrc(3, k * k), rel=1e-12)
    assert chi3_isf(0.5) == pytest.approx(math.sqrt(2 * scipy.special.gammaincinv(1.5, 0.5)),
                                          rel=1e-15)
    for bad in (0.0, 1.0, -1.0, float("nan")):
        with pytest.raises(ValueError):
            chi3_isf(bad)


@pytest.mark.parametrize("n", [97, 150, 401])
def test_large_triangular_matrices_invert_in_halves(n):
    rng = np.random.default_rng(n)
    B = rng.standard_normal((n + 20, n))
    U = cholesky_upper(B.T @ B)
    for T in (U, U.T):
        np.testing.assert_allclose(triangular_inverse(T) @ T, np.eye(n), atol=1e-9)
        Ti = triangular_inverse(T)
        assert not (np.tril(Ti, -1) if T is U else np.triu(Ti, 1)).any()
