"""``cellcal runs [RUN]``: the runs of a run store, or one run in detail.

:func:`read_runs` reads the store once and returns the runs' JSON documents (what
``--json`` prints; the text is rendered from them by :mod:`presentation.run_listing`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pydantic import Field

from ..errors import UsageError
from ..request import Request


class RunsRequest(Request):
    """The store, and the run to show (None: list them, only ``robot_id``'s if given)."""

    run_id: int | None = Field(None, alias="RUN")
    db: str = Field(alias="--db")
    robot_id: str | None = Field(None, alias="--robot-id")


@dataclass(frozen=True)
class RunListing:
    """The runs (JSON documents) and each one's interruption kinds."""

    runs: list[dict]
    kinds: list[list[str]]


@dataclass(frozen=True)
class RunDetail:
    """One run's JSON document (with identities, context, interruptions and rejected
    readings) and the executor's default settings (the text shows those that differ)."""

    doc: dict
    executor_defaults: dict = field(default_factory=dict)


def _run_doc(store, r) -> dict:
    return {"run": r.id, "routine": r.routine, "status": r.status, "reason": r.reason,
            "points": r.n_points, "samples": store.n_samples(r.id), "model": r.model,
            "robot_id": r.robot_id,
            "robot": r.robot_url, "tracker": r.tracker_url, "robot_desc": r.robot_desc,
            "tracker_desc": r.tracker_desc, "software": r.software, "seed": r.seed,
            "started": r.started, "stopped": r.stopped, "plan_hash": r.plan_hash,
            "frame": r.frame, "summary": None if r.summary is None else r.summary.to_json(),
            "remeasure": store.remeasure_counts(r.id)}


def _detail(store, run_id: int) -> RunDetail:
    from daq.run_context import ExecutorOptions
    from daq.store import StoreError

    try:
        r = store.run(run_id)
    except StoreError as e:
        raise UsageError(str(e)) from None
    d = _run_doc(store, r)
    d.update(robot_identity=r.robot_identity, tracker_identity=r.tracker_identity,
             source_run=r.source_run)
    d["context"] = r.context.model_dump(mode="json")
    d["interruptions"] = [{"point": p, "t": t, "kind": k, "message": m}
                          for p, t, k, m in store.interruptions(r.id)]
    d["rejected_readings"] = [
        {"point": x.sample.point_index, "pose_id": x.sample.pose_id, "t": x.sample.t_s,
         "xyz": [float(v) for v in x.sample.tracker_p_smr], "reason": x.reason}
        for x in store.readings(r.id)]
    curves = _drift_checks(store, r)
    if curves:
        d["drift_checks"] = curves
    return RunDetail(d, ExecutorOptions().model_dump(mode="json"))


def _drift_checks(store, r) -> list[dict]:
    """The run's drift checks (:func:`daq.drift_checks.drift_curve`), [] without any."""
    import json

    from daq.drift_checks import drift_curve

    bound = (json.loads(r.plan_json).get("params", {}).get("drift_check") or {}).get("bound_mm")
    if r.summary is not None and r.summary.warmup is not None:
        bound = r.summary.warmup.threshold_mm
    return [c.to_json() for c in drift_curve(store.samples(r.id), bound)]


def read_runs(req: RunsRequest) -> RunListing | RunDetail:
    """Run ``req.run_id`` in detail, or the list of the store's runs (read-only; a missing
    store, an unknown run or a damaged store is a UsageError)."""
    from .stores import open_store, store_errors

    store = open_store(req.db, read_only=True)
    with store, store_errors(req.db):
        if req.run_id is not None:
            return _detail(store, req.run_id)
        runs = store.runs(req.robot_id)
        return RunListing([_run_doc(store, r) for r in runs],
                          [[k for _, _, k, _ in store.interruptions(r.id)] for r in runs])
