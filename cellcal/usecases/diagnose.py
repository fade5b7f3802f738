"""``diagnose``: where the model fails and which missing effect explains it; with
``--auto``, add the best effects one at a time while the held-out error falls.

:class:`DiagnoseRequest` is what the command was asked; :func:`diagnose` fits the current
model and ranks the candidates, or runs the automatic diagnosis and writes its params.json;
it returns a :class:`DiagnoseResult`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field

from pydantic import Field

from calibration.data.dataset import Dataset
from calibration.diagnosis.auto_diagnosis import AutoDiagnosis, AutoStep, auto_diagnose
from calibration.diagnosis.diagnosis import Diagnosis
from calibration.diagnosis.diagnosis import diagnose as rank_candidates
from calibration.exports.params_io import fit_to_dict
from calibration.files import write_atomic
from calibration.fit.identify import Fit
from calibration.fit.model_check import ModelCheck, check_model
from calibration.workflow import current_fit

from ..errors import UsageError
from ..request import FiniteFloat
from .inputs import CurrentModelInputs, DataInputs, check_data, current_model, load_inputs
from .outputs import check_outputs, existing_paths

#: ``--max-steps`` when not given
DEFAULT_MAX_STEPS = 12


class DiagnoseRequest(DataInputs, CurrentModelInputs):
    """The flags of ``cellcal diagnose`` (defaults as the parser's)."""

    top: int = Field(12, alias="--top", ge=1)
    auto: bool = Field(False, alias="--auto")
    max_steps: int = Field(DEFAULT_MAX_STEPS, alias="--max-steps")
    budget_s: FiniteFloat | None = Field(None, alias="--budget-s")
    out: str | None = Field(None, alias="--out")

    def check(self) -> None:
        """Refuse ``--auto``'s flags without it, and outputs that would destroy something
        (UsageError, exit 2)."""
        if not self.auto:
            given = [f for f, v in (("--out", self.out), ("--budget-s", self.budget_s),
                                    ("--max-steps", self.max_steps != DEFAULT_MAX_STEPS)) if v]
            if given:
                raise UsageError(f"{', '.join(given)} need(s) --auto")
            return
        if self.max_steps < 1:
            raise UsageError("--max-steps must be at least 1")
        if self.budget_s is not None and not self.budget_s > 0:
            raise UsageError("--budget-s must be a positive number of seconds")
        check_outputs({"--out": self.out},
                      existing_paths(self.data, self.params, self.model, self.effect_file))


@dataclass
class DiagnoseResult:
    """What :func:`diagnose` found.

    Attributes
    ----------
    fit : the current model's fit; ``data`` the measured poses
    diagnosis : the ranking of the missing effects (None with ``--auto``)
    auto : the automatic diagnosis (``--auto``), else None
    notes : remarks for the user on the data and the parameters read
    given : with ``--params``, the given model's own error on the calibration poses, as
        calibrated (:func:`~calibration.fit.model_check.check_model`): the diagnosis'
        figures are of a refit of every parameter on these poses, this one is not
    """

    fit: Fit
    data: Dataset
    diagnosis: Diagnosis | None = None
    auto: AutoDiagnosis | None = None
    notes: list[str] = field(default_factory=list)
    given: ModelCheck | None = None


def diagnose(request: DiagnoseRequest, *, on_note: Callable[[str], None] | None = None,
             on_start: Callable[[Fit, ModelCheck | None], None] | None = None,
             on_step: Callable[[AutoStep], None] | None = None) -> DiagnoseResult:
    """Fit the current model, then rank the candidates (or, with ``--auto``, add them).

    ``on_note`` is called with each remark as soon as it is known (before the fit);
    ``on_start`` with the start fit (and, with ``--params``, the given model's own error:
    ``given`` of the result) before the automatic diagnosis, ``on_step`` with each
    step it accepts (the command shows them as they come).

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2); InsufficientData: data too poor for the model, TooLarge: too
        large for the memory left (exit 3).
    """
    request.check()
    model, data = load_inputs(request)
    em, params, notes = current_model(request, model)
    notes += check_data(em, data, "diagnose", "auto" if request.auto else "diagnose")
    for n in notes if on_note is not None else ():
        on_note(n)
    fit = current_fit(model, data, request.effects, params, request.solver)
    given = None
    if params is not None:  # the given model's own error, before anything is refitted
        given = check_model(*params, data.calib() if data.is_valid.any() else data)
    if not request.auto:
        return DiagnoseResult(fit, data, diagnosis=rank_candidates(fit, data), notes=notes,
                              given=given)
    if on_start is not None:
        on_start(fit, given)
    result = auto_diagnose(fit, data, max_steps=request.max_steps, budget_s=request.budget_s,
                           progress=on_step)
    if request.out:
        write_atomic(request.out, json.dumps(fit_to_dict(result.fit, list(request.effect_file),
                                                         auto=result), indent=1) + "\n")
    return DiagnoseResult(fit, data, auto=result, notes=notes, given=given)
