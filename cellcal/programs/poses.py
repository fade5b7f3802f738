"""Poses as controller languages write them, to and from 4x4 transforms (mm, rad).

URScript writes ``p[x, y, z, rx, ry, rz]``: metres and a rotation vector (rad). KRL writes
``{X, Y, Z, A, B, C}``: millimetres and Euler angles in degrees, R = Rz(A) Ry(B) Rx(C).
RAPID writes ``[[x, y, z], [q1, q2, q3, q4]]``: millimetres and a unit quaternion, scalar
first. Each has more than one way to write a rotation; a pose written back is the one
nearest the original's numbers (so a small correction changes the numbers a little).
"""

from __future__ import annotations

import numpy as np

from calibration.model.transforms import (
    make_T,
    matrix_to_quat,
    matrix_to_rotvec,
    quat_to_matrix,
    rotvec_to_matrix,
)


def ur_to_T(p) -> np.ndarray:
    """4x4 (mm) of a URScript pose (m, rotation vector)."""
    p = np.asarray(p, float)
    return make_T(rotvec_to_matrix(p[3:]), 1000.0 * p[:3])


def T_to_ur(T: np.ndarray, near=None) -> tuple[float, ...]:
    """URScript pose of a 4x4 (mm); the rotation vector nearest ``near``'s when given
    (r and r - 2π r/|r| are the same rotation)."""
    r = matrix_to_rotvec(T[:3, :3])
    if near is not None:
        ref = np.asarray(near, float)[3:]
        th = np.linalg.norm(r)
        if th > 1e-9:
            other = r * (th - 2 * np.pi) / th
            if np.linalg.norm(other - ref) < np.linalg.norm(r - ref):
                r = other
    return tuple(float(v) for v in np.concatenate([T[:3, 3] / 1000.0, r]))


def pose_trans(a, b, near=None) -> tuple[float, ...]:
    """URScript's ``pose_trans(a, b)``: b expressed in a, i.e. T(a) @ T(b)."""
    return T_to_ur(ur_to_T(a) @ ur_to_T(b), near)


def pose_add(a, b, near=None) -> tuple[float, ...]:
    """URScript's ``pose_add(a, b)``: positions added, rotations composed R(a) R(b)."""
    Ta, Tb = ur_to_T(a), ur_to_T(b)
    return T_to_ur(make_T(Ta[:3, :3] @ Tb[:3, :3], Ta[:3, 3] + Tb[:3, 3]), near)


def _rot(axis: int, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def krl_to_T(f) -> np.ndarray:
    """4x4 (mm) of a KRL frame (X, Y, Z mm; A, B, C deg, R = Rz(A) Ry(B) Rx(C))."""
    x, y, z, a, b, c = (float(v) for v in f)
    a, b, c = np.radians([a, b, c])
    return make_T(_rot(2, a) @ _rot(1, b) @ _rot(0, c), [x, y, z])


def T_to_krl(T: np.ndarray, near=None) -> tuple[float, ...]:
    """KRL frame of a 4x4 (mm): of the two Euler solutions (A, B, C) and
    (A + 180, 180 - B, C + 180), each angle shifted by whole turns, the one nearest
    ``near``'s angles; without ``near``, angles in (-180, 180]."""
    R = T[:3, :3]
    b = np.arctan2(-R[2, 0], np.hypot(R[0, 0], R[1, 0]))
    if np.hypot(R[0, 0], R[1, 0]) > 1e-9:
        a, c = np.arctan2(R[1, 0], R[0, 0]), np.arctan2(R[2, 1], R[2, 2])
    else:  # gimbal lock: put the whole turn about z into A
        a, c = np.arctan2(-R[0, 1], R[1, 1]), 0.0
    sols = np.degrees([[a, b, c], [a + np.pi, np.pi - b, c + np.pi]])
    ref = np.zeros(3) if near is None else np.asarray(near, float)[3:]
    sols = ref + (sols - ref + 180.0) % 360.0 - 180.0
    best = sols[int(np.argmin(np.abs(sols - ref).sum(axis=1)))]
    return tuple(float(v) for v in np.concatenate([T[:3, 3], best]))


def rapid_to_T(p) -> np.ndarray:
    """4x4 (mm) of a RAPID pose (x, y, z mm; q1, q2, q3, q4 a quaternion, scalar first,
    normalised here as the controller does)."""
    p = np.asarray(p, float)
    return make_T(quat_to_matrix(p[3:7]), p[:3])


def T_to_rapid(T: np.ndarray, near=None) -> tuple[float, ...]:
    """RAPID pose of a 4x4 (mm): the unit quaternion (q and -q are the same rotation) of
    the sign nearest ``near``'s, else with q1 >= 0."""
    q = matrix_to_quat(T[:3, :3])
    if near is not None and float(np.dot(q, np.asarray(near, float)[3:7])) < 0.0:
        q = -q
    return tuple(float(v) for v in np.concatenate([T[:3, 3], q]))
