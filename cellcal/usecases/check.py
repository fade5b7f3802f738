"""``check``: a calibration's error on new measurements, exactly as calibrated.

:class:`CheckRequest` is what the command was asked; :func:`check` reads the params.json
and the measurement CSV, decides whether the tracker-to-base transform is refitted (asked
with ``--refit-base``, or the data recorded another measurement frame than the
calibration's: :func:`calibration.fit.model_check.frame_change`), computes every pose's
error (:func:`calibration.fit.model_check.check_model`; inside and outside the calibrated
envelope the params.json records, a note when it records none), judges it against
``--tolerance-mm`` and records it in the robot's history with ``--db``; it returns a
:class:`Checked`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import Field

from calibration.data.capture_meta import CaptureMeta
from calibration.fit.data_quality import refuse_radians
from calibration.fit.model_check import FrameVerdict, ModelCheck, base_effect, check_model
from calibration.fit.model_check import frame_change as compare_frames

from ..errors import UsageError
from ..request import FiniteFloat
from .calibration_record import open_history_store
from .inputs import DataInputs
from .target_checks import no_envelope_note


class CheckRequest(DataInputs):
    """The flags of ``cellcal check`` (defaults as the parser's)."""

    params: str = Field(alias="--params")
    tolerance_mm: FiniteFloat | None = Field(None, alias="--tolerance-mm", gt=0)
    refit_base: bool = Field(False, alias="--refit-base")
    db: str | None = Field(None, alias="--db")
    robot_id: str | None = Field(None, alias="--robot-id")

    def check(self) -> None:
        """Refuse flags that do not go together (UsageError, exit 2)."""
        if self.robot_id and not self.db:
            raise UsageError("--robot-id needs --db (where the check is recorded)")


@dataclass
class Checked:
    """What :func:`check` found.

    Attributes
    ----------
    result : the model's error on the new poses (:class:`ModelCheck`)
    frame : whether the data are in the calibration's measurement frame
    refit_reason : why the base was refitted (None: it was not)
    calibration_stats : the calibration's own figures (params.json ``stats``: ``calib``,
        ``valid``)
    within_tolerance : the RMS within ``--tolerance-mm`` (None without one)
    recorded : the ``recorded`` JSON object of the check recorded with ``--db``, else None
    notes : remarks on the inputs
    """

    result: ModelCheck
    frame: FrameVerdict
    refit_reason: str | None
    calibration_stats: dict
    within_tolerance: bool | None
    recorded: dict | None = None
    notes: list[str] = field(default_factory=list)


def check(request: CheckRequest, *, on_note: Callable[[str], None] | None = None,
          summary: Callable[[Checked], dict] | None = None) -> Checked:
    """Check the calibration ``--params`` on the poses of ``DATA.csv``.

    ``on_note`` is called with each remark as soon as it is known; ``summary`` makes the
    JSON object recorded with ``--db`` from the result (the command's ``--json``).

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2); InsufficientData: data the check cannot use (exit 3).
    """
    from calibration import load_csv, load_model
    from calibration.effects import load_effect_file
    from calibration.exports.params_io import (
        capture_of,
        params_from_doc,
        read_document,
        read_stats,
    )

    request.check()
    for f in request.effect_file:
        load_effect_file(f)
    model = load_model(request.model) if request.model else None
    doc = read_document(request.params)
    loaded = params_from_doc(doc, request.params, model=model)
    em, values = loaded.error_model, loaded.values
    notes = list(loaded.notes)
    data = load_csv(request.data, em.model)
    if request.sigma is not None:
        data = data.with_tracker_sigma(request.sigma)
    refuse_radians(data, em.model)
    calibration = capture_of(doc)
    notes += _tool_notes(calibration, data.capture, request.params)
    if loaded.envelope is None:
        notes.append(no_envelope_note(request.params, "poses"))
    frame = compare_frames(calibration, data.capture)
    reason = None
    if request.refit_base:
        reason = "asked (--refit-base)"
    elif frame.same is False:
        reason = frame.reason
    if reason is not None and base_effect(em) is None:
        if request.refit_base:
            raise UsageError(f"--refit-base: the calibration {request.params} has no base "
                             f"effect (effects {','.join(em.labels)})")
        notes.append(f"{frame.reason}, but the calibration has no base effect to refit: its "
                     "errors are in its own frame")
        reason = None
    for n in notes if on_note is not None else ():
        on_note(n)
    result = check_model(em, values, data, refit_base=reason is not None,
                         envelope=loaded.envelope)
    notes += result.notes
    if on_note is not None:
        for n in result.notes:
            on_note(n)
    within = None
    if request.tolerance_mm is not None:
        within = bool(result.stats["rms_mm"] <= request.tolerance_mm)
    done = Checked(result, frame, reason, read_stats(doc), within, notes=notes)
    if request.db:
        done.recorded = _record(request, done, doc, summary)
    return done


def _tool_notes(calibration: CaptureMeta, data: CaptureMeta, params: str) -> list[str]:
    """A remark when the data's capture had another TCP than the calibration's."""
    a, b = calibration.tool_mm, data.tool_mm
    if a is None or b is None or np.allclose(a, b, atol=1e-6):
        return []
    fmt = ", ".join
    return [f"the data were captured with the tool {fmt(f'{v:g}' for v in b)} mm, the "
            f"calibration {params} with {fmt(f'{v:g}' for v in a)} mm: the calibration's "
            "identified tool is used (the SMR must sit where it sat)"]


def _record(request: CheckRequest, done: Checked, doc: dict,
            summary: Callable[[Checked], dict] | None) -> dict:
    """Record the check in the robot's history: ``{"id", "robot_id", "new",
    "calibration", "db"}``."""
    from daq.store import StoreError

    data = done.result.data
    robot_id = request.robot_id or data.meta.get("robot_id")
    if not robot_id:
        raise UsageError(f"{request.data}: the data name no robot: give --robot-id")
    t = None
    if data.t_s is not None and np.isfinite(data.t_s).any() and np.nanmax(data.t_s) > 1e9:
        t = float(np.nanmax(data.t_s))  # epoch times (not seconds from a start)
    result = summary(done) if summary is not None else {}
    result = {k: v for k, v in result.items() if k not in ("poses", "recorded")}
    store = open_history_store(request.db)
    try:
        source_run = None
        if data.meta.get("run", "").isdigit():  # exported from a run of this store?
            with contextlib.suppress(StoreError):
                run = store.run(int(data.meta["run"]))
                if run.plan_hash == data.meta.get("plan_hash"):
                    source_run = run.id
        check_id, new, cal_id = store.add_check(
            robot_id, doc, result, t=t, source_file=str(Path(request.data).resolve()),
            source_run=source_run)
        return {"id": check_id, "robot_id": robot_id, "new": new, "calibration": cal_id,
                "db": store.address}
    finally:
        store.close()
