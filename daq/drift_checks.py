"""Drift checks: reference poses measured again during a capture (``capture --drift-check``).

A robot warming up, a settling stand or a tracker that moves shows as the same pose
measured somewhere else later. :func:`with_drift_checks` inserts into a plan, every N
points (or every N minutes of the plan's estimated capture time), a visit of one or more
reference poses (default: the plan's first measured posture): joint targets of their own
kind, set ``drift``, labelled ``drift<k>.<r>`` (check k, reference r), the first checks
before the first point and the last after the last. The executor measures them like any
point; the store keeps them as samples of set ``drift``; export writes them with
``set=drift`` (calibration rows that also show the drift over time, so they constrain a
drift effect). :func:`drift_curve` reads them back: each reference's distance from its
first reading over time, flagged above a bound (what ``cellcal runs RUN`` shows).
:class:`DriftWatch` does the same as the run goes, for the capture's log: each check's
distance from its reference's first reading, at INFO (``daq.drift_checks``).

Units: mm, s (minutes only in the ``every`` of :class:`DriftCheck`).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace

import numpy as np

from .plans import Plan, Target

log = logging.getLogger(__name__)

#: the set name of a drift check's target, sample and exported row
DRIFT_SET = "drift"
#: the bound of the drift when none is given: this many times the tracker's sigma, at least
#: :data:`MIN_BOUND_MM`
BOUND_SIGMAS = 4.0
MIN_BOUND_MM = 0.02


@dataclass(frozen=True)
class DriftCheck:
    """How often to measure the references: every ``every`` points (``unit`` "points") or
    minutes ("min"), ``references`` poses each time, the drift flagged above ``bound_mm``
    (None: :data:`BOUND_SIGMAS` × the tracker's sigma)."""

    every: float
    unit: str = "points"
    references: int = 1
    bound_mm: float | None = None

    def __post_init__(self) -> None:
        if self.unit not in ("points", "min"):
            raise ValueError(f"drift check: unit must be points or min, not {self.unit!r}")
        if not (math.isfinite(self.every) and self.every > 0):
            raise ValueError(f"drift check: every {self.every} is not a positive number")
        if self.unit == "points" and self.every != int(self.every):
            raise ValueError(f"drift check: every {self.every} points is not a whole number")
        if self.references < 1:
            raise ValueError("drift check: at least one reference pose")
        if self.bound_mm is not None and not self.bound_mm > 0:
            raise ValueError(f"drift check: bound {self.bound_mm} mm is not positive")

    @classmethod
    def parse(cls, text: str, **kw) -> DriftCheck:
        """``"20"`` (every 20 points) or ``"5min"`` (every 5 minutes); ValueError."""
        t = str(text).strip().lower()
        unit = "min" if t.endswith("min") else "points"
        try:
            every = float(t.removesuffix("min"))
        except ValueError:
            raise ValueError(f"{text!r} is not N (points) or Nmin (minutes)") from None
        return cls(every, unit, **kw)


def with_drift_checks(plan: Plan, check: DriftCheck, seconds_per_point: float | None = None
                      ) -> Plan:
    """``plan`` with its drift checks inserted (indices renumbered; spares stay last).

    ``seconds_per_point``: the plan's estimated time per point, which turns minutes into
    points (required when ``check.unit`` is "min"). ValueError for a plan without joint
    postures to return to, or one whose points a routine acquires itself (zero20).
    """
    regular = [t for t in plan.targets if not t.spare]
    if any(t.move == "zero" for t in plan.targets):
        raise ValueError(f"drift checks: not in a {plan.routine} plan (its closed loop "
                         "acquires every point itself)")
    postures = [t for t in regular if t.q is not None]
    if not postures:
        raise ValueError(f"drift checks: the {plan.routine} plan has no posture to return to")
    every = check.every
    if check.unit == "min":
        if not seconds_per_point or seconds_per_point <= 0:
            raise ValueError("drift checks every N minutes need the plan's estimated time")
        every = check.every * 60.0 / seconds_per_point
    every = max(1, int(round(every)))
    picks = np.linspace(0, len(postures) - 1, check.references).round().astype(int)
    references = [postures[i] for i in dict.fromkeys(picks.tolist())]
    out: list[Target] = []
    k = 0

    def visit() -> None:
        nonlocal k
        k += 1
        for r, ref in enumerate(references, 1):
            out.append(Target(0, "joints", q=ref.q, set=DRIFT_SET, label=f"drift{k}.{r}",
                              info={"drift_check": k, "reference": r, "of": ref.label}))

    for i, t in enumerate(regular):
        if i % every == 0:
            visit()
        out.append(t)
    visit()
    out += [t for t in plan.targets if t.spare]
    targets = tuple(replace(t, index=i) for i, t in enumerate(out))
    params = {**plan.params, "drift_check": {
        "every": check.every, "unit": check.unit, "every_points": every,
        "references": [ref.label for ref in references], "bound_mm": check.bound_mm}}
    return Plan(plan.routine, params, targets, model=plan.model)


@dataclass(frozen=True)
class DriftCurve:
    """The drift of one reference pose over a run: ``t_s`` since its first reading,
    ``drift_mm`` the distance from it, ``joint_temp_c`` the joints' mean temperature at each
    (None when not recorded); ``flagged`` where the drift exceeds ``bound_mm``."""

    reference: str
    t_s: np.ndarray
    drift_mm: np.ndarray
    joint_temp_c: np.ndarray | None
    bound_mm: float

    @property
    def flagged(self) -> np.ndarray:
        return self.drift_mm > self.bound_mm

    @property
    def max_mm(self) -> float:
        return float(self.drift_mm.max()) if len(self.drift_mm) else 0.0

    def to_json(self) -> dict:
        return {"reference": self.reference, "bound_mm": round(self.bound_mm, 4),
                "max_mm": round(self.max_mm, 4), "flagged": bool(self.flagged.any()),
                "t_s": [round(float(v), 1) for v in self.t_s],
                "drift_mm": [round(float(v), 4) for v in self.drift_mm],
                **({} if self.joint_temp_c is None else
                   {"joint_temp_c": [round(float(v), 2) for v in self.joint_temp_c]})}


def default_bound(std_mm: np.ndarray, given: float | None = None, *,
                  sigmas: float = BOUND_SIGMAS) -> float:
    """The drift bound: ``given``, else ``sigmas`` × the readings' RMS std (the tracker's
    sigma per axis), at least :data:`MIN_BOUND_MM`."""
    if given is not None:
        return float(given)
    sigma = float(np.sqrt(np.mean(np.asarray(std_mm, float) ** 2))) if len(std_mm) else 0.0
    return max(MIN_BOUND_MM, sigmas * sigma)


def drift_curve(samples, bound_mm: float | None = None) -> list[DriftCurve]:
    """The drift curve of each reference pose of a run's samples
    (:class:`~daq.store.Samples`: those of set ``drift``, grouped by ``info.reference``);
    [] for a run without drift checks."""
    sets = np.asarray(samples.set_name)
    rows = np.flatnonzero(sets == DRIFT_SET)
    if len(rows) == 0:
        return []
    refs = [int(((samples.target[i] or {}).get("info") or {}).get("reference", 1))
            for i in rows]
    bound = default_bound(samples.std_mm[rows], bound_mm)
    out = []
    for r in sorted(set(refs)):
        idx = rows[np.asarray(refs) == r]
        idx = idx[np.argsort(samples.t_s[idx])]
        p = samples.tracker_p_smr[idx]
        temp = (None if samples.joint_temp is None
                else samples.joint_temp[idx].mean(axis=1))
        label = ((samples.target[idx[0]] or {}).get("info") or {}).get("of", str(r))
        out.append(DriftCurve(str(label), samples.t_s[idx] - samples.t_s[idx[0]],
                              np.linalg.norm(p - p[0], axis=1), temp, bound))
    return out


class DriftWatch:
    """The drift checks of a run as they are stored: each reading's distance from its
    reference's first (the drift curve so far), logged at INFO with the bound (the plan's
    ``bound_mm``, else :func:`default_bound` over the readings so far) and whether it is
    above it. :meth:`of_run` starts from the readings already stored (a resumed run)."""

    def __init__(self, bound_mm: float | None = None) -> None:
        self.bound_mm = bound_mm
        self.first: dict[int, np.ndarray] = {}
        self.std: list[np.ndarray] = []

    @classmethod
    def of_run(cls, plan: Plan, samples) -> DriftWatch | None:
        """The watch of ``plan`` (None without drift checks), fed the drift readings of
        ``samples`` (:class:`~daq.store.Samples`, the run's stored ones) in time order."""
        params = plan.params.get("drift_check")
        if not params:
            return None
        watch = cls(params.get("bound_mm"))
        rows = np.flatnonzero(np.asarray(samples.set_name) == DRIFT_SET)
        for i in rows[np.argsort(samples.t_s[rows])]:
            info = (samples.target[i] or {}).get("info") or {}
            watch._add(int(info.get("reference", 1)), samples.tracker_p_smr[i],
                       samples.std_mm[i])
        return watch

    def _add(self, reference: int, xyz, std) -> float:
        xyz = np.asarray(xyz, float)
        self.std.append(np.asarray(std, float))
        first = self.first.setdefault(reference, xyz)
        return float(np.linalg.norm(xyz - first))

    def observe(self, target: Target, xyz, std) -> float:
        """Take drift target ``target``'s stored reading; its drift (mm), logged."""
        info = target.info or {}
        drift = self._add(int(info.get("reference", 1)), xyz, std)
        bound = default_bound(np.array(self.std), self.bound_mm)
        log.info("drift check %s, reference %s (%s): %.4f mm from its first reading, %s the "
                 "bound %.4f mm", info.get("drift_check", "?"), info.get("reference", 1),
                 info.get("of", target.label), drift, "ABOVE" if drift > bound else "within",
                 bound)
        return drift
