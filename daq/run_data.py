"""Runs as calibration inputs: a run's samples as a measurement data set or as zero-point
postures (what ``cellcal export`` writes and ``cellcal zero --db`` reads)."""

from __future__ import annotations

import numpy as np

from .store import RunStore, StoreError


def dataset_from_run(store: RunStore, run_id: int, *, sigma_mode: str = "std"):
    """The run's samples as a :class:`calibration.Dataset` (for the measurement CSV).

    ``sigma_mm`` per point: with ``sigma_mode="std"`` (default) the RMS over the axes of
    the per-axis std the tracker reports for the measurement; with ``"mean"`` that
    divided by sqrt(n) (the standard error of the average). The default is the
    conservative one: a stationary tracker measurement's error is dominated by
    effects that are correlated over its samples (interferometer, angle encoders,
    air), which averaging does not reduce as 1/sqrt(n).

    ``cmd``, ``temp_c``, ``pressure_hpa``, ``humidity_pct``, ``reflector``, ``face`` and
    ``dirs`` are set only when every sample has them (a column is all or nothing).
    """
    from calibration import Dataset

    if sigma_mode not in ("std", "mean"):
        raise ValueError(f"sigma_mode must be std or mean, got {sigma_mode!r}")
    run = store.run(run_id)
    s = store.samples(run_id)
    if len(s) == 0:
        raise StoreError(f"{store.address}: run {run_id} has no samples")
    sigma = np.sqrt(np.mean(s.std_mm ** 2, axis=1))
    if sigma_mode == "mean":
        sigma = sigma / np.sqrt(np.maximum(s.n_averaged, 1))
    ids = list(s.pose_id)
    if len(set(ids)) != len(ids):
        ids = [f"{p}#{i}" for p, i in zip(ids, s.point_index, strict=True)]

    def every(a):
        return a if np.all(np.isfinite(a)) else None

    reflector = s.reflector if all(s.reflector) else None
    face = s.face if np.all(s.face > 0) else None
    meta = {"run": str(run.id), "routine": run.routine, "plan_hash": run.plan_hash,
            "model": run.model or "", "robot": run.robot_url or "",
            "tracker": run.tracker_url or "", "software": run.software or "",
            **({"robot_id": run.robot_id} if run.robot_id else {}),
            "sigma_mm": ("tracker std, RMS over axes" if sigma_mode == "std"
                         else "tracker std / sqrt(n), RMS over axes")}
    return Dataset(
        q=s.joints_rad, tracker_p_smr=s.tracker_p_smr, pose_id=ids, cmd=every(s.base_p_tcp_cmd),
        temp_c=every(s.temp_c), t_s=s.t, sigma_mm=sigma, pressure_hpa=every(s.pressure_hpa),
        humidity_pct=every(s.humidity_pct), reflector=reflector, face=face, dirs=s.dirs,
        is_valid=np.array([v == "valid" for v in s.set_name]), meta=meta,
        source=f"{store.address} run {run_id}",
    )


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
    targets = store.samples(run.id).targets
    try:
        plane = np.array([int(t["info"]["plane"]) for t in targets])
    except (TypeError, KeyError) as e:
        raise StoreError(f"{store.address}: run {run.id}: a target has no plane ({e})") from None
    post = postures_from_dataset(data, plane)
    T = run.context.tracker_T_base_matrix
    if to_base and T is not None:
        post = post.tips_in_base(T[:3, :3], T[:3, 3])
    return post, run
