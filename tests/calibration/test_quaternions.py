"""Quaternion, rotation-matrix and rotation-vector helpers: round trips, agreement with
the scalar Rodrigues functions, the awkward angles (zero, tiny, half turn), vectorised."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calibration.model.transforms import (
    matrices_to_rotvecs,
    matrix_to_quat,
    matrix_to_rotvec,
    quat_angle,
    quat_multiply,
    quat_to_matrix,
    quat_to_rotvec,
    random_rotation,
    rotvec_to_matrix,
    rotvec_to_quat,
    rotvecs_to_matrices,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)
quats = arrays(float, 4, elements=finite).filter(lambda q: np.linalg.norm(q) > 1e-3)


def _same_rotation(qa, qb, atol=1e-12):
    """q and -q are the same rotation."""
    qa, qb = np.asarray(qa), np.asarray(qb)
    sign = np.sign(np.sum(qa * qb, -1, keepdims=True))
    np.testing.assert_allclose(qa, sign * qb, atol=atol)


@settings(max_examples=200, deadline=None)
@given(quats)
def test_quaternion_matrix_round_trip_is_the_same_rotation(q):
    q = q / np.linalg.norm(q)
    R = quat_to_matrix(q)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    back = matrix_to_quat(R)
    assert back[0] >= 0
    _same_rotation(back, q, atol=1e-11)


@settings(max_examples=200, deadline=None)
@given(arrays(float, 3, elements=st.floats(-3.1, 3.1, allow_nan=False)))
def test_rotation_vectors_agree_with_rodrigues(r):
    np.testing.assert_allclose(rotvecs_to_matrices(r), rotvec_to_matrix(r), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(rotvec_to_quat(r)), rotvec_to_matrix(r),
                               atol=1e-12)
    if np.linalg.norm(r) < np.pi - 1e-3:  # below a half turn the vector is unique
        np.testing.assert_allclose(quat_to_rotvec(rotvec_to_quat(r)), r, atol=1e-10)
        np.testing.assert_allclose(matrices_to_rotvecs(rotvec_to_matrix(r)),
                                   matrix_to_rotvec(rotvec_to_matrix(r)), atol=1e-9)


def test_awkward_angles_zero_tiny_and_half_turns():
    for r in ([0.0, 0.0, 0.0], [1e-12, -2e-12, 3e-12], [1e-6, 0.0, 0.0], [np.pi, 0, 0],
              [0, np.pi, 0], [0, 0, np.pi], np.pi * np.array([1.0, 1.0, 0.0]) / np.sqrt(2)):
        r = np.asarray(r, float)
        R = rotvec_to_matrix(r)
        q = matrix_to_quat(R)
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-12)
        got = quat_to_rotvec(q)
        np.testing.assert_allclose(rotvec_to_matrix(got), R, atol=1e-12)
        assert np.linalg.norm(got) == pytest.approx(np.linalg.norm(r), abs=1e-12)
    # the small-angle branch keeps relative precision
    np.testing.assert_allclose(quat_to_rotvec(rotvec_to_quat([3e-9, -1e-9, 2e-9])),
                               [3e-9, -1e-9, 2e-9], rtol=1e-12)


def test_everything_is_vectorised_over_leading_axes():
    rng = np.random.default_rng(1)
    R = np.stack([random_rotation(rng) for _ in range(12)]).reshape(3, 4, 3, 3)
    q = matrix_to_quat(R)
    assert q.shape == (3, 4, 4)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-12)
    r = matrices_to_rotvecs(R)
    assert r.shape == (3, 4, 3)
    np.testing.assert_allclose(rotvecs_to_matrices(r), R, atol=1e-12)
    for i in range(3):
        for j in range(4):
            np.testing.assert_allclose(rotvec_to_matrix(r[i, j]), R[i, j], atol=1e-12)


def test_product_and_angle():
    rng = np.random.default_rng(2)
    A, B = random_rotation(rng), random_rotation(rng)
    qa, qb = matrix_to_quat(A), matrix_to_quat(B)
    np.testing.assert_allclose(quat_to_matrix(quat_multiply(qa, qb)), A @ B, atol=1e-12)
    small = rotvec_to_quat(np.array([0.0, 1e-7, 0.0]))
    assert quat_angle(qa, quat_multiply(qa, small)) == pytest.approx(1e-7, rel=1e-9)
    assert quat_angle(qa, -qa) == pytest.approx(0.0, abs=1e-15)
    angle = np.linalg.norm(matrix_to_rotvec(A.T @ B))
    assert quat_angle(qa, qb) == pytest.approx(angle, abs=1e-12)


def test_random_rotation_is_unchanged_bit_for_bit():
    """The simulated truths draw their base orientation with it: same seed, same bits."""
    rng = np.random.default_rng(7)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    old = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    assert np.array_equal(random_rotation(np.random.default_rng(7)), old)
