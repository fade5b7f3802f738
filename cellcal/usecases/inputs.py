"""What calibrate, diagnose and report read: the measurement CSV, its robot model and the
current model, as typed request fields, and the loaders that turn them into the core's
objects.

:class:`DataInputs` and :class:`CurrentModelInputs` are mixins of the commands' requests
(their fields carry the flags' names); :func:`load_inputs` gives (model, dataset) with the
capture's tool and a ``--sigma`` override applied; :func:`current_model` the model to start
from (``--params`` or ``--effects``); :func:`check_data` refuses data too poor to fit.
Bad files raise the core's errors (DataError, ModelError, EffectError, ParamsError: exit 2).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import Field

from calibration.effects import DEFAULT_EFFECTS

from ..errors import UsageError
from ..request import FiniteFloat, Request
from .input_errors import wrap_errors  # noqa: F401 - the loaders' error wrapper

if TYPE_CHECKING:
    from calibration import Dataset, ErrorModel, RobotModel


class DataInputs(Request):
    """A measurement CSV and the model to read it with (``DATA.csv``, ``--model``,
    ``--effect-file``, ``--sigma``)."""

    data: str = Field(alias="DATA.csv")
    model: str | None = Field(None, alias="--model")
    effect_file: tuple[str, ...] = Field((), alias="--effect-file")
    sigma: FiniteFloat | None = Field(None, alias="--sigma", gt=0)


class CurrentModelInputs(Request):
    """The current model of diagnose and report: ``--params`` (given parameters), else
    ``--effects`` fitted with ``--solver``."""

    effects: str = Field(DEFAULT_EFFECTS, alias="--effects")
    params: str | None = Field(None, alias="--params")
    solver: str = Field("lm", alias="--solver")


def model_name(request: DataInputs, required: bool = True) -> str | None:
    """``--model``, else the model the data file's metadata names; UsageError when neither
    (None when not ``required``)."""
    if request.model:
        return request.model
    from calibration.data.dataset import read_meta

    name = read_meta(request.data).get("model")
    if not name and required:
        raise UsageError(f"give --model: {request.data} names no model (no `# model:` line)")
    return name or None


def load_model_with(name: str | None, effect_files: tuple[str, ...] = (),
                    request: DataInputs | None = None) -> RobotModel:
    """The model ``name`` (built-in or YAML), after loading the user's effect files (a
    model may use their effects); ``name`` None: the one ``request``'s data names, else,
    with ``--params``, the calibration's own (params.json embeds its model)."""
    from calibration import load_model
    from calibration.effects import load_effect_file

    for f in effect_files:
        load_effect_file(f)
    if name:
        return load_model(name)
    params = getattr(request, "params", None)
    named = model_name(request, required=not params)
    if named:
        return load_model(named)
    from calibration.exports.params_io import read_params

    return read_params(params).error_model.model


def load_inputs(request: DataInputs) -> tuple[RobotModel, Dataset]:
    """(model, dataset) of the request.

    The model gets the capture's tool (the controller's TCP, ``# tool_mm:`` in the CSV's
    metadata) as its nominal tool, so every fit starts from what the controller knew; a
    ``--sigma`` replaces the file's tracker uncertainty (:meth:`Dataset.with_tracker_sigma`).
    """
    from calibration import load_csv

    model = load_model_with(request.model, request.effect_file, request)
    data = load_csv(request.data, model)
    model = data.capture.with_tool(model)
    if request.sigma is not None:
        data = data.with_tracker_sigma(request.sigma)
    return model, data


def error_model_of(model: RobotModel, spec: str, flag: str = "--effects") -> ErrorModel:
    """``ErrorModel(model, spec)``; a bad effect list is a UsageError naming the flag."""
    from calibration import ErrorModel
    from calibration.effects import EffectError

    try:
        return ErrorModel(model, spec)
    except EffectError as e:
        raise UsageError(f"{flag} {spec!r}: {e}") from None


def current_model(request: CurrentModelInputs, model: RobotModel):
    """The current model of diagnose/report: (error model, params source for
    :func:`calibration.workflow.current_fit` or None, notes). ``--params`` is read
    strictly and checked against ``--model``; else ``--effects`` on the model."""
    from calibration.exports.params_io import read_params

    if request.params:
        p = read_params(request.params, model=model)
        return p.error_model, (p.error_model, p.values), p.notes
    return error_model_of(model, request.effects), None, []


def check_data(error_model: ErrorModel, data: Dataset, command: str = "calibrate",
               work: str = "fit") -> list[str]:
    """Refuse data too large for the memory left (TooLarge: exit 3, before any work:
    ``work`` a kind of :data:`calibration.numerics.memory.WORK`) or too poor to identify
    ``error_model`` (InsufficientData: exit 3); the notes on marginal data otherwise."""
    from calibration.fit.data_quality import check_for_fit
    from calibration.numerics.memory import check_memory

    check_memory(command, work, data.n, error_model.n_params)
    return check_for_fit(error_model, data).notes
