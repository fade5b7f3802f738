"""Plan a run: load the model, make the routine's plan for the cell and dry-run it.

:func:`plan_run` turns a :class:`~daq.run_request.CaptureRequest` into a
:class:`~daq.run_request.PlannedRun` (or refuses it); :func:`acquire_options` completes a
routine's acquisition options, for a new run and for a resumed one.
"""

from __future__ import annotations

import logging
from pathlib import Path

from calibration import load_model

from .check import check_plan
from .drift_checks import with_drift_checks
from .errors import PlanRefused, RequestError, one_line
from .routines import get as get_routine
from .run_request import CaptureRequest, PlannedRun
from .sight import estimate_time, frame_from_store, predict, require_tracker, resolve_cell
from .store import RunStore, StoreError

log = logging.getLogger(__name__)


def _open_existing(db) -> RunStore:
    if db is None:
        raise RequestError("no run store given")
    try:
        return RunStore.open_existing(db)
    except (StoreError, OSError) as e:
        raise RequestError(str(e)) from None


def plan_run(request: CaptureRequest, *, model=None, db: str | Path | None = None
             ) -> PlannedRun:
    """Load the model, make the routine's plan and dry-run it.

    Parameters
    ----------
    request : CaptureRequest
    model : RobotModel, optional
        The model already loaded (``request.model`` names it); else loaded from it.
    db : path, optional
        The run store, read for a measurement frame (the tracker's position) and when the
        routine's parameters refer to an earlier run (zero20 ``--replay``).

    The plan is made for the tracker's line of sight (unless ``request.visibility`` is
    False): the tracker position is ``request.tracker_at``, else the frame run
    (``request.frame_run`` or the latest in ``db``), else ``request.cell``
    (:func:`daq.sight.resolve_cell`); none of them is refused unless the reflector accepts
    every direction (:func:`daq.sight.require_tracker`). The planned run's ``sight`` says
    what the tracker will see of it either way. ``request.drift_check`` inserts its drift
    checks (:func:`daq.drift_checks.with_drift_checks`) before the dry run.

    Raises
    ------
    RequestError
        Unknown routine or model, bad parameters or acquisition options.
    TrackerUnknown
        The tracker's position is unknown and the line of sight not waived (exit code 2).
    NotEnoughVisible
        The tracker would not see enough of the plan (a RequestError, exit code 3).
    PlanRefused
        The plan fails the dry run (joint limits, reach, floor).
    """
    try:
        mod = get_routine(request.routine)
        if model is None:
            model = load_model(request.model)
        if request.tool_mm is not None:
            model = model.with_changes(tool=tuple(float(v) for v in request.tool_mm))
        params = dict(request.params)
        resolve = getattr(mod, "resolve_params", None)
        if resolve is not None:
            params = resolve(params, lambda: _open_existing(db))
        cell = resolve_cell(request.cell, request.tracker_at,
                            *frame_from_store(db, request.frame_run))
        plan = mod.make_plan(model, **params, cell=cell if request.visibility else None)
        if request.drift_check is not None:
            plan = with_drift_checks(plan, request.drift_check,
                                     estimate_time(plan, request.executor)[
                                         "estimated_capture_s"] / max(len(plan), 1))
        acquire = acquire_options(mod, request.acquire)
        if request.visibility:  # after the parameters' own refusals
            require_tracker(cell)
    except RequestError:  # NotEnoughVisible keeps its exit code
        raise
    except (ValueError, StoreError) as e:  # ModelError, CellError, pydantic's ValidationError
        raise RequestError(one_line(e)) from None
    res = check_plan(plan, model, limits=request.motion)
    if not res.ok:
        log.info("plan %s refused by the dry run: %s", plan.hash[:16], res.report())
        raise PlanRefused(res)
    sight = predict(plan, model, cell)
    log.info("plan %s: %s, %d points (%d spares), dry run passed; %s", plan.hash[:16],
             plan.routine, plan.n_planned, len(plan) - plan.n_planned,
             sight.report(limit=0))
    return PlannedRun(request, model, plan, res, acquire, sight)


def acquire_options(mod, given: dict) -> dict:
    """The routine's complete acquisition options (its defaults, then ``given``); {} for a
    routine without (which refuses any given)."""
    options = getattr(mod, "ACQUIRE_OPTIONS", None)
    if options is None:
        if given:
            raise RequestError(f"routine {mod.__name__.rsplit('.', 1)[-1]} takes no "
                               f"acquisition options ({', '.join(given)})")
        return {}
    return options(**given).model_dump()
