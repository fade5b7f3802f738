"""``frame``: measurement-frame setup — the joint-1 circle and the x line.

Joint 1 alone turns through ``circle_span_deg`` in ``circle_points`` steps
(the target traces a circle about the base Z axis), then the TCP moves along
the base x axis alone, ``line_points`` points over ``line_length_mm`` centred
on the start (a joint move to the first, in the start's orientation, then linear
moves, which keep it). :func:`finalize` fits the circle and the line
(:mod:`calibration.cell.frame_fit`) and stores the base frame in the tracker frame
(``tracker_T_base``) and the fit quality with the run.

Line of sight (when the plan knows roughly where the tracker is: ``cell``): a
turn of joint 1 turns the SMR away from the tracker, so the circle is the widest
arc up to ``circle_span_deg`` that the tracker sees with the cell's margins
(at least :data:`MIN_CIRCLE_SPAN_DEG`), and the line is shortened until the tracker
sees it. Without ``start_deg`` the start is chosen for the widest arc among postures
whose SMR faces the tracker straight on (:func:`~daq.routines._common.facing_starts`).
"""

from __future__ import annotations

import numpy as np

from calibration.cell.frame_fit import measurement_frame

from ..errors import NotEnoughVisible
from ..plans import Plan, Target
from ..store import RunSummary
from ._common import (
    default_start,
    expected_joints,
    facing_starts,
    hidden,
    knows_tracker,
    nominal_point,
    require_visible,
    visibility_params,
    what_hides,
)

#: the narrowest joint-1 arc the frame fit is given (deg): below it the circle's normal is poor
MIN_CIRCLE_SPAN_DEG = 30.0
#: rounding allowed when an arc capped at the minimum span is compared with it (deg)
_SPAN_TOL_DEG = 1e-6
#: the shortest x line, mm
MIN_LINE_MM = 100.0


def visible_arcs(model, q0: np.ndarray, cell, span_rad: float, step_rad: float = np.radians(1.0)
                 ) -> tuple[np.ndarray, np.ndarray]:
    """For each start (m, N): the joint-1 offsets (rad) ``lo <= 0 <= hi`` of the widest arc
    around it that the tracker sees throughout (at most ``span_rad`` wide; lo = hi = 0 when
    the start itself is hidden). Returns (lo (m,), hi (m,))."""
    from calibration.cell.visibility import assess

    K = int(np.ceil(span_rad / step_rad))
    off = np.arange(-K, K + 1) * step_rad
    Q = np.repeat(q0, len(off), axis=0)
    Q[:, 0] += np.tile(off, len(q0))
    vis = assess(model, Q, cell).visible.reshape(len(q0), len(off))
    # the visible run through offset 0: first hidden offset on either side
    up = np.argmin(np.concatenate([vis[:, K:], np.zeros((len(q0), 1), bool)], axis=1), axis=1)
    down = np.argmin(np.concatenate([vis[:, K::-1], np.zeros((len(q0), 1), bool)], axis=1),
                     axis=1)
    hi, lo = np.maximum(up - 1, 0) * step_rad, -np.maximum(down - 1, 0) * step_rad
    mid = (lo + hi) / 2
    wide = hi - lo > span_rad
    lo = np.where(wide, mid - span_rad / 2, lo)
    hi = np.where(wide, mid + span_rad / 2, hi)
    return lo, hi


def _line(model, q0: np.ndarray, length_mm: float, n: int, cell):
    """The x line's points (n, 3) mm, their expected joints and its length; with ``cell``
    shortened (by 1.5 at a time, down to :data:`MIN_LINE_MM`) until the tracker sees all
    of it, None when it cannot be seen or reached."""
    p0 = nominal_point(model, q0)
    length = float(length_mm)
    while True:
        xs = p0[0] + np.linspace(-length / 2, length / 2, n)
        xyz = np.column_stack([xs, np.full(n, p0[1]), np.full(n, p0[2])])
        qs, ok = expected_joints(model, xyz, q0)
        if cell is None:
            return xyz, qs, length
        if ok.all() and not hidden(model, qs, cell):
            return xyz, qs, length
        length /= 1.5
        if length < MIN_LINE_MM:
            return None


def make_plan(model, *, start_deg=None, circle_span_deg: float = 90.0, circle_points: int = 12,
              line_length_mm: float = 300.0, line_points: int = 11, cell=None) -> Plan:
    """The frame plan (joints deg at the edge, rad inside; mm).

    Parameters
    ----------
    model : RobotModel
    start_deg : sequence of float, optional
        Start posture (deg); default the middle of the limits, or with ``cell`` the
        posture facing the tracker with the widest visible arc.
    circle_span_deg : float
        Total turn of joint 1 (deg): centred on the start, or with ``cell`` the widest
        visible arc up to it.
    circle_points, line_points : int
        Points on the circle (>= 3) and on the line (>= 2).
    line_length_mm : float
        Length of the x move, centred on the start TCP (mm); with ``cell`` shortened
        until the tracker sees all of it.
    cell : CellSpec, optional
        The cell (tracker position, SMR, margins, fixtures); None: no line of sight check.
    """
    if circle_points < 3 or line_points < 2:
        raise ValueError("frame: needs at least 3 circle points and 2 line points")
    if not circle_span_deg >= MIN_CIRCLE_SPAN_DEG:
        raise ValueError(f"frame: circle_span_deg {circle_span_deg:g} is below the minimum "
                         f"{MIN_CIRCLE_SPAN_DEG:g} deg")
    span = np.radians(circle_span_deg)
    if start_deg is not None and len(start_deg) != model.n_joints:
        raise ValueError(f"frame: start has {len(start_deg)} joints, model has {model.n_joints}")
    sight = knows_tracker(cell)
    change = ("another --start-deg whose SMR faces the tracker (or leave it out: the routine "
              "picks one), a shorter --line-length-mm, --tracker-at, or move the tracker")
    if not sight:
        q0 = np.radians(start_deg) if start_deg is not None else default_start(model)
        offsets = np.linspace(-span / 2, span / 2, circle_points)
        xyz, qs, length = _line(model, q0, line_length_mm, line_points, None)
    else:
        starts = (np.radians(np.atleast_2d(start_deg)) if start_deg is not None
                  else facing_starts(model, cell)[0])
        if len(starts) == 0:
            cause = what_hides(model, cell)
            raise NotEnoughVisible(f"frame: no posture found whose SMR faces the tracker at "
                                   f"{np.round(cell.tracker_mm).tolist()} mm; "
                                   f"{f'the cause: {cause}; ' if cause else ''}change: {change}")
        lo, hi = visible_arcs(model, starts, cell, span)
        found = None
        for k in np.argsort(-(hi - lo), kind="stable")[:20]:  # the widest arcs first
            if np.degrees(hi[k] - lo[k]) < MIN_CIRCLE_SPAN_DEG - _SPAN_TOL_DEG:
                break
            line = _line(model, starts[k], line_length_mm, line_points, cell)
            if line is not None:
                found = k, line
                break
        if found is None:
            require_visible("frame", model, starts[:1], ["start"], cell, change)
            raise NotEnoughVisible(
                f"frame: no start found from which the tracker sees a turn of joint 1 by "
                f"{MIN_CIRCLE_SPAN_DEG:g} deg or more (widest {np.degrees(np.max(hi - lo)):.0f} "
                f"deg) and a reachable x line of {MIN_LINE_MM:g} mm or more; change: {change}")
        k, (xyz, qs, length) = found
        q0 = starts[k].copy()
        offsets = np.linspace(lo[k], hi[k], circle_points)
    targets = []
    for k, a in enumerate(offsets):
        q = q0.copy()
        q[0] += a
        targets.append(Target(len(targets), "joints", q=q, label=f"circle{k + 1}",
                              info={"part": "circle"}))
    # the line's first point by a joint move: back to the start's orientation, which the
    # linear moves then keep (after the circle the flange is turned by joint 1, a full turn
    # or more after a multi-turn circle), through a pre-position one line step before it so
    # that it is approached along +x like the others
    step = (xyz[1] - xyz[0]) if len(xyz) > 1 else np.array([1.0, 0.0, 0.0])
    via, _ = expected_joints(model, np.vstack([xyz[0] - step, xyz[0]]), qs[0])
    for k in range(line_points):
        targets.append(Target(len(targets), "joints" if k == 0 else "linear", q=qs[k],
                              base_p_tcp=xyz[k], via=via[0] if k == 0 else None,
                              label=f"line{k + 1}", info={"part": "line"}))
    p0 = nominal_point(model, q0)
    params = {"start_deg": np.degrees(q0).tolist(), "circle_span_deg": circle_span_deg,
              "circle_points": circle_points, "line_length_mm": line_length_mm,
              "line_points": line_points, "origin_height_mm": float(p0[2])}
    if sight:
        params.update(circle_from_deg=float(np.degrees(offsets[0])),
                      circle_to_deg=float(np.degrees(offsets[-1])), line_used_mm=length,
                      visibility=visibility_params(cell))
    return Plan("frame", params, tuple(targets), model=model.name)


def finalize(plan: Plan, samples, run) -> dict:
    """Fit the frame: ``{"frame": FrameFit.to_dict(), "summary": {...}}`` (the run's
    summary kept)."""
    part = [(t or {}).get("info", {}).get("part") for t in samples.target]
    circ = np.array([p == "circle" for p in part], bool)
    line = np.array([p == "line" for p in part], bool)
    height = float(plan.params["origin_height_mm"])
    cmd_z = samples.cmd[circ, 2]
    if cmd_z.size and np.all(np.isfinite(cmd_z)):
        height = float(cmd_z.mean())  # the controller's own nominal TCP height
    fit = measurement_frame(samples.tracker_p_smr[circ], samples.tracker_p_smr[line], height)
    d = fit.to_dict()
    summary = run.summary or RunSummary()
    summary.circle_rms_mm = fit.circle.rms
    summary.line_rms_mm = fit.line.rms
    summary.orthogonality_deg = fit.orthogonality_deg
    return {"frame": d, "summary": summary}
