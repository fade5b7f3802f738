"""``calibrate``: identify a robot's error parameters from a measurement CSV.

:class:`CalibrateRequest` is what the command was asked; :func:`calibrate` loads the data,
fits the error model (and the uncalibrated baseline on the same points), records the fit
in a run store when asked (:mod:`.calibration_record`), draws the ridge plot, runs the
Monte-Carlo check and writes params.json; it returns a :class:`Calibrated`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from calibration import DEFAULT_EFFECTS, load_csv
from calibration.diagnosis.orientation_blindness import Blindness, orientation_blindness
from calibration.exports.params_io import read_params, save_params
from calibration.fit.envelope import identify_supported, supported_model
from calibration.fit.full_pose import for_data
from calibration.fit.identify import Fit
from calibration.fit.uncertainty import MonteCarlo, monte_carlo
from calibration.workflow import fit_uncalibrated

from ..errors import UsageError
from .calibration_record import open_history_store, record_calibration
from .inputs import DataInputs, check_data, error_model_of, load_inputs
from .outputs import check_outputs, existing_paths


class CalibrateRequest(DataInputs):
    """The flags of ``cellcal calibrate`` (defaults as the parser's)."""

    effects: str = Field(DEFAULT_EFFECTS, alias="--effects")
    solver: str = Field("lm", alias="--solver")
    valid: str | None = Field(None, alias="--valid")
    params: str | None = Field(None, alias="--params")
    out: str | None = Field(None, alias="--out")
    seed: int | None = Field(None, alias="--seed", ge=0)
    monte_carlo: int = Field(0, alias="--monte-carlo", ge=0)
    outliers: Literal["exclude", "flag", "keep"] = Field("exclude", alias="--outliers")
    ridge_plot: str | None = Field(None, alias="--ridge-plot")
    db: str | None = Field(None, alias="--db")
    robot_id: str | None = Field(None, alias="--robot-id")
    position_only: bool = Field(False, alias="--position-only")

    def check(self) -> None:
        """Refuse flags that do not go together (UsageError, exit 2)."""
        if self.ridge_plot and self.solver != "ridge":
            raise UsageError("--ridge-plot needs --solver ridge")
        if self.monte_carlo and self.monte_carlo < 2:
            raise UsageError("--monte-carlo needs N >= 2")
        if self.robot_id and not self.db:
            raise UsageError("--robot-id needs --db (where the calibration is recorded)")


@dataclass
class Calibrated:
    """What :func:`calibrate` did.

    Attributes
    ----------
    fit : the calibrated fit; ``baseline`` the uncalibrated one on the same points
    mc : the Monte-Carlo check (``--monte-carlo``), or None
    recorded : the ``calibration`` JSON object of the fit recorded with ``--db`` (None:
        not recorded, the fit did not converge, or no ``--db``)
    notes : remarks for the user on the data and the start parameters
    blindness : how much tool orientation a position-only fit leaves undetermined
        (:mod:`calibration.diagnosis.orientation_blindness`), None for a full-pose fit
    """

    fit: Fit
    baseline: Fit
    mc: MonteCarlo | None = None
    recorded: dict | None = None
    notes: list[str] = field(default_factory=list)
    blindness: Blindness | None = None


def calibrate(request: CalibrateRequest,
              on_note: Callable[[str], None] | None = None) -> Calibrated:
    """Run the calibration ``request`` asks for and write its files.

    ``on_note`` is called with each remark as soon as it is known (before the fit, which
    may take long or fail); the result's ``notes`` lists them too.

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2); InsufficientData: data too poor for the model, TooLarge: too
        large for the memory left (exit 3).
    """
    request.check()
    check_outputs({"--out": request.out, "--ridge-plot": request.ridge_plot},
                  existing_paths(request.data, request.valid, request.params, request.model,
                                 request.effect_file))
    store = open_history_store(request.db) if request.db else None
    try:
        fit, baseline, notes = _fit(request, on_note)
        blindness = orientation_blindness(fit)
        if blindness is not None and blindness.blind:
            notes.append(blindness.note())
            if on_note is not None:
                on_note(blindness.note())
        recorded = (record_calibration(store, fit, data_file=request.data,
                                       robot_id=request.robot_id)
                    if store is not None else None)
    finally:
        if store is not None:
            store.close()
    if request.ridge_plot:
        from presentation.ridge_plot import plot_ridge

        plot_ridge(fit.info, request.ridge_plot, f"{fit.data.source}: ridge solver")
    mc = None
    if request.monte_carlo:
        mc = monte_carlo(fit, request.monte_carlo,
                         seed=request.seed if request.seed is not None else 0)
    if request.out:
        save_params(fit, request.out, list(request.effect_file), capture=fit.data.capture)
    return Calibrated(fit, baseline, mc, recorded, notes, blindness)


def _fit(request: CalibrateRequest, on_note) -> tuple[Fit, Fit, list[str]]:
    """(fit, uncalibrated baseline on the same points, notes)."""
    model, data = load_inputs(request)
    em, more = for_data(error_model_of(model, request.effects), data, request.position_only)
    # every table over the knots the calibration rows support (constant beyond them)
    em, cut = supported_model(em, data.calib() if data.is_valid.any() else data)
    more += cut
    valid = load_csv(request.valid, model) if request.valid else None
    x0 = None
    notes = []
    if request.params:
        start = read_params(request.params, model=model)
        notes += start.notes
    notes += more + check_data(em, data)
    if request.params:
        x0 = em.initial(em.bind(data.calib() if data.is_valid.any() else data))
        for k, name in enumerate(start.error_model.names):
            if name in em.names:
                x0[em.index(name)] = start.values[k]
        # a table of the same name keeps the smoothing it was fitted with (the model
        # diagnose --auto --out wrote is the model calibrate fits)
        smoothing = {e.label: e.smoothing for e in start.error_model.effects
                     if hasattr(e, "penalty_matrix")}
        for e in em.effects:
            if hasattr(e, "penalty_matrix") and e.smoothing is None and e.label in smoothing:
                e.smoothing = smoothing[e.label]
    for n in notes if on_note is not None else ():
        on_note(n)
    opts = {}
    if request.seed is not None and request.solver in ("besa", "sa", "besa+lm"):
        opts["seed"] = request.seed
    fit, _ = identify_supported(em, data, request.solver, valid=valid, x0=x0,
                                solver_options=opts or None, outliers=request.outliers)
    # the uncalibrated reference on the same points (without the blunders the fit left out)
    if fit.outliers is not None and fit.outliers.excluded:
        data = data.subset(~np.isin(data.pose_id, fit.outliers.ids))
    baseline = fit_uncalibrated(model, data, valid=valid, outliers="keep")
    return fit, baseline, notes
