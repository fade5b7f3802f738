"""The exact conversion of a serial chain, given by its joint axes, into a standard
Denavit–Hartenberg table with the Hayati tilt beta (the table of
:meth:`calibration.model.robot_model.RobotModel.dh_table`).

Used for URDF chains (:mod:`calibration.model.urdf_model`) and to re-express a chain in a
controller's own frames (:func:`calibration.exports.controller_export.ur_table`). The rules:

- the base frame is F itself when joint 1's axis is F's z axis, else a frame on that
  axis (``mount``, F_T_base);
- row i follows the common normal from axis i to axis i+1, its x axis signed so that
  theta_offset is smallest (a may be negative, as in UR's tables);
- axes within ``PARALLEL_SIN`` (~3 deg) of parallel use the Hayati form instead: d = 0,
  the normal in the plane through the previous origin, the small tilt in alpha and beta;
- the last row turns the flange frame like a given tip frame (a = 0) and puts its origin
  on the last axis level with the tip; the tool point is the tip's origin in it.

Lengths mm, angles rad.
"""

from __future__ import annotations

import math

import numpy as np

#: sin of the angle below which two neighbouring axes use the Hayati (beta) form: within
#: ~3 deg their common normal is far away (>= 20 x the axes' distance) and ill-conditioned
PARALLEL_SIN = 0.05
#: lengths (mm) and angles (rad) smaller than this are rounding and written as 0
SNAP_MM, SNAP_RAD = 1e-9, 1e-12


def rot_z(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _signed_x(x_xy: np.ndarray) -> tuple[np.ndarray, float]:
    """(x, theta): the unit direction ±x_xy (in the xy plane) nearest the current x axis."""
    x = np.array([x_xy[0], x_xy[1], 0.0])
    x /= np.linalg.norm(x)
    if x[0] < -1e-12 or (abs(x[0]) <= 1e-12 and x[1] < 0):
        x = -x
    return x, math.atan2(x[1], x[0])


#: one table row: theta_offset, d, a, alpha, beta (rad, mm)
Row = tuple[float, float, float, float, float]


def _dh_row(R: np.ndarray, p: np.ndarray, o_next: np.ndarray,
            u_next: np.ndarray) -> tuple[Row, np.ndarray, np.ndarray]:
    """One standard-DH row from the current frame (z on this joint's axis) to the next axis.

    Returns (theta, d, a, alpha, beta) and the next frame (R, p).
    """
    u = R.T @ u_next
    o = R.T @ (o_next - p)
    s2 = u[0] * u[0] + u[1] * u[1]
    if math.sqrt(s2) > PARALLEL_SIN:  # common normal
        t2 = -(o[0] * u[0] + o[1] * u[1]) / s2
        d = o[2] + t2 * u[2]
        foot = o + t2 * u
        x, theta = _signed_x(np.array([-u[1], u[0]]))
        a = float(foot @ x)
        alpha = math.atan2(-u[1] * x[0] + u[0] * x[1], u[2])
        beta = 0.0
    else:  # Hayati: d = 0, the next axis met in the plane z = 0
        d = 0.0
        foot = o - (o[2] / u[2]) * u
        r = math.hypot(foot[0], foot[1])
        if r > SNAP_MM:
            x, theta = _signed_x(foot[:2])
        else:
            x, theta = np.array([1.0, 0.0, 0.0]), 0.0
        a = float(foot @ x)
        v = rot_z(theta).T @ u
        beta = math.asin(max(-1.0, min(1.0, v[0])))
        alpha = math.atan2(-v[1], v[2])
    R_next = R @ rot_z(theta) @ rot_x(alpha) @ rot_y(beta)
    p_next = p + R @ np.array([0.0, 0.0, d]) + a * (R @ np.array([math.cos(theta),
                                                                  math.sin(theta), 0.0]))
    return (theta, d, a, alpha, beta), R_next, p_next


def _last_row(R: np.ndarray, p: np.ndarray,
              tip_T: np.ndarray) -> tuple[Row, np.ndarray, np.ndarray, np.ndarray]:
    """The last row: flange frame turned like the tip, origin on the last axis level with it.

    Returns (theta, d, a, alpha, beta), the flange frame (R, p) and the tool point in it.
    """
    Rt = R.T @ tip_T[:3, :3]
    pt = R.T @ (tip_T[:3, 3] - p)
    d = float(pt[2])
    alpha = math.asin(max(-1.0, min(1.0, Rt[2, 1])))
    if abs(math.cos(alpha)) > 1e-9:
        beta = math.atan2(-Rt[2, 0], Rt[2, 2])
        theta = math.atan2(-Rt[0, 1], Rt[1, 1])
    else:
        beta, theta = 0.0, math.atan2(Rt[1, 0], Rt[0, 0])
    R_n = R @ rot_z(theta) @ rot_x(alpha) @ rot_y(beta)
    p_n = p + d * R[:, 2]
    return (theta, d, 0.0, alpha, beta), R_n, p_n, R_n.T @ (tip_T[:3, 3] - p_n)


def _base_frame(o1: np.ndarray, u1: np.ndarray) -> np.ndarray:
    """root_T_base: identity when joint 1's axis is the root z axis, else a frame on it."""
    T = np.eye(4)
    if np.linalg.norm(u1 - [0.0, 0.0, 1.0]) < 1e-12 and math.hypot(o1[0], o1[1]) < SNAP_MM:
        return T
    z = u1
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - z[1] * z
    x /= np.linalg.norm(x)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = o1 - (o1 @ z) * z
    return T


def urdf_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (rad) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0]))) + 0.0  # + 0.0: no "-0.0" in files
    if abs(math.cos(pitch)) > 1e-9:
        return math.atan2(R[2, 1], R[2, 2]) + 0.0, pitch, math.atan2(R[1, 0], R[0, 0]) + 0.0
    return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1]) + 0.0


def dh_from_axes(
    origins: np.ndarray, axes: np.ndarray, tip_T: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
    """The standard-DH/Hayati table of a chain given by its joint axes (mm, any frame F).

    Parameters
    ----------
    origins, axes : (N, 3) a point on each joint axis and its unit direction (sense of
        positive motion), at zero joint positions
    tip_T : (4, 4) F_T_tip, the frame the flange is turned like; its origin is the tool point

    Returns
    -------
    mount : (4, 4) F_T_base, identity when joint 1's axis is F's z axis
    table : (N, 5) theta_offset, d, a, alpha, beta (rad, mm), rounding snapped to 0
    frames : N (R, p), the frame after each row, in F
    tool : (3,) the tip's origin in the flange frame, mm
    """
    mount = _base_frame(origins[0], axes[0])
    R, p = mount[:3, :3].copy(), mount[:3, 3].copy()
    rows, frames = [], []
    for i in range(len(origins) - 1):
        row, R, p = _dh_row(R, p, origins[i + 1], axes[i + 1])
        rows.append(row)
        frames.append((R, p))
    row, R, p, tool = _last_row(R, p, tip_T)
    rows.append(row)
    frames.append((R, p))
    tol = np.array([SNAP_RAD, SNAP_MM, SNAP_MM, SNAP_RAD, SNAP_RAD])
    table = np.array(rows, float)
    table[np.abs(table) < tol] = 0.0
    return mount, table, frames, np.array([0.0 if abs(v) < SNAP_MM else float(v) for v in tool])
