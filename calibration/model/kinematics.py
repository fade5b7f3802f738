"""Forward kinematics of serial chains, vectorised over poses, with exact Jacobians.

A chain is a product of elementary transforms, per joint row (angles rad, lengths mm):

- ``dh``  (standard Denavit-Hartenberg, with the Hayati tilt beta):
  ``Rz(theta) . Tz(d) . Tx(a) . Rx(alpha) . Ry(beta)``
- ``mdh`` (modified, Craig; a and alpha are a_{i-1}, alpha_{i-1}):
  ``Rx(alpha) . Tx(a) . Ry(beta) . Rz(theta) . Tz(d)``

with ``theta = q + theta_offset`` for a revolute joint. A prismatic joint (``prismatic``
mask) keeps theta fixed and slides instead: ``d + q·180/π`` mm. Its internal variable is
the travel in mm scaled by π/180, like an angle in rad: wherever files hold joint angles in
degrees they hold a prismatic joint's travel in millimetres, and every edge that converts
deg <-> rad converts the travel unchanged (``PRISMATIC_MM_PER_UNIT``).

Rotations act on the frame's own axes, so a
frame is carried as its three axis columns and its origin, each of shape
(n_poses, 3); an elementary rotation mixes two columns. No loop over poses: the
only Python loop is over the ~5 elementary transforms of each joint.

The derivative of the measured point P with respect to the parameter of an
elementary transform is exact and cheap: a rotation about the unit axis u
through o moves P by ``u x (P - o)`` per radian; a translation along u moves it
by ``u`` per millimetre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .robot_model import RobotModel

# column index of each parameter in the (n_joints, 5) table
THETA, D, A, ALPHA, BETA = range(5)
#: mm of travel per internal unit of a prismatic joint (see the module docstring)
PRISMATIC_MM_PER_UNIT = 180.0 / np.pi
_TRAVEL = D  # the column a prismatic joint's travel adds to

# elementary sequence per convention: (kind, axis, column)
_SEQUENCE = {
    "dh": (("r", 2, THETA), ("t", 2, D), ("t", 0, A), ("r", 0, ALPHA), ("r", 1, BETA)),
    "mdh": (("r", 0, ALPHA), ("t", 0, A), ("r", 1, BETA), ("r", 2, THETA), ("t", 2, D)),
}


def cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise cross product of arrays of 3-vectors (faster than np.cross for small stacks)."""
    out = np.empty(np.broadcast_shapes(u.shape, v.shape))
    out[..., 0] = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    out[..., 1] = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    out[..., 2] = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return out


@dataclass
class ChainResult:
    """Everything one pass along the chain yields, for n poses and N joints.

    Attributes
    ----------
    base_p_tcp : (n, 3) the tool point (target centre) in the robot base frame, mm
    base_R_flange : (n, 3, 3) flange orientation in the base frame (columns are the flange
        axes)
    base_p_flange : (n, 3) flange origin in the base frame, mm
    dP_dtable : (n, 3, N, 5) or None
        derivative of ``base_p_tcp`` with respect to each table entry
        (theta_offset, d, a, alpha, beta), mm per rad or mm per mm. Column
        ``[:, :, j, 0]`` is also the derivative with respect to joint angle j.
    joint_axes, joint_origins : (n, N, 3)
        each joint's rotation axis (unit) and a point on it, base frame
    frames_R, frames_p : (n, N + 1, 3, 3), (n, N + 1, 3)
        the base frame and the frame of every link (after each joint row)
    """

    base_p_tcp: np.ndarray
    base_R_flange: np.ndarray
    base_p_flange: np.ndarray
    dP_dtable: np.ndarray | None
    joint_axes: np.ndarray
    joint_origins: np.ndarray
    frames_R: np.ndarray
    frames_p: np.ndarray
    #: ``dP_dtable`` in its storage layout (N, 5, 3, n), for fast contractions
    dP_internal: np.ndarray | None = None
    #: (N,) bool, the prismatic joints (None: all revolute); their ``joint_axes`` are the
    #: directions of travel
    prismatic: np.ndarray | None = None
    #: the rotation axes of the elementary rotations (3, k, n) and their (row, column) in
    #: the table (2, k), kept for :attr:`dW_internal` (None without the Jacobian)
    rotation_axes: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def dW_internal(self) -> np.ndarray:
        """(N, 5, 3, n) the flange's angular velocity (base frame) per table entry, in the
        layout of ``dP_internal``: the unit axis of an elementary rotation, zero for a
        translation (rad per rad; the orientation counterpart of ``dP_internal``)."""
        if self.rotation_axes is None:
            raise ValueError("dW_internal needs the chain run with its Jacobian")
        U, (rj, rc) = self.rotation_axes
        N, n = self.joint_axes.shape[1], self.joint_axes.shape[0]
        dW = np.zeros((N, 5, 3, n))
        dW[rj, rc] = U.transpose(1, 0, 2)
        return dW

    @property
    def dP_dq(self) -> np.ndarray:
        """(n, 3, N) derivative of ``base_p_tcp`` with respect to each joint variable: mm/rad
        for a revolute joint, mm per internal unit for a prismatic one."""
        if self.dP_dtable is not None:
            G = self.dP_dtable[:, :, :, THETA]
        else:
            G = cross(self.joint_axes, self.base_p_tcp[:, None, :] - self.joint_origins)
            G = G.transpose(0, 2, 1)
        if self.prismatic is None or not self.prismatic.any():
            return G
        G = G.copy()
        G[:, :, self.prismatic] = (self.joint_axes[:, self.prismatic].transpose(0, 2, 1)
                                   * PRISMATIC_MM_PER_UNIT)
        return G

    @property
    def dR_dq(self) -> np.ndarray:
        """(n, 3, N) angular velocity of the flange per joint rate: the axis of a revolute
        joint, zero for a prismatic one."""
        W = self.joint_axes.transpose(0, 2, 1)
        if self.prismatic is None or not self.prismatic.any():
            return W
        W = W.copy()
        W[:, :, self.prismatic] = 0.0
        return W


def run_chain(
    convention: str,
    table: np.ndarray,
    q: np.ndarray,
    tool: np.ndarray,
    length_scale: np.ndarray | None = None,
    jacobian: bool = True,
    prismatic: np.ndarray | None = None,
) -> ChainResult:
    """One vectorised pass along the chain.

    Parameters
    ----------
    convention : "dh" or "mdh"
    table : array, shape (N, 5)
        theta_offset, d, a, alpha, beta per joint (rad, mm).
    q : array, shape (n, N)
        joint angles (rad) as the joints really are (corrections already added).
    tool : array, shape (3,) or (n, 3)
        target centre in the flange frame, mm.
    length_scale : array, shape (n,), optional
        per-pose relative growth of every link length (d, a) and of the tool.
    jacobian : bool
        also compute ``dP_dtable``.
    prismatic : array of bool, shape (N,), optional
        the prismatic joints (``RobotModel.prismatic_mask()``); None: all revolute.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n, N = q.shape
    table = np.asarray(table, dtype=float)
    if table.shape != (N, 5):
        raise ValueError(f"table has shape {table.shape}, expected ({N}, 5)")
    seq = _SEQUENCE[convention]
    grow = None if length_scale is None else 1.0 + np.asarray(length_scale, float)
    slide = np.zeros(N, bool) if prismatic is None else np.asarray(prismatic, bool)
    if slide.shape != (N,):
        raise ValueError(f"prismatic mask has shape {slide.shape}, expected ({N},)")

    # component-major layout inside: a vector field over poses is (3, n), so every
    # operation and every store below touches contiguous memory
    cols = [np.zeros((3, n)) for _ in range(3)]
    for k in range(3):
        cols[k][k] = 1.0
    p = np.zeros((3, n))
    FR = np.empty((N + 1, 3, 3, n))  # frame, column (axis), component, pose
    Fp = np.empty((N + 1, 3, n))
    FR[0] = np.eye(3)[:, :, None]
    Fp[0] = 0.0
    JA = np.empty((N, 3, n))
    JO = np.empty((N, 3, n))
    n_rot = sum(1 for kind, _, _ in seq if kind == "r") * N
    n_tra = N * len(seq) - n_rot
    if jacobian:
        # component-major like the frames: row-wise arithmetic on (n_rot, n) planes below
        U = np.empty((3, n_rot, n))  # rotation axes
        O = np.empty((3, n_rot, n))  # a point on each
        T = np.empty((3, n_tra, n))  # translation directions
    rot_at: list[tuple[int, int]] = []
    tra_at: list[tuple[int, int]] = []

    for j in range(N):
        for kind, ax, col in seq:
            value = table[j, col]
            u = cols[ax]
            if kind == "r":
                if jacobian:
                    U[:, len(rot_at)] = u
                    O[:, len(rot_at)] = p
                    rot_at.append((j, col))
                if col == THETA:
                    JA[j] = u
                    JO[j] = p
                    if slide[j] and value == 0.0:
                        continue
                    angle = value if slide[j] else q[:, j] + value
                elif value == 0.0:
                    continue
                else:
                    angle = value
                c, s = np.cos(angle), np.sin(angle)
                i1, i2 = (ax + 1) % 3, (ax + 2) % 3
                e1, e2 = cols[i1], cols[i2]
                cols[i1], cols[i2] = c * e1 + s * e2, c * e2 - s * e1
            else:
                if jacobian:
                    T[:, len(tra_at)] = u
                    tra_at.append((j, col))
                if col == _TRAVEL and slide[j]:
                    travel = q[:, j] * PRISMATIC_MM_PER_UNIT
                    p = p + ((value if grow is None else value * grow) + travel) * u
                    continue
                if value == 0.0:
                    continue
                p = p + (value if grow is None else value * grow) * u
        for k in range(3):
            FR[j + 1, k] = cols[k]
        Fp[j + 1] = p

    tool = np.asarray(tool, dtype=float)
    tc = tool if tool.ndim == 1 else tool.T  # (3,) or (3, n)
    if grow is not None:
        tc = tc[:, None] * grow if tc.ndim == 1 else tc * grow
    point = p + tc[0] * cols[0] + tc[1] * cols[1] + tc[2] * cols[2]

    dP = dPi = None
    if jacobian:
        dPi = np.zeros((N, 5, 3, n))
        D = point[:, None] - O
        C = np.empty_like(U)
        C[0] = U[1] * D[2] - U[2] * D[1]
        C[1] = U[2] * D[0] - U[0] * D[2]
        C[2] = U[0] * D[1] - U[1] * D[0]
        rj, rc = np.array(rot_at).T
        dPi[rj, rc] = C.transpose(1, 0, 2)
        tj, tc = np.array(tra_at).T
        dPi[tj, tc] = (T if grow is None else T * grow).transpose(1, 0, 2)
        dP = dPi.transpose(3, 2, 0, 1)
    base_R_flange = FR[N].transpose(2, 1, 0)
    result = ChainResult(
        point.T,
        base_R_flange,
        p.T,
        dP,
        JA.transpose(2, 0, 1),
        JO.transpose(2, 0, 1),
        FR.transpose(3, 0, 2, 1),
        Fp.transpose(2, 0, 1),
    )
    result.dP_internal = dPi
    if jacobian:
        result.rotation_axes = (U, np.array(rot_at).T)
    result.prismatic = slide if slide.any() else None
    return result


def forward(model: RobotModel, q_deg_or_rad: np.ndarray, *, degrees: bool = False) -> np.ndarray:
    """Every frame of the nominal model for every pose.

    Parameters
    ----------
    q_deg_or_rad : array, shape (n, N) or (N,)
        joint positions (rad, or deg with ``degrees=True``).

    Returns
    -------
    array, shape (n, N + 1, 4, 4)
        homogeneous transforms base_T_link: index 0 the base, index N the flange.
    """
    q = np.atleast_2d(np.asarray(q_deg_or_rad, float))
    if degrees:
        q = np.radians(q)
    r = run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                  prismatic=model.prismatic_mask())
    n, N1 = r.frames_p.shape[:2]
    T = np.zeros((n, N1, 4, 4))
    T[..., :3, :3] = r.frames_R
    T[..., :3, 3] = r.frames_p
    T[..., 3, 3] = 1.0
    return T


def tool_points(model: RobotModel, q: np.ndarray, tool: np.ndarray | None = None) -> np.ndarray:
    """Target centre in the base frame for joint angles ``q`` (rad), shape (n, 3), mm."""
    t = model.tool_mm() if tool is None else tool
    return run_chain(model.convention, model.dh_table(), q, t, jacobian=False,
                     prismatic=model.prismatic_mask()).base_p_tcp
