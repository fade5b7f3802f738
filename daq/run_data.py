"""Runs as calibration inputs: a run's samples as a measurement data set or as zero-point
postures (what ``cellcal export`` writes and ``cellcal zero --db`` reads)."""

from __future__ import annotations

import numpy as np

from .store import RunStore, StoreError


def dataset_from_run(store: RunStore, run_id: int, *, sigma_mode: str = "std",
                     all_readings: bool = False):
    """The run's samples as a :class:`calibration.Dataset` (for the measurement CSV).

    ``sigma_mm`` per point: with ``sigma_mode="std"`` (default) the RMS over the axes of
    the per-axis std the tracker reports for the measurement; with ``"mean"`` that
    divided by sqrt(n) (the standard error of the average). The default is the
    conservative one: a stationary tracker measurement's error is dominated by
    effects that are correlated over its samples (interferometer, angle encoders,
    air), which averaging does not reduce as 1/sqrt(n).

    Every quantity the Dataset shares with the store's record (the column table,
    :mod:`calibration.data.columns`) is carried over: ``cmd``, ``temp_c``, ``pressure_hpa``,
    ``humidity_pct``, ``reflector``, ``face``, ``dirs``, ``joint_temp`` (the joints'
    temperatures), ``quat``, ``sigma_deg`` and ``tool_id`` are set only when every sample
    has them (a column is all or nothing).

    Drift checks (:mod:`daq.drift_checks`) are rows of set ``drift`` (``is_drift``).

    A point whose readings the capture could not resolve (verdict ``unresolved``,
    :mod:`daq.remeasure`) is left out. ``all_readings``: also those and the readings
    the capture did not accept (the ``readings`` table), ordered by point, then by time
    taken; returns ``(dataset, reading, reason)`` with ``reading`` ``accepted`` or
    ``rejected`` per row and ``reason`` why (the verdict's note for an accepted one).
    """
    from calibration import Dataset
    from calibration.data.columns import RECORD

    from .remeasure import VERDICTS

    if sigma_mode not in ("std", "mean"):
        raise ValueError(f"sigma_mode must be std or mean, got {sigma_mode!r}")
    run = store.run(run_id)
    s = store.samples(run_id)
    if len(s) == 0:
        raise StoreError(f"{store.address}: run {run_id} has no samples")
    ids = list(s.pose_id)
    if len(set(ids)) != len(ids):
        ids = [f"{p}#{i}" for p, i in zip(ids, s.point_index, strict=True)]
    rows = [s.sample(i) for i in range(len(s))]
    reading = ["rejected" if v == "unresolved" else "accepted" for v in s.verdict]
    reason = [VERDICTS.get(v or "", "") for v in s.verdict]
    if not all_readings:
        keep = [i for i, r in enumerate(reading) if r == "accepted"]
        if not keep:
            raise StoreError(f"{store.address}: run {run_id} has no accepted readings")
        rows, ids = ([a[i] for i in keep] for a in (rows, ids))
    else:
        pid = {int(p): ids[i] for i, p in enumerate(s.point_index)}
        for r in store.readings(run_id):  # each with its point's pose_id and set_name
            rows.append(r.sample)
            ids.append(pid[r.sample.point_index])
            reading.append("rejected")
            reason.append(r.reason)
        order = sorted(range(len(rows)), key=lambda i: (rows[i].point_index, rows[i].t_s))
        rows, ids, reading, reason = ([a[i] for i in order]
                                      for a in (rows, ids, reading, reason))
    std = np.array([r.std_mm for r in rows], float)
    sigma = np.sqrt(np.mean(std ** 2, axis=1))
    if sigma_mode == "mean":
        sigma = sigma / np.sqrt(np.maximum([r.n_averaged for r in rows], 1))
    meta = {"run": str(run.id), "routine": run.routine, **run_meta(store, run, sigma),
            "plan_hash": run.plan_hash, "robot": run.robot_url or "",
            "tracker": run.tracker_url or "", "software": run.software or "",
            **({"robot_id": run.robot_id} if run.robot_id else {}),
            "sigma_mm": ("tracker std, RMS over axes" if sigma_mode == "std"
                         else "tracker std / sqrt(n), RMS over axes")}
    if all_readings:
        meta["readings"] = "every reading: the column reading says accepted or rejected"
    columns: dict = {}
    for c in RECORD:  # every quantity the Dataset and the record share (column table)
        if c.dataset:
            columns.update(c.gather([getattr(r, c.name) for r in rows]))
    data = Dataset(**{**columns, "pose_id": ids, "sigma_mm": sigma}, meta=meta,
                   source=f"{store.address} run {run_id}")
    return (data, reading, reason) if all_readings else data


def run_meta(store: RunStore, run, sigma_mm: np.ndarray | None = None) -> dict[str, str]:
    """The run's capture context as measurement-file metadata
    (:class:`calibration.data.capture_meta.CaptureMeta`): run id and store, model, the
    controller's tool, the SMR, the measurement frame and the tracker's sigma (RMS of the
    points' ``sigma_mm``), for ``# key: value`` header lines."""
    from calibration.data.capture_meta import CaptureMeta

    ctx = run.context
    T = ctx.tracker_T_base_matrix
    sigma = None
    if sigma_mm is not None and len(sigma_mm) and np.all(sigma_mm > 0):
        sigma = float(np.sqrt(np.mean(np.asarray(sigma_mm) ** 2)))
    return CaptureMeta(
        run=run.id, store=store.address, model=run.model or ctx.model,
        tool_mm=None if ctx.tool_mm is None else np.asarray(ctx.tool_mm, float),
        smr_radius_mm=ctx.smr_radius_mm, reflector=ctx.reflector, frame_run=ctx.frame_run,
        tracker_T_base=T, tracker_sigma_mm=sigma).to_meta()


def postures_from_run(store: RunStore, run_id: int | None = None, *, to_base: bool = True,
                      robot_id: str | None = None):
    """The zero-point postures of a ``zero20`` run (default: the latest completed one, of
    ``robot_id`` when given).

    Built with :func:`calibration.zero_point.postures_from_dataset`: the joints read
    (rad), the plane of every posture from the plan's targets (``info.plane``) and the
    measured tips (mm). The tips are in the tracker frame (``tracker_p_tip``),
    or, with ``to_base`` and a run that knows its measurement frame
    (``tracker_T_base`` from a frame run, in its context), in the robot base frame.

    Returns
    -------
    postures : Postures
    run : Run
        The run they come from.
    """
    from calibration.zero_point import postures_from_dataset

    run = (store.latest_run("zero20", robot_id=robot_id) if run_id is None
           else store.run(run_id))
    if run.routine != "zero20":
        raise StoreError(f"{store.address}: run {run.id} is a {run.routine} run, not zero20")
    n = store.n_samples(run.id)
    if n != run.n_points:
        raise StoreError(f"{store.address}: run {run.id} has {n}/{run.n_points} postures stored "
                         f"(status {run.status}); finish it with `cellcal resume {run.id}`")
    data = dataset_from_run(store, run.id)
    targets = store.samples(run.id).target
    try:
        plane = np.array([int(t["info"]["plane"]) for t in targets])
    except (TypeError, KeyError) as e:
        raise StoreError(f"{store.address}: run {run.id}: a target has no plane ({e})") from None
    post = postures_from_dataset(data, plane)
    T = run.context.tracker_T_base_matrix
    if to_base and T is not None:
        post = post.tips_in_base(T[:3, :3], T[:3, 3])
    return post, run
