"""``calibrate --db``: record a calibration (its params.json) in a run store, for
``cellcal history``: :func:`open_history_store`, :func:`record_calibration`."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calibration.exports.params_io import fit_to_dict
from calibration.fit.identify import Fit

from ..errors import UsageError

if TYPE_CHECKING:
    from daq.store import RunStore


def open_history_store(address: str) -> RunStore:
    """The run store the calibration is recorded in (made when missing); a store that
    cannot be opened is a UsageError naming it."""
    # here, not at the top: the store's modules cost every calibrate a tenth of a second
    # at start, and only --db needs them
    from daq.store import StoreError, open_store

    try:
        return open_store(address)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None


def record_calibration(store: RunStore, fit: Fit, *, data_file: str,
                       robot_id: str | None) -> dict | None:
    """Record the calibration in the store: ``{"id", "robot_id", "new", "db"}``, or None
    for a fit that did not converge (not recorded). ``robot_id`` None: the robot the data
    name (``# robot_id:``), else a UsageError. Its time is when the data were measured
    (the latest ``t_s``, when those are epoch times), else now; its source run the run
    the data were exported from, when that run is in this store."""
    from daq.store import StoreError

    data = fit.data
    robot_id = robot_id or data.meta.get("robot_id")
    if not robot_id:
        raise UsageError(f"{data_file}: the data name no robot: give --robot-id")
    if not fit.converged:
        return None
    t = None
    if data.t_s is not None and np.isfinite(data.t_s).any() and np.nanmax(data.t_s) > 1e9:
        t = float(np.nanmax(data.t_s))  # epoch times (not seconds from a start)
    source_run = None
    if data.meta.get("run", "").isdigit():  # exported from a run: of this store?
        with contextlib.suppress(StoreError):
            run = store.run(int(data.meta["run"]))
            if run.plan_hash == data.meta.get("plan_hash"):
                source_run = run.id
    cal_id, new = store.add_calibration(
        robot_id, fit_to_dict(fit, capture=data.capture), t=t,
        source_file=str(Path(data_file).resolve()), source_run=source_run)
    return {"id": cal_id, "robot_id": robot_id, "new": new, "db": store.address}
