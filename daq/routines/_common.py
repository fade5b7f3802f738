"""Helpers shared by the routines: start postures, nominal points, expected joints of
Cartesian targets."""

from __future__ import annotations

import numpy as np

from calibration.inverse import ChainFK, solve_ik


def default_start(model) -> np.ndarray:
    """A start posture (rad): the middle of each joint's limits, clipped to +-180 deg."""
    lim = np.clip(model.limits_rad(), -np.pi, np.pi)
    return lim.mean(axis=1)


def nominal_point(model, q) -> np.ndarray:
    """Nominal tool point (mm, base frame) at joints q (rad, (N,))."""
    return ChainFK.from_model(model).point(np.asarray(q, float)[None])[0]


def expected_joints(model, xyz: np.ndarray, q_start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Joints at which the nominal model reaches each Cartesian target, near ``q_start``.

    What a controller's linear move does: position targets keeping the start's
    flange orientation for 6+ joint arms, position only for smaller arms; each
    solved from the previous target's joints (a chain of moves).

    Returns
    -------
    q : (n, N) rad
    ok : (n,) bool, the target was reached (else the dry run names it unreachable)
    """
    fk = ChainFK.from_model(model)
    q_prev = np.asarray(q_start, float)
    R = fk(q_prev[None])[1][0] if model.n_joints >= 6 else None
    out, ok = [], []
    for p in np.atleast_2d(np.asarray(xyz, float)):
        r = solve_ik(fk, q_prev, p, R, limits=model.limits_rad(), success_mm=1e-3,
                     success_rad=1e-6)
        out.append(r.q[0])
        ok.append(bool(r.success[0]))
        if r.success[0]:
            q_prev = r.q[0]
    return np.array(out), np.array(ok)
