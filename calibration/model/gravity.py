"""Gravity torques at every joint from the model's mass model (links + payload)."""

from __future__ import annotations

import numpy as np

from .kinematics import PRISMATIC_MM_PER_UNIT, ChainResult, cross
from .robot_model import RobotModel


def has_mass_model(model: RobotModel) -> bool:
    return model.links is not None or model.payload is not None


def gravity_torques(
    model: RobotModel, chain: ChainResult, payload_kg: np.ndarray | None = None
) -> np.ndarray:
    """Torque of gravity about each joint axis, for every pose.

    ``tau_j = u_j . sum_{k >= j} (c_k - o_j) x (m_k g)`` over the links distal to joint j
    and the payload (at the flange), with u_j, o_j the joint's axis and a point on it.

    Parameters
    ----------
    chain : a pass along the chain for the poses (its link frames are used)
    payload_kg : (n,) payload mass per pose, overriding the model's (centre from the model's
        payload ``com``, else the flange origin)

    Returns
    -------
    array, shape (n, N), N·m. Positive = gravity pulls the joint in its positive direction.
    A prismatic joint's entry is the generalised force per internal unit of travel
    (N · mm/unit / 1000), so that ``tau = -dV/dq`` holds for every joint.
    """
    n, N = chain.joint_axes.shape[:2]
    g = np.asarray(model.gravity, float)  # m/s^2
    masses = np.array([l.mass_kg for l in model.links]) if model.links else np.zeros(N)
    coms = np.array([l.com for l in model.links], float) if model.links else np.zeros((N, 3))
    # link k (0-based) hangs on frame k + 1
    R = chain.frames_R[:, 1:]  # (n, N, 3, 3)
    c = chain.frames_p[:, 1:] + np.einsum("nkij,kj->nki", R, coms)  # (n, N, 3) mm
    mc = masses[None, :, None] * c
    S = np.cumsum(mc[:, ::-1], axis=1)[:, ::-1]  # sum over k >= j of m_k c_k
    M = np.broadcast_to(np.cumsum(masses[::-1])[::-1], (n, N)).copy()
    p_com = np.array(model.payload.com, float) if model.payload else np.zeros(3)
    if payload_kg is not None:
        mp = np.broadcast_to(np.asarray(payload_kg, float), (n,))
    else:
        mp = np.full(n, model.payload.mass_kg if model.payload else 0.0)
    cp = chain.base_p_flange + chain.base_R_flange @ p_com  # (n, 3)
    S = S + (mp[:, None] * cp)[:, None, :]
    M = M + mp[:, None]
    moment = cross(S - M[:, :, None] * chain.joint_origins, np.broadcast_to(g, S.shape))
    tau = np.einsum("nji,nji->nj", chain.joint_axes, moment) / 1000.0
    slide = chain.prismatic
    if slide is not None:
        # a prismatic joint feels the weight along its travel, per internal unit of travel
        tau[:, slide] = (chain.joint_axes[:, slide] @ g) * M[:, slide] * (
            PRISMATIC_MM_PER_UNIT / 1000.0)
    return tau


def potential_energy(
    model: RobotModel, chain: ChainResult, payload_kg: np.ndarray | None = None
) -> np.ndarray:
    """Gravitational potential energy of links and payload, (n,) J (for tests: tau = -dV/dq)."""
    g = np.asarray(model.gravity, float)
    N = chain.joint_axes.shape[1]
    masses = np.array([l.mass_kg for l in model.links]) if model.links else np.zeros(N)
    coms = np.array([l.com for l in model.links], float) if model.links else np.zeros((N, 3))
    c = chain.frames_p[:, 1:] + np.einsum("nkij,kj->nki", chain.frames_R[:, 1:], coms)
    V = -np.einsum("k,nki,i->n", masses, c, g)
    p_com = np.array(model.payload.com, float) if model.payload else np.zeros(3)
    if payload_kg is not None:
        mp = np.broadcast_to(np.asarray(payload_kg, float), (c.shape[0],))
    else:
        mp = np.full(c.shape[0], model.payload.mass_kg if model.payload else 0.0)
    cp = chain.base_p_flange + chain.base_R_flange @ p_com
    V = V - mp * (cp @ g)
    return V / 1000.0
