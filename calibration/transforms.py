"""Rotations and rigid transforms on plain arrays (rad, mm)."""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix [v]x, shape (..., 3, 3)."""
    v = np.asarray(v, float)
    z = np.zeros(v.shape[:-1])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def rotvec_to_matrix(r: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vector (rad), shape (3,), to a rotation matrix (3, 3)."""
    r = np.asarray(r, float)
    th = float(np.linalg.norm(r))
    K = skew(r)
    if th < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + np.sin(th) / th * K + (1 - np.cos(th)) / th**2 * K @ K


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation matrix (3, 3) to a rotation vector (rad), |r| <= pi."""
    R = np.asarray(R, float)
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-8:
        return 0.5 * w
    if np.pi - th < 1e-4:
        # near pi: the axis is the dominant column of R + I
        M = (R + np.eye(3)) / 2
        k = int(np.argmax(np.diag(M)))
        axis = M[:, k] / np.sqrt(M[k, k])
        if np.dot(axis, w) < 0:
            axis = -axis
        return axis * th
    return th / (2 * np.sin(th)) * w


def right_jacobian(r: np.ndarray) -> np.ndarray:
    """Right Jacobian of SO(3) at rotation vector r: R(r + dr) ~= R(r) exp([J_r dr]x)."""
    r = np.asarray(r, float)
    th = float(np.linalg.norm(r))
    K = skew(r)
    if th < 1e-6:
        return np.eye(3) - 0.5 * K + K @ K / 6.0
    return (
        np.eye(3)
        - (1 - np.cos(th)) / th**2 * K
        + (th - np.sin(th)) / th**3 * K @ K
    )


def make_T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def fit_rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Best-fit rotation (Kabsch), no translation: R minimising sum |R src_i - dst_i|^2.

    Parameters
    ----------
    src, dst : array, shape (n, 3)
        Paired vectors (e.g. displacements, mm), n >= 2 not all parallel for a unique R.

    Returns
    -------
    R : array, shape (3, 3), a proper rotation (det +1)
    """
    H = np.asarray(src, float).T @ np.asarray(dst, float)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    return Vt.T @ np.diag([1.0, 1.0, d]) @ U.T


def fit_rigid(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best-fit rigid transform (Kabsch): R, t minimising |R src + t - dst|, points (n, 3)."""
    src = np.asarray(src, float)
    dst = np.asarray(dst, float)
    cs, cd = src.mean(0), dst.mean(0)
    R = fit_rotation(src - cs, dst - cd)
    return R, cd - R @ cs


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
