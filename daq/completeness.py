"""Whether a run that went through its plan measured what the plan asked for.

A point whose beam stays broken is skipped and a spare measured in its place
(:mod:`daq.executor`). A run that reached the end of its plan ends ``completed`` when
at most :data:`MISSING_SHARE` of the plan's points are missing (skipped and not
replaced), else ``incomplete`` (:class:`~daq.store.RunStatus`): a run that measured 4
of 40 points is not a success, whatever the executor did right at each point. Its
reason names how many are missing, which, and what to do; ``cellcal capture`` and
``resume`` exit with 3 (the data too poor for what was asked), ``cellcal runs`` shows
the reason.
"""

from __future__ import annotations

from .plans import Plan
from .store import RunStatus

#: the share of a plan's points a run may miss (skipped, not replaced by a spare) and still
#: end ``completed``: a tenth lets a short plan (a frame's 23 points, a steps run's 3 x 14)
#: lose two or three points to a beam break and still serve (a frame run that is not
#: ``completed`` gives no measurement frame), while a plan whose line of sight is wrong
#: (most of its points hidden) is caught; ``poses`` plans 5 % spares on top
MISSING_SHARE = 0.10


def end_status(plan: Plan, done: set[int], skipped: set[int]) -> tuple[RunStatus, str | None]:
    """The status (and reason) of a run that went through ``plan`` with the point indices
    ``done`` stored and ``skipped`` given up (their beam stayed broken): ``completed``, or
    ``incomplete`` with the missing points named. Points neither stored nor skipped were
    not needed (a routine that reached its goal early: a settled warm-up) and are not
    missing."""
    skipped = [t.index for t in plan.targets
               if not t.spare and t.index not in done and t.index in skipped]
    spares = sum(plan.targets[i].spare for i in done if i < len(plan.targets))
    missing = len(skipped) - spares
    if missing <= MISSING_SHARE * plan.n_planned:
        return RunStatus.COMPLETED, None
    shown = ", ".join(map(str, skipped[:10])) + (", ..." if len(skipped) > 10 else "")
    if plan.params.get("visibility"):
        change = ("check where the tracker stands and the cell's fixtures (`cellcal capture "
                  "... --dry-run` lists the points it expects hidden)")
    else:
        change = ("the plan was made without the tracker's line of sight: plan with the "
                  "tracker's position (--tracker-at, a frame run in --db or --cell)")
    return RunStatus.INCOMPLETE, (
        f"{missing} of {plan.n_planned} planned points missing (more than "
        f"{MISSING_SHARE:.0%}): {len(skipped)} skipped as their beam stayed broken "
        f"[{shown}], {spares} spares measured in their place; skipped points are not "
        f"retried: {change}, then capture a new run")
