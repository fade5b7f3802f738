"""``steps``: axis-wise step moves from a start point (absolute positioning error).

From the start point (reached by a joint move) the TCP steps along x, then y,
then z (linear moves, keeping the start's flange orientation):
``count`` steps of ``step_mm`` per axis, back at the start before each axis.
Each sample records the controller's nominal TCP (``cmd_x/y/z``, what the
teach pendant shows) and the tracker's measurement; once the measurement frame
is known their difference is the absolute positioning error, and the export
calibrates directly.

Line of sight (``cell`` with a tracker position): without ``start_deg`` the start is
a posture whose SMR faces the tracker straight on (its orientation is kept by the
linear moves), and a plan with a point the tracker would not see is refused
(:class:`~daq.errors.NotEnoughVisible`, the points and reasons listed).
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ._common import (
    default_start,
    expected_joints,
    facing_start,
    knows_tracker,
    nominal_point,
    require_visible,
    visibility_params,
)

#: what to change when the tracker would not see the steps
CHANGE = ("another --start-deg / --start-xyz (or leave --start-deg out: the routine picks a "
          "posture facing the tracker), fewer or shorter steps, or move the tracker")


def make_plan(model, *, start_xyz=None, start_deg=None, step_mm: float = 20.0, count: int = 10,
              axes: str = "xyz", cell=None) -> Plan:
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
    cell : CellSpec, optional
        Plan for the tracker's line of sight (see the module docstring).
    """
    if count < 1 or not axes or set(axes) - set("xyz"):
        raise ValueError("steps: count must be >= 1 and axes a subset of 'xyz'")
    sight = knows_tracker(cell)

    def points(q0):
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
        qs, ok = expected_joints(model, np.array(pts), q0)
        return qs, ok, labels, pts, info, p0

    if start_deg is not None:
        q0 = np.radians(start_deg)
    elif sight:
        q0 = facing_start(model, cell, "steps", CHANGE, lambda q: points(q)[:3])
    else:
        q0 = default_start(model)
    qs, _, labels, pts, info, p0 = points(q0)
    if sight:
        require_visible("steps", model, qs, labels, cell, CHANGE)
    # the start by a joint move (in the start's flange orientation, which the linear moves
    # keep), the steps by linear moves
    targets = tuple(Target(i, "joints" if i == 0 else "linear", q=qs[i], base_p_tcp=pts[i],
                           label=labels[i], info=info[i])
                    for i in range(len(pts)))
    params = {"start_xyz_mm": p0.tolist(), "start_deg": np.degrees(q0).tolist(),
              "step_mm": step_mm, "count": count, "axes": axes}
    if sight:
        params["visibility"] = visibility_params(cell)
    return Plan("steps", params, targets, model=model.name)
