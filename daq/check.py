"""Dry run of a plan against the robot model, before any motion.

:func:`check_plan` checks every target against

* the model's joint limits (``q`` of joint and zero targets, the expected
  joints of linear targets, and every ``via`` in joints);
* reach: a linear target must be reachable (its expected joints put the tool
  within ``reach_tol_mm`` of it), and every tool point must lie within
  ``max_reach_mm`` of the base origin when that is given;
* a floor plane: the origin of every link frame and the tool point must be at
  ``z >= floor_z_mm`` (robot base frame).

A plan that fails is refused with the offending targets named: index, label,
which joint and limit, or which point lies below the floor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from calibration.kinematics import run_chain

from .errors import PlanRefused
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


_LIMIT_TOL = 1e-9


def check_plan(
    plan: Plan,
    model,
    *,
    floor_z_mm: float | None = 0.0,
    max_reach_mm: float | None = None,
    reach_tol_mm: float = 0.5,
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

    Returns
    -------
    CheckResult
    """
    res = CheckResult(len(plan))
    N = model.n_joints
    lim = model.limits_rad()
    rows, qs, what = [], [], []
    for t in plan.targets:
        for name, q in (("target", t.q), ("via", t.via if t.move != "linear" else None)):
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
    lo = (Q - lim[:, 0]) < -_LIMIT_TOL
    hi = (Q - lim[:, 1]) > _LIMIT_TOL
    for r, j in zip(*np.nonzero(lo | hi), strict=True):
        t, side = rows[r], "min" if lo[r, j] else "max"
        bound = np.degrees(lim[j, 0 if side == "min" else 1])
        res.problems.append(Problem(
            t.index, t.label, f"{what[r]} joint {j + 1} = {np.degrees(Q[r, j]):.3f} deg beyond "
            f"its {side} limit {bound:g} deg"))
    chain = run_chain(model.convention, model.dh_table(), Q, model.tool_mm(), jacobian=False,
                      prismatic=model.prismatic_mask())
    tip = chain.base_p_tcp
    for r, t in enumerate(rows):
        if what[r] == "target" and t.move == "linear":
            miss = float(np.linalg.norm(tip[r] - np.asarray(t.base_p_tcp)))
            if miss > reach_tol_mm:
                res.problems.append(Problem(t.index, t.label, f"unreachable: the expected joints "
                                            f"miss the target by {miss:.2f} mm"))
    if max_reach_mm is not None:
        dist = np.linalg.norm(tip, axis=1)
        for r in np.flatnonzero(dist > max_reach_mm):
            t = rows[r]
            res.problems.append(Problem(t.index, t.label, f"{what[r]} tool point "
                                        f"{dist[r]:.1f} mm from the base, beyond the reach "
                                        f"limit {max_reach_mm:g} mm"))
    if floor_z_mm is not None:
        # link origins after each joint (index 1..N) and the tool point
        z = np.concatenate([chain.frames_p[:, 1:, 2], tip[:, 2:3]], axis=1)
        for r, k in zip(*np.nonzero(z < floor_z_mm), strict=True):
            t = rows[r]
            name = "tool point" if k == N else f"origin of link {k + 1}"
            res.problems.append(Problem(t.index, t.label, f"{what[r]} {name} at z = "
                                        f"{z[r, k]:.1f} mm, below the floor {floor_z_mm:g} mm"))
    res.problems.sort(key=lambda p: p.index)
    return res


def require_ok(plan: Plan, model, **kw) -> CheckResult:
    """:func:`check_plan`, raising :class:`~daq.errors.PlanRefused` when the plan fails."""
    res = check_plan(plan, model, **kw)
    if not res.ok:
        raise PlanRefused(res)
    return res
