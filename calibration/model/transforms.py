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


def matrix_to_rotvec_each(R: np.ndarray) -> np.ndarray:
    """:func:`matrix_to_rotvec` of every matrix of a stack (n, 3, 3), (n, 3): the same
    numbers, the same formula vectorised (the rare angle near pi one at a time)."""
    R = np.asarray(R, float)
    c = np.clip((R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2] - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]],
                 axis=1)
    small = th < 1e-8
    s = np.sin(th)
    out = (th / (2 * np.where(small, 1.0, s)))[:, None] * w
    out[small] = 0.5 * w[small]
    for i in np.flatnonzero(~small & (np.pi - th < 1e-4)):
        out[i] = matrix_to_rotvec(R[i])
    return out


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
    return _unit_quat_to_matrix(q)


# ---------------------------------------------------------------- quaternions
# Unit quaternions are (w, x, y, z), scalar first (FORMATS §1 ``qw, qx, qy, qz``), and
# mean the same rotation as a matrix R that turns vectors of the rotated frame into the
# reference frame: q of ``tracker_R_target`` is the target's orientation in the tracker.


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z), shape (..., 4), to rotation matrices (..., 3, 3).

    The quaternion is normalised first (a reading rounded to a few digits stays a proper
    rotation); a zero quaternion is an error of the caller (NaN rows).
    """
    q = np.asarray(q, float)
    return _unit_quat_to_matrix(q / np.linalg.norm(q, axis=-1, keepdims=True))


def _unit_quat_to_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) to unit quaternions (..., 4), (w, x, y, z) with w >= 0.

    Shepperd's method, branch by branch on the largest of (trace, R_00, R_11, R_22), so
    no division by a small number near a half turn.
    """
    R = np.asarray(R, float)
    m = R.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    diag = np.diagonal(m, axis1=1, axis2=2)
    pick = np.argmax(np.concatenate([tr[:, None], diag], 1), 1)
    q = np.empty((m.shape[0], 4))
    r21, r12 = m[:, 2, 1], m[:, 1, 2]
    r02, r20 = m[:, 0, 2], m[:, 2, 0]
    r10, r01 = m[:, 1, 0], m[:, 0, 1]
    s = np.sqrt(np.maximum(1.0 + np.stack([tr, 2 * diag[:, 0] - tr, 2 * diag[:, 1] - tr,
                                             2 * diag[:, 2] - tr], 1), 1e-300))
    s = s[np.arange(len(pick)), pick]
    cols = {
        0: (0.5 * s, (r21 - r12) / (2 * s), (r02 - r20) / (2 * s), (r10 - r01) / (2 * s)),
        1: ((r21 - r12) / (2 * s), 0.5 * s, (r01 + r10) / (2 * s), (r02 + r20) / (2 * s)),
        2: ((r02 - r20) / (2 * s), (r01 + r10) / (2 * s), 0.5 * s, (r12 + r21) / (2 * s)),
        3: ((r10 - r01) / (2 * s), (r02 + r20) / (2 * s), (r12 + r21) / (2 * s), 0.5 * s),
    }
    for k, c in cols.items():
        rows = pick == k
        q[rows] = np.stack(c, 1)[rows]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(R.shape[:-2] + (4,))


def rotvec_to_quat(r: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad), shape (..., 3), to unit quaternions (..., 4)."""
    r = np.asarray(r, float)
    th = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * th
    # sin(th/2)/th, with its series below 1e-4 rad (relative error < 1e-17 there)
    k = np.where(th < 1e-4, 0.5 - th**2 / 48.0, np.sin(half) / np.where(th == 0, 1.0, th))
    return np.concatenate([np.cos(half), k * r], -1)


def quat_to_rotvec(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) to rotation vectors (rad), shape (..., 3), |r| <= pi.

    ``q`` and ``-q`` give the same vector (the shorter turn); the angle comes from
    ``atan2(|v|, w)``, accurate for small and for half turns alike.
    """
    q = np.asarray(q, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    v = q[..., 1:]
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    th = 2.0 * np.arctan2(s, q[..., :1])
    k = np.where(s < 1e-8, 2.0 / np.maximum(q[..., :1], 1e-300), th / np.where(s == 0, 1.0, s))
    return k * v


def rotvecs_to_matrices(r: np.ndarray) -> np.ndarray:
    """Vectorised :func:`rotvec_to_matrix`: rotation vectors (..., 3) to matrices (..., 3, 3)."""
    return quat_to_matrix(rotvec_to_quat(r))


def matrices_to_rotvecs(R: np.ndarray) -> np.ndarray:
    """Vectorised :func:`matrix_to_rotvec`: matrices (..., 3, 3) to rotation vectors (..., 3)."""
    return quat_to_rotvec(matrix_to_quat(R))


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` of quaternions (..., 4): the rotation ``R(a) @ R(b)``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw], -1)


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The angle (rad, in [0, pi]) of the rotation from ``a`` to ``b``, quaternions (..., 4):
    ``2 atan2(|a* ⊗ b|_v, |a·b|)``, exact for tiny angles (no arccos near 1)."""
    a = np.asarray(a, float) / np.linalg.norm(a, axis=-1, keepdims=True)
    b = np.asarray(b, float) / np.linalg.norm(b, axis=-1, keepdims=True)
    conj = a * np.array([1.0, -1.0, -1.0, -1.0])
    d = quat_multiply(conj, b)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))
