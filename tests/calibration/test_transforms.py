"""Kabsch fits: the rotation between paired displacements, and the rigid transform."""

import numpy as np

from calibration.model.transforms import fit_rigid, fit_rotation, random_rotation


def test_fit_rotation_recovers_a_rotation_from_three_probe_displacements():
    rng = np.random.default_rng(4)
    R = random_rotation(rng)
    a = 5.0 * np.eye(3)  # three probe moves along the base axes, mm
    b = a @ R.T + rng.normal(0.0, 1e-4, (3, 3))  # the same moves as the tracker sees them
    got = fit_rotation(a, b)
    np.testing.assert_allclose(got, R, atol=1e-4)
    np.testing.assert_allclose(got @ got.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(got) > 0


def test_fit_rotation_is_proper_for_planar_and_reflected_pairs():
    rng = np.random.default_rng(5)
    R = random_rotation(rng)
    a = rng.normal(size=(2, 3))  # two displacements: a plane, the third axis from det +1
    got = fit_rotation(a, a @ R.T)
    np.testing.assert_allclose(got, R, atol=1e-9)
    mirrored = fit_rotation(a, a * [1.0, 1.0, -1.0])  # no rotation fits a mirror exactly
    assert np.linalg.det(mirrored) > 0


def test_fit_rigid_recovers_the_transform():
    rng = np.random.default_rng(6)
    R, t = random_rotation(rng), rng.normal(0.0, 1000.0, 3)
    src = rng.normal(0.0, 500.0, (20, 3))
    R_fit, t_fit = fit_rigid(src, src @ R.T + t)
    np.testing.assert_allclose(R_fit, R, atol=1e-12)
    np.testing.assert_allclose(t_fit, t, atol=1e-9)


def test_rotation_vectors_of_a_stack_are_those_of_each_matrix():
    from calibration.model.transforms import (
        matrix_to_rotvec,
        matrix_to_rotvec_each,
        random_rotation,
        rotvec_to_matrix,
    )

    rng = np.random.default_rng(5)
    R = [random_rotation(rng) for _ in range(200)]
    R += [rotvec_to_matrix(np.array([1e-10, 0.0, 0.0])), np.eye(3),
          rotvec_to_matrix(np.array([0.0, np.pi - 1e-6, 0.0])),
          rotvec_to_matrix(np.array([0.3, -0.2, 0.1]))]
    R = np.array(R)
    got = matrix_to_rotvec_each(R)
    want = np.array([matrix_to_rotvec(r) for r in R])
    assert np.array_equal(got, want)  # the same numbers, bit for bit
