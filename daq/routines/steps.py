"""``steps``: axis-wise step moves from a start point (absolute positioning error).

From the start point the TCP steps along x, then y, then z (linear moves):
``count`` steps of ``step_mm`` per axis, back at the start before each axis.
Each sample records the controller's nominal TCP (``cmd_x/y/z``, what the
teach pendant shows) and the tracker's measurement; once the measurement frame
is known their difference is the absolute positioning error, and the export
calibrates directly.
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ._common import default_start, expected_joints, nominal_point


def make_plan(model, *, start_xyz=None, start_deg=None, step_mm: float = 20.0, count: int = 10,
              axes: str = "xyz") -> Plan:
    """The steps plan.

    Parameters
    ----------
    model : RobotModel
    start_xyz : sequence of 3 float, optional
        Start point (mm, base frame); default the tool point at ``start_deg``.
    start_deg : sequence of float, optional
        Posture used as the start (and as the IK seed), deg; default the middle of the limits.
    step_mm : float
        Step length (mm; negative steps go the other way).
    count : int
        Steps per axis.
    axes : str
        Which axes, in order (subset of ``"xyz"``).
    """
    if count < 1 or not axes or set(axes) - set("xyz"):
        raise ValueError("steps: count must be >= 1 and axes a subset of 'xyz'")
    q0 = np.radians(start_deg) if start_deg is not None else default_start(model)
    p0 = np.asarray(start_xyz, float) if start_xyz is not None else nominal_point(model, q0)
    pts, labels, info = [], [], []
    for ax in axes:
        k_ax = "xyz".index(ax)
        for k in range(count + 1):
            p = p0.copy()
            p[k_ax] += k * step_mm
            pts.append(p)
            labels.append(f"{ax}{k}")
            info.append({"axis": ax, "step": k})
    qs, _ = expected_joints(model, np.array(pts), q0)
    targets = tuple(Target(i, "linear", q=qs[i], base_p_tcp=pts[i], label=labels[i],
                           info=info[i])
                    for i in range(len(pts)))
    params = {"start_xyz_mm": p0.tolist(), "start_deg": np.degrees(q0).tolist(),
              "step_mm": step_mm, "count": count, "axes": axes}
    return Plan("steps", params, targets, model=model.name)
