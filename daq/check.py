"""Dry run of a plan against the robot model, before any motion.

:func:`check_plan` checks every target against

* the model's joint limits (``q`` of joint and zero targets, the expected
  joints of linear targets, and every ``via`` in joints);
* reach: a linear target must be reachable (its expected joints put the tool
  within ``reach_tol_mm`` of it), and every tool point must lie within
  ``max_reach_mm`` of the base origin when that is given;
* a floor plane: the origin of every link frame and the tool point must be at
  ``z >= floor_z_mm`` (robot base frame);
* keep-out boxes (link origins and tool point outside them);
* the moves between consecutive postures: no linear move that would have to turn a
  joint by more than half a turn; with ``limits.check_paths`` also the floor, keep-out
  boxes and reach along each joint move.

The checks are the executor's own (:class:`daq.motion_guard.MotionGuard`), which repeats
them before every move it sends. A plan that fails is refused with the offending targets
named: index, label, which joint and limit, or which point lies below the floor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import PlanRefused
from .motion_guard import MotionGuard, MotionLimits
from .plans import Plan


@dataclass
class Problem:
    """One reason to refuse a target."""

    index: int
    label: str
    message: str

    def __str__(self) -> str:
        return f"point {self.index} ({self.label}): {self.message}"


@dataclass
class CheckResult:
    """Outcome of :func:`check_plan`: ``ok`` and the problems found (at most a few per target)."""

    n_targets: int
    problems: list[Problem] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems

    @property
    def bad_indices(self) -> list[int]:
        return sorted({p.index for p in self.problems})

    def report(self, limit: int = 20) -> str:
        """Human-readable summary naming the offending targets."""
        if self.ok:
            return f"plan ok: {self.n_targets} targets within limits, reach and above the floor"
        lines = [f"plan refused: {len(self.bad_indices)} of {self.n_targets} targets fail the "
                 "dry run"]
        lines += [f"  {p}" for p in self.problems[:limit]]
        if len(self.problems) > limit:
            lines.append(f"  ... and {len(self.problems) - limit} more")
        return "\n".join(lines)


def check_plan(
    plan: Plan,
    model,
    *,
    floor_z_mm: float | None = 0.0,
    max_reach_mm: float | None = None,
    reach_tol_mm: float = 0.5,
    limits: MotionLimits | None = None,
) -> CheckResult:
    """Dry-run ``plan`` against ``model`` (a :class:`calibration.RobotModel`).

    Parameters
    ----------
    plan : Plan
    model : RobotModel
    floor_z_mm : float or None
        Lowest allowed z (mm, base frame) of every link origin after the first joint
        and of the tool point; None: no floor check.
    max_reach_mm : float or None
        Largest allowed distance (mm) of the tool point from the base origin.
    reach_tol_mm : float
        A linear target whose expected joints miss it by more than this is unreachable.
    limits : MotionLimits, optional
        The run's motion limits (floor, reach, keep-out boxes); when given, ``floor_z_mm``
        and ``max_reach_mm`` are taken from it.

    Returns
    -------
    CheckResult
    """
    if limits is None:
        limits = MotionLimits(floor_z_mm=floor_z_mm, max_reach_mm=max_reach_mm)
    guard = MotionGuard(model, limits)
    res = CheckResult(len(plan))
    N = model.n_joints
    rows, qs, what = [], [], []
    for t in plan.targets:
        for name, q in (("via", t.via if t.move != "linear" else None), ("target", t.q)):
            if q is None:
                continue
            if len(q) != N:
                res.problems.append(Problem(t.index, t.label, f"{name} has {len(q)} joints, the "
                                            f"model {model.name} has {N}"))
                continue
            rows.append(t)
            qs.append(q)
            what.append(name)
        if t.move == "linear" and t.q is None:
            res.problems.append(Problem(t.index, t.label, "linear target without expected "
                                        "joints: cannot be checked (unreachable?)"))
    if not qs:
        return res
    Q = np.asarray(qs, float)
    for r, msg in guard.pose_problems(Q):
        res.problems.append(Problem(rows[r].index, rows[r].label, f"{what[r]} {msg}"))
    tip = guard.tool_points(Q)
    for r, t in enumerate(rows):
        if what[r] == "target" and t.move == "linear":
            miss = float(np.linalg.norm(tip[r] - np.asarray(t.base_p_tcp)))
            if miss > reach_tol_mm:
                res.problems.append(Problem(t.index, t.label, f"unreachable: the expected joints "
                                            f"miss the target by {miss:.2f} mm"))
    _check_moves(res, guard, rows, Q, what)
    res.problems.sort(key=lambda p: p.index)
    return res


def _check_moves(res: CheckResult, guard: MotionGuard, rows, Q: np.ndarray, what) -> None:
    """The moves between consecutive postures: linear moves that would have to turn a
    joint more than half a turn (the controller moves the short way), and with
    ``check_paths`` the floor, keep-out and reach along each joint move (one vectorised
    pass over every sampled posture)."""
    paths, owner = [], []
    for r in range(1, len(rows)):
        t = rows[r]
        if t.move == "linear" and what[r] == "target":
            turn = np.abs(Q[r] - Q[r - 1])
            for j in np.flatnonzero(turn > np.pi):
                res.problems.append(Problem(t.index, t.label, (
                    f"a linear move from {what[r - 1]} of point {rows[r - 1].index} would turn "
                    f"joint {j + 1} by {np.degrees(turn[j]):.1f} deg: the controller moves "
                    "the short way and would not land on the planned posture")))
            continue
        if not guard.limits.check_paths:
            continue
        P = guard.path(Q[r - 1], Q[r])[1:-1]  # the ends are checked as postures
        paths.append(P)
        owner += [r] * len(P)
    if not paths:
        return
    seen = set()
    for k, msg in guard.space_problems(np.vstack(paths)):
        r = owner[k]
        if r not in seen:  # the first posture on the way that breaks it
            seen.add(r)
            t = rows[r]
            res.problems.append(Problem(t.index, t.label, f"on the way to the {what[r]}: {msg}"))


def require_ok(plan: Plan, model, **kw) -> CheckResult:
    """:func:`check_plan`, raising :class:`~daq.errors.PlanRefused` when the plan fails."""
    res = check_plan(plan, model, **kw)
    if not res.ok:
        raise PlanRefused(res)
    return res
