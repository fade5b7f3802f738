"""Why the tracker sees none of a robot's poses: the one constraint that hides the most.

When a plan finds no pose the tracker sees, a list of everything that might help misleads:
the cause is most often one thing. :func:`what_hides` draws poses facing the tracker and
counts, per constraint (the SMR facing away, each link in the beam, each fixture in the
beam), how many of them it hides. :func:`smr_inside_link` finds the case no pose can help:
the SMR centre inside a capsule of the last link (a tool offset shorter than that link's
radius, e.g. a model whose tool is the flange centre), so the wrist itself is in every
beam. Numbers only; the capture service words the advice (:mod:`daq.routines._common`).

Units: mm, rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.kinematics import tool_points
from ..model.robot_model import RobotModel
from .cell import CellSpec
from .visibility import assess, draw_facing, link_capsules, segment_distance


@dataclass(frozen=True)
class Hiding:
    """What hides the most of ``n`` poses drawn facing the tracker: ``what`` ("facing",
    "link K" or "fixture NAME") hides ``hidden`` of them."""

    what: str
    hidden: int
    n: int


def smr_inside_link(model: RobotModel, clearance_mm: float = 0.0, q: np.ndarray | None = None
                    ) -> tuple[int, float] | None:
    """The link (1-based) of the last row whose capsule, grown by ``clearance_mm``, holds the
    SMR centre (the model's tool point), and that capsule's radius (mm); None when the SMR is
    outside them. The capsule ends flat at the flange face, so an SMR at the flange centre
    is on its surface: inside once grown by any clearance. The last row's capsules move with
    the flange, so one pose (``q``, default all zeros) decides."""
    q = np.zeros((1, model.n_joints)) if q is None else np.atleast_2d(q)
    caps = link_capsules(model, q)
    p = tool_points(model, q)[:, None]  # (1, 1, 3)
    d = segment_distance(p, p, caps.a, caps.b)[0]
    last = caps.link == model.n_joints
    inside = last & (d < caps.radius + clearance_mm)
    if not inside.any():
        return None
    k = int(np.flatnonzero(inside)[0])
    return int(caps.link[k]), float(caps.radius[k])


def what_hides(model: RobotModel, cell: CellSpec, rng: np.random.Generator, *, n: int = 256,
               floor_z_mm: float | None = 0.0, max_reach_mm: float | None = None) -> Hiding:
    """The single constraint that hides the most of ``n`` poses drawn facing the tracker
    straight on (:func:`calibration.cell.visibility.draw_facing`, within the workspace), with the
    cell's margins. ``Hiding("", 0, 0)`` when no pose could be drawn (the workspace is
    empty: the floor or the reach rules out every pose)."""
    q = draw_facing(model, cell, n, rng, cone_rad=0.0, floor_z_mm=floor_z_mm,
                    max_reach_mm=max_reach_mm)
    if len(q) == 0:
        return Hiding("", 0, 0)
    s = assess(model, q, cell)
    counts = {"facing": int(np.sum(~s.facing_ok))}
    blocked = s.clearance_mm < s.clearance_min_mm
    for link in np.unique(s.capsule_link):
        counts[f"link {int(link)}"] = int(np.sum(blocked[:, s.capsule_link == link].any(axis=1)))
    for j, name in enumerate(s.fixture_names):
        counts[f"fixture {name}"] = int(np.sum(s.fixture_hit[:, j]))
    what = max(counts, key=counts.__getitem__)
    return Hiding(what, counts[what], len(q))
