"""Questions asked of a run store by the capture service: which frame run holds for a
robot in a cell."""

from __future__ import annotations

from ..devices import CellIdentity, stored_identity
from .errors import StoreError
from .records import Run
from .runstore import RunStore


def same_robot(r: Run, robot_id: str | None, robot_url: str | None) -> bool:
    """Run ``r`` measured this robot: the same robot id when both know theirs; the same URL
    when only one does; any run when neither does (a store of one cell) or nothing is
    known of this robot (``robot_id`` and ``robot_url`` None)."""
    if robot_id and r.robot_id:
        return r.robot_id == robot_id
    if robot_id is None and robot_url is None:
        return True
    if robot_id or r.robot_id:
        return r.robot_url == robot_url
    return True


def frame_run(store: RunStore, run_id: int | None, cell: CellIdentity | None = None,
              robot_id: str | None = None, robot_url: str | None = None) -> Run | None:
    """The frame run ``run_id`` (it must have a frame), else the latest completed frame
    run of the store measured in ``cell`` (a run without stored identities counts as
    any cell's) of the same robot (``robot_id``, ``robot_url``: :func:`same_robot`),
    else None."""
    if run_id is not None:
        r = store.run(run_id)
        if r.frame is None:
            raise StoreError(f"run {run_id} has no measurement frame (not a completed "
                             "frame run)")
        return r
    for r in reversed(store.runs()):
        if (r.routine == "frame" and r.status == "completed" and r.frame is not None
                and (cell is None or measured_in(r, cell))
                and same_robot(r, robot_id, robot_url)):
            return r
    return None


def measured_in(run: Run, cell: CellIdentity) -> bool:
    for stored, now in ((run.robot_identity, cell.robot), (run.tracker_identity, cell.tracker)):
        old = stored_identity(stored)
        if old is not None and not old.same_device(now):
            return False
    return True
