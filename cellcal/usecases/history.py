"""``history``: a robot's calibrations over time, as recorded with ``calibrate --db``.

:class:`HistoryRequest` is what the command was asked; :func:`robot_history` reads the
calibrations from the store (read-only), follows every parameter over them
(:func:`calibration.diagnosis.history.parameter_histories`) and draws the trends when asked; it
returns a :class:`RobotHistory`.
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass, field
from pathlib import Path

from pydantic import Field

from calibration.diagnosis.history import (
    DEFAULT_SIGMA,
    CalibrationSummary,
    ParameterHistory,
    parameter_histories,
)
from daq.store import Calibration, Check, StoreError
from presentation.history_text import flagged_rows

from ..errors import UsageError
from ..request import FiniteFloat, Request
from .outputs import check_outputs
from .stores import open_store


class HistoryRequest(Request):
    """The flags of ``cellcal history`` (defaults as the parser's)."""

    robot_id: str = Field(alias="ROBOT")
    db: str = Field(alias="--db")
    param: tuple[str, ...] = Field((), alias="--param")
    sigma: FiniteFloat = Field(DEFAULT_SIGMA, alias="--sigma", gt=0)
    plot: str | None = Field(None, alias="--plot")


@dataclass
class RobotHistory:
    """What :func:`robot_history` read: the store's ``address``, the robot's
    ``calibrations`` (oldest first) with their ``summaries``, every parameter's history,
    the histories ``shown`` (those named with ``--param``, else those that changed), and
    the ``checks`` of its calibrations on new poses (``cellcal check --db``, oldest
    first)."""

    address: str
    calibrations: list[Calibration]
    summaries: list[CalibrationSummary]
    histories: list[ParameterHistory]
    shown: list[ParameterHistory]
    checks: list[Check] = field(default_factory=list)


def robot_history(request: HistoryRequest) -> RobotHistory:
    """Read the robot's calibrations and follow their parameters; draw ``--plot``.

    Raises
    ------
    UsageError
        No such store or robot, a parameter pattern that matches nothing, a plot file of
        another kind than .html or .png (exit 2).
    """
    if request.plot and Path(request.plot).suffix.lower() not in (".html", ".htm", ".png"):
        raise UsageError(f"--plot {request.plot}: give a .html or .png file")
    check_outputs({"--plot": request.plot}, [request.db])
    address, cals, checks = _load(request.db, request.robot_id)
    docs = [c.params for c in cals]
    summaries = [CalibrationSummary.of(d) for d in docs]
    histories = parameter_histories(docs, request.sigma)
    if request.param:
        shown = [h for h in histories
                 if any(fnmatch.fnmatchcase(h.name, g) for g in request.param)]
        if not shown:
            raise UsageError(f"no parameter matches {', '.join(request.param)}")
    else:
        shown = [h for h in histories if h.flagged.any()]
    if request.plot and not cals:
        raise UsageError(f"--plot: robot {request.robot_id!r} has checks but no calibrations "
                         "in the store: there are no parameters to draw")
    if request.plot:
        import numpy as np

        from presentation.history_plot import write_history_plot

        write_history_plot(request.plot, shown or histories, np.array([c.t for c in cals]),
                           f"calibration history of {request.robot_id}",
                           flagged_rows(cals, histories))
    return RobotHistory(address, cals, summaries, histories, shown, checks)


def _load(db: str, robot_id: str) -> tuple[str, list[Calibration], list[Check]]:
    """(the store's address, the robot's calibrations, their checks); UsageError when it
    has neither."""
    store = open_store(db, read_only=True)
    try:
        cals = store.calibrations(robot_id)
        checks = store.checks(robot_id)
        robots = store.robots()
    except StoreError as e:
        raise UsageError(str(e)) from None
    finally:
        store.close()
    if not cals and not checks:
        known = ", ".join(r for r, _ in robots) or "none"
        raise UsageError(f"{store.address}: no calibrations of robot {robot_id!r} "
                         f"(robots with calibrations: {known})")
    return store.address, cals, checks
