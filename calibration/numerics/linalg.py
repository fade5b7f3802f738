"""Dense linear algebra of the default identification on numpy alone: Cholesky solves,
a triangular factor's inverse and QR with column pivoting.

Why not scipy.linalg: importing any part of scipy (1.17) takes about 0.17 s, half of a
``cellcal calibrate`` of 150 poses, for three LAPACK calls on matrices of a few dozen
columns. numpy's LAPACK does the factorisations (``potrf``, ``gesv``); the pivoted QR,
which numpy lacks, is Householder QR with LAPACK's pivot rule (``geqp3``: the remaining
column of largest norm, the first of equals), in Python over the columns: a few dozen
steps of numpy products; a large triangular matrix is inverted in halves (numpy has no
triangular inverse). Results agree with scipy's to rounding.
"""

from __future__ import annotations

import numpy as np


def cholesky_upper(A: np.ndarray) -> np.ndarray:
    """U upper triangular with ``A = UᵀU`` (``scipy.linalg.cho_factor``'s default);
    :class:`numpy.linalg.LinAlgError` when A is not positive definite."""
    return np.linalg.cholesky(A).T


#: a triangular matrix up to this order is inverted by numpy's LU in one call; a larger
#: one in halves (recursively), whose off-diagonal block is two matrix products: the LU
#: of a triangular matrix costs as much as a full one's (2/3 n³, and 2 n³ more to
#: invert), the halves the triangular n³/3
TRIANGULAR_BLOCK = 96


def _triangular_inverse(T: np.ndarray, upper: bool) -> np.ndarray:
    n = T.shape[0]
    if n <= TRIANGULAR_BLOCK:
        return np.linalg.solve(T, np.eye(n))
    h = n // 2
    Ai, Ci = _triangular_inverse(T[:h, :h], upper), _triangular_inverse(T[h:, h:], upper)
    out = np.zeros((n, n))
    out[:h, :h], out[h:, h:] = Ai, Ci
    if upper:  # [A B; 0 C]⁻¹ = [A⁻¹ -A⁻¹ B C⁻¹; 0 C⁻¹]
        out[:h, h:] = -(Ai @ T[:h, h:]) @ Ci
    else:  # [A 0; B C]⁻¹ = [A⁻¹ 0; -C⁻¹ B A⁻¹ C⁻¹]
        out[h:, :h] = -(Ci @ T[h:, :h]) @ Ai
    return out


def cho_solve(U: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with ``UᵀU x = b``, U from :func:`cholesky_upper`."""
    return np.linalg.solve(U, np.linalg.solve(U.T, b))


def triangular_inverse(U: np.ndarray) -> np.ndarray:
    """U⁻¹ of a non-singular triangular U (upper or lower)."""
    upper = not np.tril(U, -1).any()
    return _triangular_inverse(U, upper)


def qr_pivoted(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """QR with column pivoting, ``A[:, piv] = Q R``: R (min(m, n), n) upper triangular with
    non-increasing ``|diag(R)|``, and piv (n,) the column order (R and P of
    ``scipy.linalg.qr(A, mode="economic", pivoting=True)``; Q is not formed).

    At each step the column of the remaining block with the largest norm comes first
    (the first of equal ones), then one Householder reflection zeroes it below the
    diagonal."""
    R = np.array(A, dtype=float, copy=True)
    m, n = R.shape
    piv = np.arange(n)
    for j in range(min(m, n)):
        rest = R[j:, j:]
        c = j + int(np.argmax(np.einsum("ij,ij->j", rest, rest)))
        if c != j:
            R[:, [j, c]] = R[:, [c, j]]
            piv[[j, c]] = piv[[c, j]]
        x = R[j:, j]
        alpha = float(np.linalg.norm(x))
        if alpha == 0.0:  # every remaining column is zero
            break
        v = x.copy()
        v[0] += alpha if v[0] >= 0 else -alpha
        v /= np.linalg.norm(v)
        R[j:, j:] -= 2.0 * np.outer(v, v @ R[j:, j:])
        R[j + 1:, j] = 0.0
    return np.triu(R[: min(m, n)]), piv
