"""Generating the 20 zero-point postures: 5 on each of 4 vertical planes through the target,
by batched inverse kinematics on a given (true) chain. The capture routine ``zero20`` and
the tests use :func:`zero20_postures`.

Lengths mm, angles rad.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from ..model.inverse import ChainFK, solve_ik, solve_ik_multistart, wrap_to_pi


def _frame_from_z(z: np.ndarray, x_hint: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) with z axis z (n, 3) and x axis as near x_hint (n, 3)."""
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    x = x_hint - np.sum(x_hint * z, axis=1, keepdims=True) * z
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=2)


def zero20_directions(target_mm: np.ndarray, *, n_planes: int = 4, per_plane: int = 5,
                      tilts_deg: npt.ArrayLike = (-35.0, -17.5, 0.0, 17.5, 35.0),
                      spin_deg: float = 25.0, about: npt.ArrayLike | None = None,
                      axis_flange: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Flange orientations for the 4-plane, 20-posture routine.

    Plane k is the plane through the target that contains the direction ``about`` (unit;
    default straight down: vertical planes), at azimuth ``k·45°`` about it from the
    target's own azimuth; in it the tool axis (flange z, or ``axis_flange`` given in the
    flange frame: the SMR's opening, which a tracker must face) is tilted from ``about``
    by each of ``tilts_deg``, and the flange is turned about the tool axis by
    ``spin_deg`` times the posture's index in the plane (varied wrist postures). By
    default the tool points at the target from above; with ``about`` = the direction from
    the target to a tracker and tilts within the reflector's acceptance the tracker sees
    every posture's SMR.

    Returns
    -------
    R : (n_planes·per_plane, 3, 3) flange orientations, base frame
    plane : (n_planes·per_plane,) plane number 1..n_planes
    """
    t = np.asarray(target_mm, float)
    az0 = math.atan2(t[1], t[0])
    c = np.array([0.0, 0.0, -1.0]) if about is None else np.asarray(about, float)
    c = c / np.linalg.norm(c)
    e1 = np.array([math.cos(az0), math.sin(az0), 0.0])
    if abs(float(e1 @ c)) > 0.9:
        e1 = np.array([0.0, 0.0, 1.0])
    e1 = e1 - (e1 @ c) * c
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e1, c)
    tilts = np.radians(np.asarray(tilts_deg, float))[:per_plane]
    az = np.arange(n_planes) * np.pi / n_planes
    A, T = np.meshgrid(az, tilts, indexing="ij")
    A, T = A.ravel(), T.ravel()
    h = np.cos(A)[:, None] * e1 + np.sin(A)[:, None] * e2
    z = np.cos(T)[:, None] * c + np.sin(T)[:, None] * h
    normal = np.cross(h, c)
    spin = np.radians(spin_deg) * np.tile(np.arange(per_plane) - per_plane // 2, n_planes)
    # turn the in-plane normal about the tool axis by the spin
    x = (np.cos(spin)[:, None] * normal + np.sin(spin)[:, None] * np.cross(z, normal))
    plane = np.repeat(np.arange(1, n_planes + 1), per_plane)
    R = _frame_from_z(z, x)
    if axis_flange is not None:  # turn the flange so its axis_flange lies along z
        a = np.asarray(axis_flange, float)[None]
        R = R @ np.swapaxes(_frame_from_z(a, np.array([[1.0, 0.0, 0.0]]) if abs(a[0, 0]) < 0.9
                                          * np.linalg.norm(a) else np.array([[0.0, 1.0, 0.0]])),
                            1, 2)
    return R, plane


def zero20_postures(
    convention: str,
    table: np.ndarray,
    tool_mm: np.ndarray,
    target_mm: np.ndarray,
    *,
    q_seed: np.ndarray | None = None,
    limits: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    n_starts: int = 32,
    flip_shoulder: bool = True,
    **direction_options: Any,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """20 postures (5 on each of 4 planes) that put the tool point on one target.

    Inverse kinematics (batched, several starts) on the given chain, normally the
    *true* robot's: the returned joints are the true joint angles. Planes 1 and 3 use
    one arm configuration, planes 2 and 4 (with ``flip_shoulder``) the other shoulder
    configuration (joint 1 turned by roughly 150-180°): a single point seen from one
    configuration only hardly determines joint 2's offset, whose effect then barely
    differs from a shift of the target.

    Parameters
    ----------
    convention, table : the chain (table (N, 5), rad and mm)
    tool_mm : (3,) tool point in the flange frame, mm
    target_mm : (3,) the fixed target point, base frame, mm
    q_seed : (N,) preferred configuration (rad); default: the best-conditioned IK
        solution of the middle posture
    limits : (N, 2) joint limits, rad
    rng : for the random starts
    flip_shoulder : use the other shoulder configuration on planes 2 and 4
    direction_options : passed to :func:`zero20_directions`

    Returns
    -------
    q : (20, N) joint angles, rad
    plane : (20,) plane numbers 1..4
    success : (20,) bool, IK reached the target exactly
    """
    rng = rng or np.random.default_rng(0)
    R, plane = zero20_directions(target_mm, **direction_options)
    p_flange = np.asarray(target_mm, float) - R @ np.asarray(tool_mm, float)
    # flange pose targets: the tool point lands on the target
    flange = ChainFK(convention, table, np.zeros(3))
    N = flange.n_joints
    lim = limits if limits is not None else np.tile([-np.pi, np.pi], (N, 1))
    lo, hi = np.maximum(lim[:, 0], -np.pi), np.minimum(lim[:, 1], np.pi)
    seeds = rng.uniform(lo, hi, size=(n_starts, N))
    configs = _configurations(flange, p_flange, R, seeds, limits, q_seed)
    if not flip_shoulder or len(configs) == 1:
        configs = configs[:1]
    ref = np.array([configs[(k - 1) % len(configs)] for k in plane])
    res = solve_ik_multistart(flange, p_flange, R, np.vstack([configs, seeds]), reference=ref,
                              limits=limits, max_iter=200)
    q = ref + wrap_to_pi(res.q - ref)
    if limits is not None:  # prefer the turn that is within the limits
        q = np.where(q > limits[:, 1], q - 2 * np.pi, np.where(q < limits[:, 0], q + 2 * np.pi, q))
    return q, plane, res.success


def _configurations(flange: ChainFK, p_flange: np.ndarray, R: np.ndarray, seeds: np.ndarray,
                    limits: np.ndarray | None, q_seed: np.ndarray | None) -> np.ndarray:
    """One or two reference configurations for the middle posture: the best-conditioned
    IK solution (largest smallest singular value of the scaled Jacobian) or ``q_seed``,
    and the best-conditioned one with joint 1 at least 90° away (the other shoulder)."""
    mid = len(R) // 2
    res = solve_ik(flange, seeds, p_flange[mid], R[mid], limits=limits, max_iter=200)
    q = wrap_to_pi(res.q[res.success])
    if len(q) == 0:
        return np.atleast_2d(seeds[0] if q_seed is None else q_seed)
    _, _, Jp, Jw = flange(q)
    smin = np.linalg.svd(np.concatenate([Jp / 1000.0, Jw], axis=1), compute_uv=False)[:, -1]
    first = np.asarray(q_seed, float) if q_seed is not None else q[int(np.argmax(smin))]
    other = np.abs(wrap_to_pi(q[:, 0] - first[0])) > np.pi / 2
    if not other.any():
        return first[None]
    second = q[other][int(np.argmax(smin[other]))]
    return np.stack([first, second])
