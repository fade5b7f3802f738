"""What a measurement file says about its capture: :class:`CaptureMeta`.

``cellcal export`` writes a run's context as ``# key: value`` comment lines at the top of
the measurement CSV (docs/formats.md §1); ``calibrate``, ``diagnose``, ``report``,
``zero`` read them back, and ``calibrate --out`` keeps them in params.json (``capture``),
so what the controller knew travels with the data:

=====================  ==========================================================
``run``                the run id in the store (``store``: the store's path)
``model``              the robot model the run was captured with (name or YAML path)
``tool_mm``            the controller's TCP in the flange frame, ``x, y, z`` mm: the
                       nominal tool of every later fit (``--tool-mm`` of the capture)
``smr_radius_mm``      radius of the SMR measured (the reflector's surface offset)
``reflector``          the reflector's name, when the tracker says it
``frame_run``          the frame run whose measurement frame the run used
``tracker_T_base``     that frame: 12 numbers, the rows of [R | t] (mm), robot base in
                       the tracker frame
``tracker_sigma_mm``   the tracker's standard uncertainty per axis, mm (RMS over points)
=====================  ==========================================================

Every key is optional; a malformed value is refused with a
:class:`~calibration.data.dataset.DataError` naming the file and the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..errors import DataError

if TYPE_CHECKING:
    from ..model.robot_model import RobotModel

#: the header keys this module reads (others are kept in ``Dataset.meta`` untouched)
KEYS = ("run", "store", "model", "tool_mm", "smr_radius_mm", "reflector", "frame_run",
        "tracker_T_base", "tracker_sigma_mm")


def _numbers(text: str, n: int, key: str, source: str) -> np.ndarray:

    try:
        v = np.array([float(s) for s in text.replace(";", ",").split(",") if s.strip()])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise DataError(f"{source}: metadata {key}: {text!r} is not {n} comma-separated "
                        "finite numbers")
    return v


def _positive(text: str, key: str, source: str) -> float:

    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (v > 0 and math.isfinite(v)):
        raise DataError(f"{source}: metadata {key}: {text!r} is not a positive number")
    return v


def _integer(text: str, key: str, source: str) -> int:

    try:
        return int(text)
    except ValueError:
        raise DataError(f"{source}: metadata {key}: {text!r} is not an integer") from None


def _fmt(v: float) -> str:
    return f"{float(v):.10g}"


@dataclass(frozen=True)
class CaptureMeta:
    """The capture context a measurement file carries (every field optional).

    Attributes
    ----------
    run : run id in the store; ``store`` the store's path
    model : the model the capture used (name or YAML path, as given)
    tool_mm : (3,) the controller's TCP in the flange frame, mm
    smr_radius_mm : radius of the SMR, mm; ``reflector`` its name
    frame_run : the frame run of ``tracker_T_base``
    tracker_T_base : (4, 4) robot base in the tracker frame (mm)
    tracker_sigma_mm : the tracker's standard uncertainty per axis, mm
    """

    run: int | None = None
    store: str | None = None
    model: str | None = None
    tool_mm: np.ndarray | None = None
    smr_radius_mm: float | None = None
    reflector: str | None = None
    frame_run: int | None = None
    tracker_T_base: np.ndarray | None = None
    tracker_sigma_mm: float | None = None

    @classmethod
    def from_meta(cls, meta: dict[str, str], source: str = "<data>") -> CaptureMeta:
        """Parse the ``# key: value`` metadata of a file (:class:`DataError` when bad)."""

        def get(key: str) -> str | None:
            v = meta.get(key)
            return v if v not in (None, "") else None

        T = None
        if get("tracker_T_base") is not None:
            T = np.eye(4)
            T[:3] = _numbers(meta["tracker_T_base"], 12, "tracker_T_base", source).reshape(3, 4)
            R = T[:3, :3]
            if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
                raise DataError(f"{source}: metadata tracker_T_base: its rotation is not a "
                                "rotation (rows of [R | t] expected)")
        return cls(
            run=None if get("run") is None else _integer(meta["run"], "run", source),
            store=get("store"),
            model=get("model"),
            tool_mm=None if get("tool_mm") is None
            else _numbers(meta["tool_mm"], 3, "tool_mm", source),
            smr_radius_mm=None if get("smr_radius_mm") is None
            else _positive(meta["smr_radius_mm"], "smr_radius_mm", source),
            reflector=get("reflector"),
            frame_run=None if get("frame_run") is None
            else _integer(meta["frame_run"], "frame_run", source),
            tracker_T_base=T,
            tracker_sigma_mm=None if get("tracker_sigma_mm") is None
            else _positive(meta["tracker_sigma_mm"], "tracker_sigma_mm", source),
        )

    def to_meta(self) -> dict[str, str]:
        """The ``# key: value`` lines (known fields only), in :data:`KEYS` order."""
        out = {}
        for key in KEYS:
            v = getattr(self, key)
            if v is None:
                continue
            if key == "tool_mm":
                out[key] = ", ".join(_fmt(a) for a in v)
            elif key == "tracker_T_base":
                out[key] = ", ".join(_fmt(a) for a in np.asarray(v)[:3].ravel())
            elif isinstance(v, float):
                out[key] = _fmt(v)
            else:
                out[key] = str(v)
        return out

    def to_json(self) -> dict:
        """JSON-ready (params.json's ``capture``): lists for arrays, None where unknown."""
        out = {}
        for key in KEYS:
            v = getattr(self, key)
            out[key] = v.tolist() if isinstance(v, np.ndarray) else v
        return out

    @classmethod
    def from_json(cls, doc: dict | None) -> CaptureMeta:
        """Inverse of :meth:`to_json` (unknown keys ignored)."""
        doc = doc or {}
        kw = {k: doc.get(k) for k in KEYS}
        for k in ("tool_mm", "tracker_T_base"):
            if kw[k] is not None:
                kw[k] = np.asarray(kw[k], float)
        return cls(**kw)

    @property
    def known(self) -> bool:
        """True when the file said anything about its capture."""
        return any(getattr(self, k) is not None for k in KEYS)

    def with_tool(self, model: RobotModel) -> RobotModel:
        """``model`` with the capture's tool (the controller's TCP) as its nominal tool;
        ``model`` itself when the capture did not record one."""
        if self.tool_mm is None:
            return model
        return model.with_changes(tool=tuple(float(v) for v in self.tool_mm))

    def describe(self) -> str:
        """One line for people: ``run 2 of cell.db, tool 0, 0, 60 mm, SMR r 19.05 mm``."""
        parts = []
        if self.run is not None:
            parts.append(f"run {self.run}" + (f" of {self.store}" if self.store else ""))
        if self.tool_mm is not None:
            parts.append("tool " + ", ".join(f"{v:g}" for v in self.tool_mm) + " mm")
        if self.smr_radius_mm is not None:
            parts.append(f"SMR radius {self.smr_radius_mm:g} mm")
        if self.tracker_T_base is not None:
            parts.append("measurement frame" + (f" of run {self.frame_run}"
                                                if self.frame_run is not None else ""))
        return ", ".join(parts)
