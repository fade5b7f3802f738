"""``validate``: a program's waypoints, as written and compensated, measured by the tracker.

The waypoints come with the joints each controller variant ends at (``joints_deg``:
variant -> deg, :mod:`calibration.compensation.controller_joints`: the program as written, the
compensated program, the calibrated DH table alone) and the TCP point the program means
(``xyz_mm``, robot base frame). ``cycles`` cycles run every variant's waypoints in program
order (a variant after the other, as the program would run), by joint moves. The plan is
plain data: every number the run needs is in it, so a resumed run measures the same.

:func:`finalize` measures each visit against its waypoint in the frame the plan names
(``frame``: the calibration's base, the frame its targets live in) or else the run's
measurement frame (``tracker_T_base`` from the frame run): per variant the error's RMS,
mean and max, and ISO 9283 per waypoint: the accuracy AP = |x̄ − x_c| of the mean attained
position, and the repeatability RP = l̄ + 3·S_l where a waypoint was visited more than once.

Line of sight (``cell`` with a tracker position): a plan with a waypoint the tracker would
not see is refused (:class:`~daq.errors.NotEnoughVisible`), naming it.
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ..store import Iso9283Point, RunSummary, ValidationVariant
from ._common import knows_tracker, require_visible, visibility_params

#: what to change when the tracker would not see a waypoint
CHANGE = ("waypoints whose SMR faces the tracker (leave the others out of the program "
          "validated), or move the tracker")


def make_plan(model, *, waypoints: list[dict], variants=("uncompensated", "compensated"),
              cycles: int = 1, frame: dict | None = None, source: dict | None = None,
              cell=None) -> Plan:
    """The validate plan: ``cycles`` × variants × waypoints joint targets.

    Parameters
    ----------
    waypoints : dicts with ``label``, ``xyz_mm`` (3,) and ``joints_deg`` (variant -> (N,))
        (``line``, ``kind``: where the program has it, kept in the plan)
    variants : the variants run, in order (keys of every ``joints_deg``)
    frame : ``{"tracker_T_base": 4x4 rows, "source": text}``: the frame the errors are
        measured in (default the run's measurement frame)
    source : what the waypoints came from (program, params; kept in the plan)
    """
    if cycles < 1:
        raise ValueError("validate: cycles must be >= 1")
    if not waypoints:
        raise ValueError("validate: no waypoints")
    variants = list(variants)
    for w in waypoints:
        missing = [v for v in variants if v not in w["joints_deg"]]
        if missing:
            raise ValueError(f"validate: waypoint {w['label']} has no joints for "
                             f"{', '.join(missing)}")
    q = {v: np.radians([w["joints_deg"][v] for w in waypoints]) for v in variants}
    if knows_tracker(cell):
        labels = [f"{v} {w['label']}" for v in variants for w in waypoints]
        require_visible("validate", model, np.vstack([q[v] for v in variants]), labels,
                        cell, CHANGE)
    targets = []
    for cyc in range(cycles):
        for v in variants:
            for k, w in enumerate(waypoints):
                targets.append(Target(len(targets), "joints", q=q[v][k],
                                      base_p_tcp=w["xyz_mm"], set="valid",
                                      label=f"c{cyc + 1}.{v}.{w['label']}",
                                      info={"cycle": cyc + 1, "variant": v, "waypoint": k}))
    params = {"waypoints": waypoints, "variants": variants, "cycles": cycles,
              "frame": frame, "source": source}
    if knows_tracker(cell):
        params["visibility"] = visibility_params(cell)
    return Plan("validate", params, tuple(targets), model=model.name)


def variant_summary(labels: list[str], errors: np.ndarray, points: np.ndarray,
                    which: np.ndarray, xyz: np.ndarray) -> ValidationVariant:
    """One variant's figures: ``errors`` (n,) mm per visit, ``points`` (n, 3) attained
    (base frame), ``which`` (n,) waypoint index per visit, ``xyz`` (m, 3) the waypoints."""
    per = {}
    for k in np.unique(which):
        X = points[which == k]
        mean = X.mean(axis=0)
        entry = Iso9283Point(n=len(X), AP_mm=float(np.linalg.norm(mean - xyz[k])))
        if len(X) > 1:
            ell = np.linalg.norm(X - mean, axis=1)
            entry.RP_mm = float(ell.mean() + 3 * np.std(ell, ddof=1))
        per[labels[k]] = entry
    rp = [e.RP_mm for e in per.values() if e.RP_mm is not None]
    return ValidationVariant(
        n=len(errors), rms_mm=float(np.sqrt(np.mean(errors**2))),
        mean_mm=float(errors.mean()), max_mm=float(errors.max()),
        ap_max_mm=max(e.AP_mm for e in per.values()), rp_max_mm=max(rp) if rp else None,
        waypoints=per)


def finalize(plan: Plan, samples, run) -> dict:
    """The error of every variant (see the module docstring), in the run's summary."""
    frame = plan.params.get("frame")
    if frame is not None:
        T, where = np.asarray(frame["tracker_T_base"], float), frame["source"]
    else:
        T, where = run.context.tracker_T_base_matrix, "the run's measurement frame"
    summary = run.summary or RunSummary()
    if T is None or len(samples.target) == 0:
        return {"summary": summary}
    waypoints = plan.params["waypoints"]
    labels = [w["label"] for w in waypoints]
    xyz = np.array([w["xyz_mm"] for w in waypoints], float)
    info = [(t or {}).get("info", {}) for t in samples.target]
    variant = np.array([i.get("variant", "") for i in info])
    which = np.array([i.get("waypoint", -1) for i in info])
    p = samples.tracker_p_smr
    base_p = (p - T[:3, 3]) @ T[:3, :3]  # base_T_tracker applied: R^T (p - t)
    out = {}
    for v in plan.params["variants"]:
        sel = (variant == v) & (which >= 0)
        if sel.any():
            e = np.linalg.norm(base_p[sel] - xyz[which[sel]], axis=1)
            out[v] = variant_summary(labels, e, base_p[sel], which[sel], xyz)
    summary.validation, summary.validation_frame = out, where
    return {"summary": summary}
