"""Numbers only: circle, line and measurement-frame fits for the ``frame`` routine.

The measurement-frame setup turns joint 1 alone (the target traces a circle
about the joint-1 axis = the base Z axis) and then moves the TCP along the
base x axis alone (a straight line). From the tracker measurements:

* Z axis: the circle's normal (oriented by the direction of rotation: a
  positive joint-1 turn is counter-clockwise about +Z);
* origin: the circle's centre moved down the Z axis by the nominal height of
  the TCP above the base (the controller's ``cmd_z`` during the circle);
* X axis: the fitted line's direction (oriented along the motion), made
  orthogonal to Z; Y = Z × X (right-hand rule).

Everything is in the tracker frame, mm; pure numpy, vectorised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class Circle:
    """A circle in space: ``centre`` (3,) mm, unit ``normal`` (3,), ``radius`` mm, ``rms``
    of the 3-D point-to-circle distances (mm), ``max_residual`` mm, ``n`` points."""

    centre: np.ndarray
    normal: np.ndarray
    radius: float
    rms: float
    max_residual: float
    n: int


@dataclass(frozen=True)
class Line:
    """A line: a ``point`` on it (the centroid, mm), unit ``direction``, ``rms`` and
    ``max_residual`` of the perpendicular distances (mm), ``n`` points."""

    point: np.ndarray
    direction: np.ndarray
    rms: float
    max_residual: float
    n: int


def _points(points: npt.ArrayLike, k: int, what: str) -> np.ndarray:
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3:
        raise ValueError(f"{what}: points must have shape (n, 3), got {P.shape}")
    if len(P) < k:
        raise ValueError(f"{what}: needs at least {k} points, got {len(P)}")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{what}: non-finite points")
    return P


def fit_plane(points: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares plane: (centroid (3,), unit normal (3,)) of points (n, 3)."""
    P = _points(points, 3, "plane fit")
    c = P.mean(axis=0)
    _, s, vt = np.linalg.svd(P - c, full_matrices=False)
    if s[1] <= 1e-12 * max(s[0], 1e-300):
        raise ValueError("plane fit: the points are collinear")
    return c, vt[2]


def fit_line(points: npt.ArrayLike) -> Line:
    """Least-squares 3-D line through points (n, 3) (total least squares, SVD).

    The direction is oriented from the first point towards the last.
    """
    P = _points(points, 2, "line fit")
    c = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - c, full_matrices=False)
    d = vt[0]
    if float((P[-1] - P[0]) @ d) < 0:
        d = -d
    r = (P - c) - np.outer((P - c) @ d, d)
    dist = np.linalg.norm(r, axis=1)
    return Line(c, d, float(np.sqrt(np.mean(dist**2))), float(dist.max()), len(P))


def fit_circle(points: npt.ArrayLike, iterations: int = 20) -> Circle:
    """Geometric least-squares circle through points (n, 3).

    A plane fit, an algebraic (Kåsa) circle fit in that plane as the start, then
    Gauss–Newton on the in-plane radial distances. The normal is oriented so the
    points, in the order given, turn counter-clockwise about it.
    """
    P = _points(points, 3, "circle fit")
    c0, nrm = fit_plane(P)
    # in-plane basis
    u = np.cross(nrm, [1.0, 0.0, 0.0])
    if np.linalg.norm(u) < 0.5:
        u = np.cross(nrm, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(nrm, u)
    D = P - c0
    xy = np.column_stack([D @ u, D @ v])
    A = np.column_stack([2 * xy, np.ones(len(xy))])
    sol, *_ = np.linalg.lstsq(A, (xy**2).sum(axis=1), rcond=None)
    a, b = sol[:2]
    r = float(np.sqrt(max(sol[2] + a * a + b * b, 0.0)))
    for _ in range(iterations):
        dx, dy = xy[:, 0] - a, xy[:, 1] - b
        rho = np.hypot(dx, dy)
        if np.any(rho == 0):
            break
        res = rho - r
        J = np.column_stack([-dx / rho, -dy / rho, -np.ones_like(rho)])
        step, *_ = np.linalg.lstsq(J, -res, rcond=None)
        a, b, r = a + step[0], b + step[1], r + step[2]
        if np.abs(step).max() < 1e-12 * max(r, 1.0):
            break
    centre = c0 + a * u + b * v
    # orientation: the points turn counter-clockwise about +normal
    rel = P - centre
    turn = np.cross(rel[:-1], rel[1:]).sum(axis=0)
    if float(turn @ nrm) < 0:
        nrm = -nrm
    radial = np.linalg.norm(rel - np.outer(rel @ nrm, nrm), axis=1) - r
    out = rel @ nrm
    dist = np.hypot(radial, out)
    return Circle(centre, nrm, float(abs(r)), float(np.sqrt(np.mean(dist**2))),
                  float(dist.max()), len(P))


@dataclass(frozen=True)
class FrameFit:
    """The robot base frame in the tracker frame, with the fits it came from.

    ``tracker_T_base`` (4, 4): columns X, Y, Z axes and the origin (mm) in the
    tracker frame. ``orthogonality_deg``: angle between the fitted line and the
    circle's plane (0 when the x move was exactly perpendicular to joint 1).
    """

    tracker_T_base: np.ndarray
    circle: Circle
    line: Line
    origin_height_mm: float
    orthogonality_deg: float

    def to_dict(self) -> dict:
        c, ln = self.circle, self.line
        return {
            "tracker_T_base": self.tracker_T_base.tolist(),
            "circle": {"centre_mm": c.centre.tolist(), "normal": c.normal.tolist(),
                       "radius_mm": c.radius, "rms_mm": c.rms, "max_mm": c.max_residual,
                       "n": c.n},
            "line": {"point_mm": ln.point.tolist(), "direction": ln.direction.tolist(),
                     "rms_mm": ln.rms, "max_mm": ln.max_residual, "n": ln.n},
            "origin_height_mm": self.origin_height_mm,
            "orthogonality_deg": self.orthogonality_deg,
        }


def measurement_frame(circle_points: npt.ArrayLike, line_points: npt.ArrayLike,
                      origin_height_mm: float = 0.0) -> FrameFit:
    """The base frame from the joint-1 circle and the x-line (see the module docstring).

    Parameters
    ----------
    circle_points : array, shape (n, 3), mm
        Tracker measurements while joint 1 turns, in order of increasing joint-1 angle.
    line_points : array, shape (m, 3), mm
        Tracker measurements along the base +x move, in order of increasing x.
    origin_height_mm : float
        Nominal height of the TCP above the base origin during the circle (mm).
    """
    circle = fit_circle(circle_points)
    line = fit_line(line_points)
    z = circle.normal
    x = line.direction - (line.direction @ z) * z
    nx = np.linalg.norm(x)
    if nx < 1e-6:
        raise ValueError("frame fit: the x line is parallel to the joint-1 axis")
    x /= nx
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
    T[:3, 3] = circle.centre - origin_height_mm * z
    ortho = float(np.degrees(np.arcsin(np.clip(abs(line.direction @ z), 0.0, 1.0))))
    return FrameFit(T, circle, line, float(origin_height_mm), ortho)


def axis_angle_deg(a: npt.ArrayLike, b: npt.ArrayLike) -> float:
    """Angle between two vectors, degrees (robust for tiny angles)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b)))
