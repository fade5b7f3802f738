"""``frame``: measurement-frame setup — the joint-1 circle and the x line.

Joint 1 alone turns through ``circle_span_deg`` in ``circle_points`` steps
(the target traces a circle about the base Z axis), then the TCP moves along
the base x axis alone, ``line_points`` points over ``line_length_mm`` centred
on the start. The line's first point is a joint move (through a pre-position one
line step before it, so it is approached along +x like the others): it brings joint 1
back from the circle's end to the start's configuration, whatever the circle's span (a
linear move from there would turn joint 1 the short way, and a multi-turn circle would
leave it a full turn away from the posture the plan expects). The other line points
are linear moves. :func:`finalize` fits the circle and the line
(:mod:`calibration.frame_fit`) and stores the base frame in the tracker frame
(``tracker_T_base``) and the fit quality with the run.
"""

from __future__ import annotations

import numpy as np

from calibration.frame_fit import measurement_frame

from ..plans import Plan, Target
from ._common import default_start, expected_joints, nominal_point


def make_plan(model, *, start_deg=None, circle_span_deg: float = 90.0, circle_points: int = 12,
              line_length_mm: float = 300.0, line_points: int = 11) -> Plan:
    """The frame plan (joints deg at the edge, rad inside; mm).

    Parameters
    ----------
    model : RobotModel
    start_deg : sequence of float, optional
        Start posture (deg); default the middle of the limits.
    circle_span_deg : float
        Total turn of joint 1, centred on the start (deg).
    circle_points, line_points : int
        Points on the circle (>= 3) and on the line (>= 2).
    line_length_mm : float
        Length of the x move, centred on the start TCP (mm).
    """
    if circle_points < 3 or line_points < 2:
        raise ValueError("frame: needs at least 3 circle points and 2 line points")
    q0 = np.radians(start_deg) if start_deg is not None else default_start(model)
    if len(q0) != model.n_joints:
        raise ValueError(f"frame: start has {len(q0)} joints, model has {model.n_joints}")
    targets = []
    span = np.radians(circle_span_deg)
    for k, a in enumerate(np.linspace(-span / 2, span / 2, circle_points)):
        q = q0.copy()
        q[0] += a
        targets.append(Target(len(targets), "joints", q=q, label=f"circle{k + 1}",
                              info={"part": "circle"}))
    p0 = nominal_point(model, q0)
    xs = p0[0] + np.linspace(-line_length_mm / 2, line_length_mm / 2, line_points)
    xyz = np.column_stack([xs, np.full(line_points, p0[1]), np.full(line_points, p0[2])])
    # approach the line's first point along +x, like the rest of the line: a joint move
    # from a pre-position one step before it (back from the circle's end), then linear
    step = np.array([line_length_mm / max(line_points - 1, 1), 0.0, 0.0])
    qs, _ = expected_joints(model, np.vstack([xyz[0] - step, xyz]), q0)
    targets.append(Target(len(targets), "joints", q=qs[1], base_p_tcp=xyz[0], via=qs[0],
                          label="line1", info={"part": "line"}))
    for k in range(1, line_points):
        targets.append(Target(len(targets), "linear", q=qs[k + 1], base_p_tcp=xyz[k],
                              label=f"line{k + 1}", info={"part": "line"}))
    params = {"start_deg": np.degrees(q0).tolist(), "circle_span_deg": circle_span_deg,
              "circle_points": circle_points, "line_length_mm": line_length_mm,
              "line_points": line_points, "origin_height_mm": float(p0[2])}
    return Plan("frame", params, tuple(targets), model=model.name)


def finalize(plan: Plan, samples, run) -> dict:
    """Fit the frame: ``{"frame": FrameFit.to_dict(), "summary": {...}}``."""
    part = [(t or {}).get("info", {}).get("part") for t in samples.targets]
    circ = np.array([p == "circle" for p in part])
    line = np.array([p == "line" for p in part])
    height = float(plan.params["origin_height_mm"])
    cmd_z = samples.base_p_tcp_cmd[circ, 2]
    if cmd_z.size and np.all(np.isfinite(cmd_z)):
        height = float(cmd_z.mean())  # the controller's own nominal TCP height
    fit = measurement_frame(samples.tracker_p_smr[circ], samples.tracker_p_smr[line], height)
    d = fit.to_dict()
    return {"frame": d, "summary": {"circle_rms_mm": fit.circle.rms, "line_rms_mm": fit.line.rms,
                                    "orthogonality_deg": fit.orthogonality_deg}}
