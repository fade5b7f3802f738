"""Zero-point postures as data: :class:`Postures`, the postures CSV (FORMATS.md §1) read
strictly by :func:`load_postures`, and :func:`postures_from_dataset` for a
:class:`~calibration.dataset.Dataset` (e.g. a ``zero20`` run from the store).

Lengths mm, angles rad; degrees only in files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..dataset import CsvTable, DataError, Dataset
from ..robot_model import RobotModel


@dataclass
class Postures:
    """Recorded zero-point postures.

    Attributes
    ----------
    q : (n, N) joint readings of the controller, rad
    plane : (n,) plane number 1..4 of each posture
    pose_id : n labels
    xyz : (n, 3) measured tip, or None (frame: see :func:`rigorous_method`), mm
    source : where they came from
    lines : (n,) file line of each row (0 when not from a file)
    xyz_frame : the frame of ``xyz``: ``"base"`` (the robot base frame, usable as
        measured tips as they are) or ``"tracker"`` (the measurement frame: usable only
        with the base's pose, e.g. a calibrated model's ``base``)
    """

    q: np.ndarray
    plane: np.ndarray
    pose_id: list[str] = field(default_factory=list)
    xyz: np.ndarray | None = None
    source: str = "<arrays>"
    lines: np.ndarray | None = None
    xyz_frame: str = "base"

    def __post_init__(self) -> None:
        self.q = np.atleast_2d(np.asarray(self.q, float))
        n = len(self.q)
        self.plane = np.asarray(self.plane, int)
        if not self.pose_id:
            self.pose_id = [str(i + 1) for i in range(n)]
        if self.lines is None:
            self.lines = np.zeros(n, int)

    @property
    def n(self) -> int:
        return len(self.q)

    def subset(self, keep: np.ndarray) -> Postures:
        idx = np.arange(self.n)[keep]
        return Postures(self.q[idx], self.plane[idx], [self.pose_id[i] for i in idx],
                        None if self.xyz is None else self.xyz[idx], self.source, self.lines[idx],
                        self.xyz_frame)

    def to_csv(self, path: str | Path | None = None, meta: dict | None = None) -> str:
        """The postures CSV (deg); returns the text, writes it when a path is given.

        ``meta`` becomes ``# key: value`` comment lines before the header; with measured
        tips in the tracker frame, ``xyz_frame: tracker`` is always written.
        """
        N = self.q.shape[1]
        head = ["pose_id", "plane"] + [f"q{j + 1}" for j in range(N)]
        meta = dict(meta or {})
        if self.xyz is not None:
            head += ["x", "y", "z"]
            if self.xyz_frame != "base":
                meta["xyz_frame"] = self.xyz_frame
        lines = [f"# {k}: {v}" for k, v in meta.items()] + [",".join(head)]
        qd = np.degrees(self.q)
        for i in range(self.n):
            row = [self.pose_id[i], str(int(self.plane[i]))] + [repr(float(v)) for v in qd[i]]
            if self.xyz is not None:
                row += [repr(float(v)) for v in self.xyz[i]]
            lines.append(",".join(row))
        text = "\n".join(lines) + "\n"
        if path is not None:
            Path(path).write_text(text)
        return text


def load_postures(path: str | Path, model: RobotModel, *, check_limits: bool = True) -> Postures:
    """Read a zero-point postures CSV (FORMATS.md §1): ``pose_id, plane, q1..qN`` (deg),
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
    xyz = np.column_stack([t.numeric(c) for c in "xyz"]) if measured else None
    frame = t.meta.get("xyz_frame", "base").strip().lower()
    if frame not in ("base", "tracker"):
        raise DataError(f"{t.source}: xyz_frame: {frame!r} is not base or tracker")
    return Postures(np.radians(q), plane.astype(int), pose_id, xyz, t.source, t.lines, frame)


def postures_from_dataset(data: Dataset, plane: np.ndarray | None = None,
                          measured: bool = True, xyz_frame: str = "base") -> Postures:
    """Postures from a :class:`Dataset` (e.g. a ``zero20`` run from the store).

    ``plane`` (n,) defaults to 5 consecutive postures per plane; ``measured`` keeps the
    data's ``xyz`` (mm) as measured tips, in the frame ``xyz_frame`` (``"base"`` or
    ``"tracker"``, see :class:`Postures`).
    """
    if plane is None:
        plane = np.arange(data.n) // 5 % 4 + 1
    return Postures(data.q, plane, list(data.pose_id), data.xyz if measured else None,
                    data.source, data.lines, xyz_frame)
