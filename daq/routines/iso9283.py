"""``iso9283``: pose accuracy and repeatability cycles (ISO 9283 cube points).

The cube of side ``side_mm`` centred at ``centre_xyz`` (base frame): P1 its
centre, P2–P5 on the diagonals of the diagonal plane through two opposite
edges, 10 % of the diagonal in from the corners. ``cycles`` cycles visit P1..P5
in order, each approached from the same direction: a linear move to a
pre-position ``approach_mm`` away along ``approach_dir`` first (the very first point
by joint moves to the same two places, so the run starts in the flange orientation
the plan was made with).

:func:`finalize` computes per point the positional repeatability
RP = l̄ + 3·S_l (ISO 9283 §7.2.2, from the tracker only) and, when the run knows
the measurement frame (``tracker_T_base`` in its context), the positional
accuracy AP = |x̄ − x_c| of the mean attained position from the commanded one.

Line of sight (``cell`` with a tracker position): without ``start_deg`` the IK seed is a
posture whose SMR faces the tracker straight on, and a plan with a point (or
pre-position) the tracker would not see is refused
(:class:`~daq.errors.NotEnoughVisible`).
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ..store import Iso9283Point, RunSummary
from ._common import (
    default_start,
    expected_joints,
    facing_start,
    knows_tracker,
    nominal_point,
    require_visible,
    visibility_params,
)

#: what to change when the tracker would not see the cube
CHANGE = ("another --start-deg / --centre-xyz (or leave --start-deg out: the routine picks a "
          "posture facing the tracker), a smaller --side-mm, or move the tracker")


def cube_points(centre, side_mm: float) -> np.ndarray:
    """P1..P5 (5, 3) mm: the centre and four points 10 % of the diagonal in from the corners
    of the diagonal plane (corners (-,-,-), (+,+,-), (+,+,+), (-,-,+))."""
    c = np.asarray(centre, float)
    h = side_mm / 2.0
    corners = np.array([[-h, -h, -h], [h, h, -h], [h, h, h], [-h, -h, h]])
    return np.vstack([c, c + 0.8 * corners])


def make_plan(model, *, centre_xyz=None, start_deg=None, side_mm: float = 200.0,
              cycles: int = 30, approach_mm: float = 20.0, approach_dir=(0.0, 0.0, 1.0),
              cell=None) -> Plan:
    """The iso9283 plan: ``5 × cycles`` linear targets with pre-positions (``cell``: for the
    tracker's line of sight, see the module docstring)."""
    if cycles < 1:
        raise ValueError("iso9283: cycles must be >= 1")
    sight = knows_tracker(cell)
    d = np.asarray(approach_dir, float)
    d = d / np.linalg.norm(d)
    labels = [f"P{k + 1}" for k in range(5)]

    def points(q0):
        c = np.asarray(centre_xyz, float) if centre_xyz is not None else nominal_point(model, q0)
        pts = cube_points(c, side_mm)
        # the pre-positions must be reached too (not seen: nothing is measured there)
        qs, ok = expected_joints(model, np.vstack([pts, pts + approach_mm * d]), q0)
        return qs[:5], ok[:5] & ok[5:], labels, c, pts

    if start_deg is not None:
        q0 = np.radians(start_deg)
    elif sight:
        q0 = facing_start(model, cell, "iso9283", CHANGE, lambda q: points(q)[:3])
    else:
        q0 = default_start(model)
    qs, _, _, c, pts = points(q0)
    if sight:
        require_visible("iso9283", model, qs, labels, cell, CHANGE)
    q_via0 = expected_joints(model, pts[:1] + approach_mm * d, q0)[0][0]
    targets = []
    for cyc in range(cycles):
        for k in range(5):
            # the very first by joint moves (pre-position, then P1): in the start's flange
            # orientation, which every later linear move keeps
            first = not targets
            targets.append(Target(len(targets), "joints" if first else "linear", q=qs[k],
                                  base_p_tcp=pts[k],
                                  via=q_via0 if first else pts[k] + approach_mm * d,
                                  label=f"c{cyc + 1}.P{k + 1}",
                                  info={"cycle": cyc + 1, "point": k + 1}))
    params = {"centre_xyz_mm": c.tolist(), "start_deg": np.degrees(q0).tolist(),
              "side_mm": side_mm, "cycles": cycles, "approach_mm": approach_mm,
              "approach_dir": d.tolist()}
    if sight:
        params["visibility"] = visibility_params(cell)
    return Plan("iso9283", params, tuple(targets), model=model.name)


def finalize(plan: Plan, samples, run) -> dict:
    """RP (and AP when the frame is known) per cube point, mm."""
    pts = np.array([(t or {}).get("info", {}).get("point", 0) for t in samples.target])
    T = run.context.tracker_T_base_matrix
    out = {}
    for k in range(1, 6):
        X = samples.tracker_p_smr[pts == k]
        if len(X) == 0:
            continue
        mean = X.mean(axis=0)
        ell = np.linalg.norm(X - mean, axis=1)
        s = float(np.std(ell, ddof=1)) if len(ell) > 1 else 0.0
        entry = Iso9283Point(n=len(X), RP_mm=float(ell.mean() + 3 * s))
        if T is not None:
            xc = T[:3, :3] @ np.asarray(plan.targets[k - 1].base_p_tcp) + T[:3, 3]
            entry.AP_mm = float(np.linalg.norm(mean - xc))
        out[f"P{k}"] = entry
    summary = run.summary or RunSummary()
    summary.iso9283 = out
    return {"summary": summary}
