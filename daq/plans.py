"""Plans as data: a list of targets with stable indices, the routine's parameters, a hash.

A :class:`Plan` is what a routine (:mod:`daq.routines`) produces and what the
executor (:mod:`daq.executor`) runs. It is plain data: it can be dry-run
(:func:`daq.check.check_plan`), stored as JSON in the run store and compared
by its content hash (sha256 of a canonical JSON text) — a resumed run refuses
a plan whose hash differs from the stored one.

Units: joints in rad, positions in mm (robot base frame). In the JSON a target's
``base_p_tcp`` is the key ``xyz`` (the stored plans and their hashes keep it).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: how a target is reached
MOVES = ("joints", "linear", "zero")


def _clean(o: Any) -> Any:
    """JSON-ready copy: numpy scalars/arrays to Python, tuples to lists."""
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean(o.tolist())
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, (np.floating, float)):
        return float(o)
    return o


def _vec(v) -> tuple[float, ...] | None:
    return None if v is None else tuple(float(x) for x in np.asarray(v, float).ravel())


@dataclass(frozen=True)
class Target:
    """One point of a plan.

    Attributes
    ----------
    index : int
        Stable index within the plan (0-based); the store's key with the run id.
    move : {"joints", "linear", "zero"}
        ``joints``: joint move to ``q``; ``linear``: linear TCP move to ``base_p_tcp``;
        ``zero``: joint move to ``q``, then the routine's acquisition decides the
        joints (zero20 closes the loop with the tracker until the tool tip is on the
        run's zero-point target, see :mod:`daq.routines.zero20`).
    q : tuple of float, shape (N,), rad, optional
        Joint target (``joints``/``zero``), or the joints expected at ``base_p_tcp``
        for a ``linear`` target (used by the dry run only).
    base_p_tcp : tuple of float, shape (3,), mm, optional
        TCP target in the robot base frame (``linear``), or the nominal target
        point (``zero``).
    via : tuple of float, optional
        A pre-position of the same kind as ``move`` (joints, rad, or xyz, mm)
        visited first, so the target is always approached from the same side.
    set : {"calib", "valid"}
        Role of the sample in a calibration.
    label : str
        Human label (becomes ``pose_id`` when the CSV is exported).
    info : dict
        Routine-specific extras (plane, cycle, axis...). JSON-serialisable.
    """

    index: int
    move: str
    q: tuple[float, ...] | None = None
    base_p_tcp: tuple[float, ...] | None = None
    via: tuple[float, ...] | None = None
    set: str = "calib"
    label: str = ""
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.move not in MOVES:
            raise ValueError(f"target {self.index}: move must be one of {MOVES}, got {self.move!r}")
        if self.set not in ("calib", "valid"):
            raise ValueError(f"target {self.index}: set must be calib or valid, got {self.set!r}")
        object.__setattr__(self, "q", _vec(self.q))
        object.__setattr__(self, "base_p_tcp", _vec(self.base_p_tcp))
        object.__setattr__(self, "via", _vec(self.via))
        if self.move in ("joints", "zero") and self.q is None:
            raise ValueError(f"target {self.index}: a {self.move} target needs q")
        if self.move == "linear" and (self.base_p_tcp is None or len(self.base_p_tcp) != 3):
            raise ValueError(f"target {self.index}: a linear target needs xyz (3 values)")
        if not self.label:
            object.__setattr__(self, "label", str(self.index + 1))

    def to_dict(self) -> dict:
        """JSON-ready dict (only the fields that are set; ``base_p_tcp`` as ``xyz``)."""
        d: dict[str, Any] = {"index": self.index, "move": self.move, "set": self.set,
                             "label": self.label}
        for k, v in (("q", self.q), ("xyz", self.base_p_tcp), ("via", self.via)):
            if v is not None:
                d[k] = list(v)
        if self.info:
            d["info"] = _clean(self.info)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Target:
        return cls(index=int(d["index"]), move=d["move"], q=d.get("q"),
                   base_p_tcp=d.get("xyz"), via=d.get("via"), set=d.get("set", "calib"),
                   label=d.get("label", ""), info=dict(d.get("info", {})))


@dataclass(frozen=True)
class Plan:
    """A routine's plan: targets with stable indices, the parameters that made them.

    Attributes
    ----------
    routine : str
        Routine name (``frame``, ``steps``, ``zero20``, ``poses``, ``iso9283``).
    params : dict
        The routine's parameters (JSON-serialisable; units in the key names).
    targets : tuple of Target
        Indices must be 0..n-1 in order.
    model : str
        Name of the robot model the plan was made for.
    """

    routine: str
    params: dict
    targets: tuple[Target, ...]
    model: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "targets", tuple(self.targets))
        object.__setattr__(self, "params", _clean(self.params))
        for i, t in enumerate(self.targets):
            if t.index != i:
                raise ValueError(f"plan {self.routine}: target at position {i} has index {t.index}")

    def __len__(self) -> int:
        return len(self.targets)

    def to_dict(self) -> dict:
        return {"routine": self.routine, "model": self.model, "params": self.params,
                "targets": [t.to_dict() for t in self.targets]}

    def to_json(self) -> str:
        """Canonical JSON: sorted keys, no whitespace, floats as Python's shortest repr."""
        return json.dumps(self.to_dict(), sort_keys=True, separators=(",", ":"),
                          allow_nan=False)

    @property
    def hash(self) -> str:
        """sha256 (hex) of :meth:`to_json`: equal plans, equal hashes."""
        return hashlib.sha256(self.to_json().encode()).hexdigest()

    @classmethod
    def from_dict(cls, d: dict) -> Plan:
        return cls(routine=d["routine"], params=d.get("params", {}),
                   targets=tuple(Target.from_dict(t) for t in d["targets"]),
                   model=d.get("model", ""))

    @classmethod
    def from_json(cls, text: str) -> Plan:
        return cls.from_dict(json.loads(text))

    def joints(self) -> np.ndarray:
        """Joint targets (or expected joints) of every target that has them, (n, N) rad."""
        return np.array([t.q for t in self.targets if t.q is not None], float)
