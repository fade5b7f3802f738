"""``cellcal export [RUN]``: a run's samples as a measurement CSV, or a zero20 run's
postures as a postures CSV (docs/formats.md §1).

:func:`export_run` reads the run (read-only), writes the CSV (or returns its text for
standard output, ``--out -``) and says what it wrote (:class:`ExportResult`).
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field

from ..errors import UsageError
from ..request import Request


class ExportRequest(Request):
    """The run (default: the latest; with ``postures``, the latest zero20 run), the store,
    the CSV to write (``-``: standard output) and what goes in it."""

    run_id: int | None = Field(None, alias="RUN")
    db: str = Field(alias="--db")
    out: str = Field(alias="--out")
    postures: bool = Field(False, alias="--postures")
    sigma_mode: str = Field("std", alias="--sigma-mode")
    all_readings: bool = Field(False, alias="--all-readings")


@dataclass(frozen=True)
class ExportResult:
    """What was written: the run and its status, the points of its plan, the rows written
    (samples, or postures), the readings rejected among them (with ``all_readings``, else
    None), the unresolved points left out, whether they are postures and their tips'
    frame, and the CSV's text when it goes to standard output (else None: written to the
    file)."""

    run_id: int
    status: str
    n_points: int
    rows: int
    rejected: int | None = None
    unresolved: int = 0
    postures: bool = False
    tip_frame: str | None = None
    text: str | None = None


def _postures(store, req: ExportRequest) -> ExportResult:
    """A zero20 run's postures CSV (docs/formats.md §1)."""
    from daq.run_data import postures_from_run, run_meta
    from daq.store import StoreError

    try:
        post, r = postures_from_run(store, req.run_id)  # default: the latest zero20
    except StoreError as e:
        raise UsageError(str(e)) from None
    meta = {"run": r.id, "routine": r.routine, **run_meta(store, r), "plan_hash": r.plan_hash,
            "robot": r.robot_url or "", "tracker": r.tracker_url or ""}
    text = post.to_csv(None if req.out == "-" else req.out, meta=meta)
    return ExportResult(r.id, r.status, r.n_points, post.n, postures=True, tip_frame=post.tip_frame,
                        text=text if req.out == "-" else None)


def _samples(store, req: ExportRequest) -> ExportResult:
    from daq.run_data import dataset_from_run
    from daq.store import StoreError

    try:
        r = store.run(req.run_id)
        extra = None
        if req.all_readings:
            data, reading, reason = dataset_from_run(store, r.id, sigma_mode=req.sigma_mode,
                                                     all_readings=True)
            extra = {"reading": reading, "reason": reason}
        else:
            data = dataset_from_run(store, r.id, sigma_mode=req.sigma_mode)
    except StoreError as e:
        raise UsageError(str(e)) from None
    text = data.to_csv(None if req.out == "-" else req.out, extra=extra)
    if req.out == "-":
        return ExportResult(r.id, r.status, r.n_points, data.n, text=text)
    return ExportResult(r.id, r.status, r.n_points, data.n,
                        None if extra is None else extra["reading"].count("rejected"),
                        store.remeasure_counts(r.id)["unresolved"])


def export_run(req: ExportRequest) -> ExportResult:
    """Write the run's CSV (``req.out`` checked first: never the store, never an input).
    UsageError for a missing store, an unknown run, a damaged store."""
    from .outputs import check_outputs
    from .stores import open_store, store_errors

    check_outputs({"--out": req.out}, [req.db], stdout=True)
    store = open_store(req.db, read_only=True)
    with store, store_errors(req.db):
        return _postures(store, req) if req.postures else _samples(store, req)
