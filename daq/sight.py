"""The tracker's line of sight for a capture: which cell a plan is made for, what the tracker
will see of it, and how long it will take.

:func:`resolve_cell` puts the tracker where the best source says: ``--tracker-at`` (the
user's rough position) first, then the measurement frame of a frame run in the store
(``tracker_T_base``, measured), then the cell file; no source leaves the tracker unknown,
and :func:`require_tracker` refuses to plan blind (unless the reflector accepts every
direction; the caller may waive the line of sight). :func:`predict` checks every target
of a plan against it (:func:`calibration.cell.visibility.assess`, with the cell's margins)
and :func:`estimate_time` estimates the capture time from the executor's speed.

Units: mm, rad, s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.cell.cell import CellSpec, tracker_in_base

from .errors import TrackerUnknown
from .plans import Plan, estimate_capture_s
from .store import open_if_exists
from .store.queries import frame_run


def resolve_cell(cell: CellSpec | None, tracker_at, frame_T=None,
                 frame_run: int | None = None) -> CellSpec:
    """The cell a plan is made for: ``cell`` (or the defaults) with the tracker from
    ``tracker_at`` (3 values, mm, robot base frame), else from the measurement frame
    ``frame_T`` (4x4 ``tracker_T_base`` of frame run ``frame_run``), else the cell's own."""
    cell = cell or CellSpec()
    if tracker_at is not None:
        return cell.with_tracker(tracker_at, "--tracker-at")
    if frame_T is not None:
        return cell.with_tracker(tracker_in_base(frame_T), f"frame run {frame_run}")
    return cell


#: what ``require_tracker`` says: the three ways to give the tracker's position, and the waiver
GIVE_TRACKER = ("give it one of three ways: --tracker-at X,Y,Z (robot base frame, mm; rough "
                "is fine), a frame run in --db (`cellcal capture frame --tracker-at ...` "
                "first; --frame-run RUN picks one), or --cell FILE with the tracker's "
                "position; or plan without the line of sight: --no-visibility")


def require_tracker(cell: CellSpec) -> None:
    """Refuse (:class:`~daq.errors.TrackerUnknown`) a plan made blind: the tracker's position
    unknown while the reflector has a facing limit. A plan that does not know where the
    tracker stands draws poses whose SMR faces away or whose beam a link breaks: at a real
    cell most of its points are skipped after an hour of motion."""
    if cell.tracker is not None or cell.smr.half_angle_deg >= 180.0:
        return
    raise TrackerUnknown(
        "the tracker's position is unknown, so the plan cannot keep to the tracker's line of "
        f"sight (the {cell.smr.reflector} SMR accepts the beam within "
        f"{cell.smr.half_angle_deg:g} deg only, and links break it); {GIVE_TRACKER}")


def frame_from_store(db: str | Path | None, run_id: int | None) -> tuple[np.ndarray | None,
                                                                          int | None]:
    """The measurement frame (``tracker_T_base``, 4x4) of frame run ``run_id`` (default: the
    latest completed one) in the run store ``db``, and that run's id; (None, None) when the
    store does not exist yet or has no frame."""
    store = None if db is None else open_if_exists(db)
    if store is None:
        return None, None
    with store:
        r = frame_run(store, run_id)
    return (None, None) if r is None else (np.asarray(r.frame["tracker_T_base"], float), r.id)


@dataclass
class SightReport:
    """What the tracker will see of a plan: ``hidden`` lists (index, label, reason) of the
    targets it would not see; ``cell`` the cell it was checked against (None: unknown)."""

    n_points: int
    cell: CellSpec | None
    hidden: list[tuple[int, str, str]] = field(default_factory=list)

    @property
    def checked(self) -> bool:
        return self.cell is not None and self.cell.tracker is not None

    def report(self, limit: int = 20) -> str:
        if not self.checked:
            return ("line of sight: not checked, the tracker position is unknown (give "
                    "--tracker-at X,Y,Z in the robot base frame, mm, or --cell FILE, or run "
                    "`cellcal capture frame` first)")
        c = self.cell
        head = (f"line of sight: tracker at {np.round(c.tracker_mm).astype(int).tolist()} mm "
                f"({c.tracker_source}), SMR {c.smr.reflector} +-{c.smr.half_angle_deg:g} deg, "
                f"margins {c.margins.facing_deg:g} deg / {c.margins.clearance_mm:g} mm: "
                f"{self.n_points - len(self.hidden)} of {self.n_points} points visible")
        lines = [head] + [f"  not visible: point {i} ({label}): {why}"
                          for i, label, why in self.hidden[:limit]]
        if len(self.hidden) > limit:
            lines.append(f"  ... and {len(self.hidden) - limit} more")
        return "\n".join(lines)

    def to_json(self) -> dict:
        return {"checked": self.checked,
                "tracker_mm": None if not self.checked else self.cell.tracker_mm.tolist(),
                "tracker_source": None if not self.checked else self.cell.tracker_source,
                "visible": self.n_points - len(self.hidden),
                "hidden": [{"point": i, "label": label, "reason": why}
                           for i, label, why in self.hidden]}


def predict(plan: Plan, model, cell: CellSpec | None) -> SightReport:
    """Which targets of ``plan`` the tracker would not see (targets with joints: joint and
    zero targets, the expected joints of linear ones)."""
    rows = [t for t in plan.targets if t.q is not None and len(t.q) == model.n_joints]
    out = SightReport(len(plan), cell)
    if not out.checked or not rows:
        return out
    from calibration.cell.visibility import assess

    s = assess(model, np.array([t.q for t in rows], float), cell)
    out.hidden = [(rows[i].index, rows[i].label, s.reason(i)) for i in np.flatnonzero(~s.visible)]
    return out


def estimate_time(plan: Plan, executor) -> dict:
    """Estimated capture time (s) of ``plan`` with the executor options ``executor`` (joint
    speed, measuring time, dwell): in the plan's order and, when the plan recorded it, in a
    random order."""
    kw = {"measure_s": executor.measure_s, "dwell_s": executor.dwell_s}
    plan_s = estimate_capture_s(plan, executor.speed_rad_s, **kw)
    out = {"estimated_capture_s": plan_s}
    rnd = plan.params.get("joint_travel_random_order_rad")
    travel = plan.params.get("joint_travel_rad")
    if rnd is not None and travel is not None:
        out["estimated_capture_random_order_s"] = plan_s + (rnd - travel) / executor.speed_rad_s
    return out


def format_time(estimate: dict) -> str:
    """One line: the estimated capture time (and that of a random order)."""
    s = estimate["estimated_capture_s"]
    text = f"estimated capture time {s / 60:.1f} min"
    rnd = estimate.get("estimated_capture_random_order_s")
    if rnd:
        text += f" (in a random order {rnd / 60:.1f} min: this order takes {s / rnd:.2f} of it)"
    return text

