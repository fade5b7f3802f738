"""The staged fit behind ``cellcal report``, ``cellcal diagnose`` and ``cellcal demo``.

The story of a calibration in three fits: the *uncalibrated* robot (nominal kinematics,
only where it stands and where the SMR sits fitted), the *current* model (its parameters
read from a params.json, or identified) and, when the diagnosis of the current model
finds a significant missing effect, the current model *plus that effect*, refitted.

Numbers only: the callers label the stages, print and render them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .dataset import Dataset
from .diagnosis import Diagnosis, diagnose
from .effects import DEFAULT_EFFECTS
from .error_model import ErrorModel
from .identify import Fit, fit_at, identify
from .params_io import ParamsError, read_params
from .robot_model import RobotModel

#: the "uncalibrated" reference: nominal kinematics, with only the base (where the robot
#: stands) and the tool (where the SMR sits) fitted, since neither is a property of the arm
UNCALIBRATED_EFFECTS = "base,tool"
UNCALIBRATED_LABEL = "uncalibrated (best-fit base and tool)"

#: where the current model's parameters come from: a params.json path, or
#: (error model, values in internal units)
ParamsSource = str | Path | tuple[ErrorModel, np.ndarray]


def fit_uncalibrated(model: RobotModel, data: Dataset, **kw) -> Fit:
    """The nominal robot's accuracy: only the base and tool fitted (see
    :data:`UNCALIBRATED_EFFECTS`); ``kw`` go to :func:`~calibration.identify.identify`."""
    return identify(ErrorModel(model, UNCALIBRATED_EFFECTS), data, **kw)


def current_fit(model: RobotModel, data: Dataset, effects: str = DEFAULT_EFFECTS,
                params: ParamsSource | None = None, solver: str = "lm") -> Fit:
    """The current model's fit: at given parameters, else identified.

    Parameters
    ----------
    model : the nominal robot of the data
    data : the measured poses (calibration and ``set=valid`` rows)
    effects : the current model's effects (ignored with ``params``)
    params : the current model's parameters are taken from there instead of fitted
        (:func:`~calibration.identify.fit_at`), see :data:`ParamsSource`
    solver : identification method

    Raises :class:`~calibration.params_io.ParamsError` when the parameters' model has
    other joints or another convention than ``model``; the loaders' own errors pass
    through.
    """
    if params is None:
        return identify(ErrorModel(model, effects), data, solver)
    notes: list[str] = []
    if isinstance(params, (str, Path)):
        loaded = read_params(params, model=model)
        em, x, notes = loaded.error_model, loaded.values, loaded.notes
    else:
        em, x = params
        if em.model.n_joints != model.n_joints:
            raise ParamsError(f"parameters of a model with {em.model.n_joints} joints, "
                              f"the data's {model.name} has {model.n_joints}")
    fit = fit_at(em, data, x)
    fit.notes.extend(notes)
    return fit


@dataclass
class StagedFit:
    """The three fits of :func:`staged_fit` and the diagnosis that links them.

    Attributes
    ----------
    uncalibrated : nominal kinematics, base and tool fitted
    current : the current model (``given``: at the parameters of a params file)
    diagnosis : the diagnosis of ``current``
    improved : ``current`` plus the recommended effect, refitted; None when nothing
        significant is missing (or not asked for)
    given : the current parameters were given, not fitted
    timings : seconds spent fitting (``fit_s``) and diagnosing (``diagnose_s``)
    """

    uncalibrated: Fit
    current: Fit
    diagnosis: Diagnosis
    improved: Fit | None = None
    given: bool = False
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def added_effect(self) -> str | None:
        """The effect ``improved`` adds to the current model, or None."""
        return None if self.improved is None else self.diagnosis.best.effect


def staged_fit(data: Dataset, model: RobotModel, effects: str = DEFAULT_EFFECTS,
               params: ParamsSource | None = None, *, solver: str = "lm",
               refit: bool = True) -> StagedFit:
    """Uncalibrated → current → current plus the recommended effect.

    Parameters are those of :func:`current_fit`; ``refit`` adds the recommended effect
    (when the diagnosis finds a significant one) and refits, with the same solver.
    """
    t0 = time.perf_counter()
    current = current_fit(model, data, effects, params, solver)
    uncalibrated = fit_uncalibrated(model, data, solver=solver)
    t1 = time.perf_counter()
    diag = diagnose(current, data)
    t2 = time.perf_counter()
    improved = None
    if refit and diag.best is not None:
        improved = identify(current.error_model.with_effects(diag.best.effect), data, solver)
    t3 = time.perf_counter()
    return StagedFit(uncalibrated, current, diag, improved, params is not None,
                     {"fit_s": t1 - t0 + t3 - t2, "diagnose_s": t2 - t1})
