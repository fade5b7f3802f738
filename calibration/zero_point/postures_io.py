"""Zero-point postures as data: :class:`Postures`, the postures CSV (docs/formats.md §1) read
strictly by :func:`load_postures`, and :func:`postures_from_dataset` for a
:class:`~calibration.data.dataset.Dataset` (e.g. a ``zero20`` run from the store).

Lengths mm, angles rad; degrees only in files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..data.dataset import MAX_LENGTH_MM, PLAUSIBLE_LENGTH, CsvTable, DataError, Dataset
from ..files import write_atomic
from ..model.robot_model import RobotModel


@dataclass
class Postures:
    """Recorded zero-point postures.

    Attributes
    ----------
    q : (n, N) joint readings of the controller, rad
    plane : (n,) plane number 1..4 of each posture
    pose_id : n labels
    base_p_tip : (n, 3) measured tip in the robot base frame, mm (usable as measured tips
        as they are, see :func:`~calibration.zero_point.rigorous_method`), or None
    tracker_p_tip : (n, 3) measured tip in the tracker (measurement) frame, mm, or None:
        usable only with the base's pose (e.g. a calibrated model's ``base``), see
        :meth:`tips_in_base`. At most one of ``base_p_tip`` and ``tracker_p_tip`` is given.
    source : where they came from
    lines : (n,) file line of each row (0 when not from a file)
    """

    q: np.ndarray
    plane: np.ndarray
    pose_id: list[str] = field(default_factory=list)
    base_p_tip: np.ndarray | None = None
    tracker_p_tip: np.ndarray | None = None
    source: str = "<arrays>"
    lines: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, float))
        n = len(self.q)
        self.plane = np.asarray(self.plane, int)
        if self.base_p_tip is not None and self.tracker_p_tip is not None:
            raise ValueError("measured tips are either in the base or in the tracker frame")
        if not self.pose_id:
            self.pose_id = [str(i + 1) for i in range(n)]
        if self.lines is None:
            self.lines = np.zeros(n, int)

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def tip_frame(self) -> str | None:
        """``"base"`` or ``"tracker"``: the frame of the measured tips (None without)."""
        if self.base_p_tip is not None:
            return "base"
        return "tracker" if self.tracker_p_tip is not None else None

    def subset(self, keep: np.ndarray) -> Postures:
        idx = np.arange(self.n)[keep]

        def pick(a: np.ndarray | None) -> np.ndarray | None:
            return None if a is None else a[idx]

        return Postures(self.q[idx], self.plane[idx], [self.pose_id[i] for i in idx],
                        base_p_tip=pick(self.base_p_tip), tracker_p_tip=pick(self.tracker_p_tip),
                        source=self.source, lines=pick(self.lines))

    def tips_in_base(self, tracker_R_base: np.ndarray, tracker_p_base: np.ndarray) -> Postures:
        """These postures with the tracker-frame tips mapped into the base frame, given the
        base's pose in the tracker frame (rotation (3, 3), origin (3,) mm)."""
        tips = (self.tracker_p_tip - tracker_p_base) @ tracker_R_base
        return Postures(self.q, self.plane, self.pose_id, base_p_tip=tips, source=self.source,
                        lines=self.lines)

    def to_csv(self, path: str | Path | None = None, meta: dict | None = None) -> str:
        """The postures CSV (deg); returns the text, writes it when a path is given.

        ``meta`` becomes ``# key: value`` comment lines before the header; with measured
        tips in the tracker frame, ``xyz_frame: tracker`` is always written.
        """
        N = self.q.shape[1]
        head = ["pose_id", "plane"] + [f"q{j + 1}" for j in range(N)]
        meta = dict(meta or {})
        tips = self.base_p_tip if self.base_p_tip is not None else self.tracker_p_tip
        if tips is not None:
            head += ["x", "y", "z"]
            if self.tip_frame != "base":
                meta["xyz_frame"] = self.tip_frame
        lines = [f"# {k}: {v}" for k, v in meta.items()] + [",".join(head)]
        qd = np.degrees(self.q)
        for i in range(self.n):
            row = [self.pose_id[i], str(int(self.plane[i]))] + [repr(float(v)) for v in qd[i]]
            if tips is not None:
                row += [repr(float(v)) for v in tips[i]]
            lines.append(",".join(row))
        text = "\n".join(lines) + "\n"
        if path is not None:
            write_atomic(path, text)
        return text


def load_postures(path: str | Path, model: RobotModel, *, check_limits: bool = True) -> Postures:
    """Read a zero-point postures CSV (docs/formats.md §1): ``pose_id, plane, q1..qN`` (deg),
    optional ``x, y, z`` (mm). Errors name the file, line and column; nothing is guessed.

    The tips are in the robot base frame unless a ``# xyz_frame: tracker`` comment says
    they are in the measurement frame (as ``cellcal export --postures`` writes them)."""
    t = CsvTable(path)
    N = model.n_joints
    t.require(["pose_id", "plane"] + [f"q{j + 1}" for j in range(N)],
              f"pose_id, plane, q1..q{N} are required")
    measured = t.all_or_none(["x", "y", "z"], "measured tips")
    q = t.joints_deg(model, check_limits)
    plane = t.numeric("plane")
    for r, v in enumerate(plane):
        if v not in (1.0, 2.0, 3.0, 4.0):
            raise DataError(f"{t.source}: line {t.lines[r]}, column plane: {v:g} is not 1, 2, "
                            "3 or 4")
    pose_id = t.ids("pose_id")
    tips = np.column_stack([t.numeric(c) for c in "xyz"]) if measured else None
    if tips is not None:
        for k, c in enumerate("xyz"):
            t.within(c, tips[:, k], -MAX_LENGTH_MM, MAX_LENGTH_MM, PLAUSIBLE_LENGTH)
    frame = t.meta.get("xyz_frame", "base").strip().lower()
    if frame not in ("base", "tracker"):
        raise DataError(f"{t.source}: xyz_frame: {frame!r} is not base or tracker")
    in_base = frame == "base"
    return Postures(np.radians(q), plane.astype(int), pose_id,
                    base_p_tip=tips if in_base else None,
                    tracker_p_tip=None if in_base else tips, source=t.source, lines=t.lines)


def postures_from_dataset(data: Dataset, plane: np.ndarray | None = None,
                          measured: bool = True) -> Postures:
    """Postures from a :class:`Dataset` (e.g. a ``zero20`` run from the store).

    ``plane`` (n,) defaults to 5 consecutive postures per plane; ``measured`` keeps the
    data's ``tracker_p_smr`` (mm) as measured tips, in the tracker frame
    (``tracker_p_tip``; see :meth:`Postures.tips_in_base`).
    """
    if plane is None:
        plane = np.arange(data.n) // 5 % 4 + 1
    return Postures(data.q, plane, list(data.pose_id),
                    tracker_p_tip=data.tracker_p_smr if measured else None, source=data.source,
                    lines=data.lines)
