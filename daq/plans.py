"""Plans as data: a list of targets with stable indices, the routine's parameters, a hash.

A :class:`Plan` is what a routine (:mod:`daq.routines`) produces and what the
executor (:mod:`daq.executor`) runs. It is plain data: it can be dry-run
(:func:`daq.check.check_plan`), stored as JSON in the run store and compared
by its content hash (sha256 of a canonical JSON text) — a resumed run refuses
a plan whose hash differs from the stored one.

Order: :func:`shortest_order` visits joint vectors in a short order on the move time
(nearest neighbour, 2-opt, Or-opt on ``max_j |Δq_j| / speed_j``), keeping labelled sets
interleaved; :func:`estimate_capture_s` estimates a plan's capture time.

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


#: the roles of a target's sample (:attr:`Target.set`)
SETS = ("calib", "valid", "drift")


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
    set : {"calib", "valid", "drift"}
        Role of the sample in a calibration (``drift``: a drift check's reference pose,
        :mod:`daq.drift_checks`).
    label : str
        Human label (becomes ``pose_id`` when the CSV is exported).
    info : dict
        Routine-specific extras (plane, cycle, axis...). JSON-serialisable. ``spare: true``
        marks a spare point, measured only in place of a skipped one (see
        :mod:`daq.executor`).
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
        if self.set not in SETS:
            raise ValueError(f"target {self.index}: set must be calib, valid or drift, got "
                             f"{self.set!r}")
        object.__setattr__(self, "q", _vec(self.q))
        object.__setattr__(self, "base_p_tcp", _vec(self.base_p_tcp))
        object.__setattr__(self, "via", _vec(self.via))
        if self.move in ("joints", "zero") and self.q is None:
            raise ValueError(f"target {self.index}: a {self.move} target needs q")
        if self.move == "linear" and (self.base_p_tcp is None or len(self.base_p_tcp) != 3):
            raise ValueError(f"target {self.index}: a linear target needs xyz (3 values)")
        if not self.label:
            object.__setattr__(self, "label", str(self.index + 1))

    @property
    def spare(self) -> bool:
        """A spare (``info.spare``): measured only in place of a point that was skipped."""
        return bool(self.info.get("spare", False))

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

    @property
    def n_planned(self) -> int:
        """The points the plan means to measure: its targets less the spares."""
        return sum(not t.spare for t in self.targets)

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


# ------------------------------------------------------------------ order
#: settling after each move assumed by :func:`estimate_capture_s`, s (the simulated cell's)
SETTLE_S = 0.5


def move_time_matrix(q: np.ndarray, speed_rad_s) -> np.ndarray:
    """Move time between every two joint vectors, (n, n) s: the slowest joint,
    ``max_j |Δq_j| / speed_j`` (``speed_rad_s`` scalar or (N,))."""
    q = np.asarray(q, float)
    v = np.broadcast_to(np.asarray(speed_rad_s, float), (q.shape[1],))
    D = np.zeros((len(q), len(q)))
    for j in range(q.shape[1]):  # one joint at a time: n x n memory, not n x n x N
        np.maximum(D, np.abs(q[:, j, None] - q[None, :, j]) / v[j], out=D)
    return D


def path_time(q: np.ndarray, speed_rad_s, start: np.ndarray | None = None) -> float:
    """Joint travel time (s) of visiting the joint vectors ``q`` (n, N) in their order,
    from ``start`` (N,) when given."""
    q = np.asarray(q, float)
    if start is not None:
        q = np.vstack([np.asarray(start, float)[None], q])
    if len(q) < 2:
        return 0.0
    v = np.broadcast_to(np.asarray(speed_rad_s, float), (q.shape[1],))
    return float(np.sum(np.max(np.abs(np.diff(q, axis=0)) / v, axis=1)))


def _two_opt(tour: np.ndarray, D: np.ndarray, max_passes: int = 50) -> np.ndarray:
    """Improve a closed tour by 2-opt moves (segment reversals) until none gains."""
    n = len(tour)
    for _ in range(max_passes):
        improved = False
        for i in range(n - 2):
            a, b = tour[i], tour[i + 1]
            j = np.arange(i + 2, n if i > 0 else n - 1)
            if j.size == 0:
                continue
            c, d = tour[j], tour[(j + 1) % n]
            gain = D[a, b] + D[c, d] - D[a, c] - D[b, d]
            k = int(np.argmax(gain))
            if gain[k] > 1e-9:
                jj = int(j[k])
                tour[i + 1:jj + 1] = tour[i + 1:jj + 1][::-1].copy()
                improved = True
        if not improved:
            break
    return tour


def _or_opt(tour: np.ndarray, D: np.ndarray, max_passes: int = 20) -> np.ndarray:
    """Move single points to the best place elsewhere in the closed tour while it gains."""
    for _ in range(max_passes):
        improved = False
        for pos in range(len(tour)):
            n = len(tour)
            p, prev, nxt = tour[pos], tour[pos - 1], tour[(pos + 1) % n]
            removed = D[prev, p] + D[p, nxt] - D[prev, nxt]
            rest = np.delete(tour, pos)
            a, b = rest, np.roll(rest, -1)
            insert = D[a, p] + D[p, b] - D[a, b]
            k = int(np.argmin(insert))
            if removed - insert[k] > 1e-9:
                tour = np.insert(rest, k + 1, p)
                improved = True
        if not improved:
            break
    return tour


def shortest_order(q: np.ndarray, speed_rad_s=1.0, sets=None) -> np.ndarray:
    """An order of the joint vectors ``q`` (n, N) with a short total move time.

    A closed tour by nearest neighbour, improved by 2-opt and single-point moves (Or-opt)
    on the move time of :func:`move_time_matrix`; then opened at its longest edge. With
    ``sets`` (n labels, e.g. calib/valid), the tour is opened where every kind of point
    comes early (within ``ceil(2 n / count)`` points for each kind), so that a run stopped
    early still has all kinds. Returns the indices in visiting order.
    """
    q = np.asarray(q, float)
    n = len(q)
    if n < 3:
        return np.arange(n)
    D = move_time_matrix(q, speed_rad_s)
    tour, free = [0], np.ones(n, bool)
    free[0] = False
    for _ in range(n - 1):
        d = np.where(free, D[tour[-1]], np.inf)
        k = int(np.argmin(d))
        tour.append(k)
        free[k] = False
    tour = _or_opt(_two_opt(np.array(tour), D), D)
    tour = _two_opt(tour, D)
    edge = D[tour, np.roll(tour, -1)]  # edge k joins tour[k] and tour[k + 1]
    ok = np.ones(n, bool)
    if sets is not None:
        labels = np.asarray(sets)[tour]
        for kind in np.unique(labels):
            where = np.flatnonzero(labels == kind)
            window = int(np.ceil(2 * n / len(where)))
            # opening after edge k starts at k + 1: a point of this kind within the window
            first = np.zeros(n, bool)
            for w in range(window):
                first |= np.roll(labels == kind, -(w + 1))
            ok &= first
    k = int(np.argmax(np.where(ok, edge, -np.inf))) if ok.any() else int(np.argmax(edge))
    return np.roll(tour, -(k + 1))


def estimate_capture_s(plan: Plan, speed_rad_s: float, measure_s: float, *,
                       settle_s: float = SETTLE_S, dwell_s: float = 0.0,
                       start: np.ndarray | None = None) -> float:
    """Estimated capture time of ``plan`` (s): joint travel between the targets' joints
    (:func:`path_time`, vias included) plus, per target, settling, dwell and measuring.
    Linear moves are counted by their expected joints; closed loops (zero20) by one
    measurement; spares not at all."""
    qs = []
    targets = [t for t in plan.targets if not t.spare]
    for t in targets:
        if t.via is not None and t.move != "linear":
            qs.append(t.via)
        if t.q is not None:
            qs.append(t.q)
    travel = path_time(np.array(qs, float), speed_rad_s, start) if qs else 0.0
    return travel + len(qs) * (settle_s + dwell_s) + len(targets) * measure_s
