"""``warmup``: work the robot until a reference pose stops drifting (a warm-up before a capture).

A cold robot drifts by tenths of a mm over its first half hour of work (joint
temperatures rising, links growing, joint zeros moving). The warm-up repeats a cycle of
work in the working space — ``count`` random poses the tracker sees (the poses routine's,
``seed``), visited and measured as a capture visits them, at the capture's speed — and
measures a reference pose (the one of them farthest from the base: the longest lever for
a link's growth and a joint's zero drift) before every cycle: targets of set
``drift`` (:mod:`daq.drift_checks`). After every point :func:`enough` looks at the
reference's readings: once they span ``window_min`` and their trend over the last
``window_min`` (a straight line fitted per axis, its change over the window) is below
``threshold_mm`` (default: :data:`THRESHOLD_SIGMAS` × the tracker's sigma),
the robot has settled and the run ends, completed; it ends unsettled after ``max_min``
minutes (or the plan's last cycle). :func:`finalize` stores how it ended and the drift
curve in the run's summary (``warmup``, :class:`~daq.store.WarmupSummary`), with the
joints' temperatures at the last reference reading, which ``capture --require-warm``
compares with the robot's temperatures before a capture (:mod:`daq.warm_gate`).

The time is the data's (the tracker's timestamps), so a simulated cell with a thermal
model warms on its own simulated clock (:mod:`sim_drivers.cell`).
"""

from __future__ import annotations

import math

import numpy as np

from ..drift_checks import DRIFT_SET, default_bound
from ..plans import Plan, Target, estimate_capture_s
from ..store import RunSummary, WarmupSummary
from . import poses
from ._common import nominal_point

#: the joint speed (rad/s) and measuring time (s) the number of cycles is planned for
PLANNED_SPEED_RAD_S, PLANNED_MEASURE_S = 0.5, 0.5
#: the default threshold of the drift over the window, in tracker sigmas (per axis): the
#: trend fitted to a window's readings is itself uncertain by about 2 sigmas
THRESHOLD_SIGMAS = 3.0
#: the fewest reference readings a window's trend is fitted to
MIN_WINDOW_READINGS = 3


def make_plan(model, *, count: int = 6, seed: int = 0, window_min: float = 15.0,
              threshold_mm: float | None = None, max_min: float = 60.0,
              cycles: int | None = None, floor_z_mm: float | None = 0.0,
              max_reach_mm: float | None = None, cell=None) -> Plan:
    """The warm-up plan: ``cycles`` cycles (default: enough for ``max_min`` at 0.5 rad/s)
    of the reference pose, then ``count`` working poses; a last reference at the end."""
    if count < 1:
        raise ValueError("warmup: count must be >= 1")
    if not (window_min > 0 and max_min >= window_min):
        raise ValueError(f"warmup: need 0 < window_min ({window_min:g}) <= max_min "
                         f"({max_min:g}), minutes")
    if threshold_mm is not None and not threshold_mm > 0:
        raise ValueError(f"warmup: threshold_mm {threshold_mm:g} is not positive")
    work = poses.make_plan(model, count=count, seed=seed, floor_z_mm=floor_z_mm,
                           max_reach_mm=max_reach_mm, cell=cell, spares=0)
    qs = [t.q for t in work.targets]
    far = int(np.argmax([np.linalg.norm(nominal_point(model, q)) for q in qs]))
    qs = [qs[far]] + qs[:far] + qs[far + 1:]  # the reference first
    if cycles is None:
        one = Plan("warmup", {}, tuple(Target(i, "joints", q=q) for i, q in
                                       enumerate([qs[0], *qs])))
        cycle_s = estimate_capture_s(one, PLANNED_SPEED_RAD_S, PLANNED_MEASURE_S)
        cycles = int(math.ceil(max_min * 60.0 / max(cycle_s, 1.0))) + 1
    if cycles < 1:
        raise ValueError("warmup: cycles must be >= 1")
    targets: list[Target] = []

    def reference(c: int) -> None:
        targets.append(Target(len(targets), "joints", q=qs[0], set=DRIFT_SET,
                              label=f"ref{c}",
                              info={"drift_check": c, "reference": 1, "of": "ref"}))

    for c in range(1, cycles + 1):
        reference(c)
        for k, q in enumerate(qs, 1):
            targets.append(Target(len(targets), "joints", q=q, label=f"c{c}.w{k}",
                                  info={"cycle": c, "work": k}))
    reference(cycles + 1)
    params = {"count": count, "seed": seed, "window_min": window_min,
              "threshold_mm": threshold_mm, "max_min": max_min, "cycles": cycles,
              **{k: v for k, v in work.params.items() if k == "visibility"}}
    return Plan("warmup", params, tuple(targets), model=model.name)


def _state(plan: Plan, samples) -> WarmupSummary:
    """How the warm-up stands after the samples stored so far."""
    p = plan.params
    rows = np.flatnonzero(np.asarray(samples.set_name) == DRIFT_SET)
    rows = rows[np.argsort(samples.t_s[rows])]
    window_s = float(p["window_min"]) * 60.0
    threshold = default_bound(samples.std_mm[rows], p.get("threshold_mm"),
                              sigmas=THRESHOLD_SIGMAS)
    out = WarmupSummary(settled=False, window_min=p["window_min"],
                        threshold_mm=round(threshold, 4), cycles=int(len(rows)))
    if len(rows) == 0:
        return out
    t, X = samples.t_s[rows] - samples.t_s[rows[0]], samples.tracker_p_smr[rows]
    out.minutes = round(float(t[-1]) / 60.0, 2)
    out.t_min = [round(float(v) / 60.0, 2) for v in t]
    out.curve_mm = [round(float(v), 4) for v in np.linalg.norm(X - X[0], axis=1)]
    if samples.joint_temp is not None:
        out.joint_temp_c = [round(float(v), 2) for v in samples.joint_temp[rows[-1]]]
    last = t >= t[-1] - window_s
    if t[-1] >= window_s and last.sum() >= MIN_WINDOW_READINGS:
        slope = np.polyfit(t[last], X[last], 1)[0]
        out.drift_mm = round(float(np.linalg.norm(slope) * window_s), 4)
        if out.drift_mm <= threshold:
            out.settled = True
            out.reason = (f"settled: the reference drifted {out.drift_mm:.3f} mm over the "
                          f"last {p['window_min']:g} min (threshold {threshold:.3f} mm)")
            return out
    if t[-1] >= float(p["max_min"]) * 60.0:
        out.reason = (f"not settled after the time bound ({p['max_min']:g} min): the "
                      f"reference still drifts {out.drift_mm or float('nan'):.3f} mm per "
                      f"{p['window_min']:g} min (threshold {threshold:.3f} mm)")
    return out


def enough(plan: Plan, samples, run) -> str | None:
    """The reason to end the warm-up now (settled, or the time bound), or None."""
    return _state(plan, samples).reason


def finalize(plan: Plan, samples, run) -> dict:
    """The run's summary ``warmup``: how it ended, the drift curve, the joints' temperatures."""
    state = _state(plan, samples)
    if state.reason is None:
        state.reason = (f"not settled: the plan's {plan.params['cycles']} cycles ended first "
                        f"(after {state.minutes or 0:g} min); more --cycles or a longer "
                        "--max-min")
    summary = run.summary or RunSummary()
    summary.warmup = state
    return {"summary": summary}
