"""``simulate``: a measurement CSV of a simulated robot with hidden errors.

:class:`SimulateRequest` is what the command was asked; :func:`simulate_dataset` draws
realistic hidden errors, measures random poses with a noisy tracker (and blunders, when
asked), writes the CSV and the truth; it returns a :class:`SimulatedData`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np
from pydantic import Field

from calibration import DEFAULT_EFFECTS, Dataset, ErrorModel, RobotModel
from calibration.effects import display_unit
from calibration.files import write_atomic
from calibration.fit.simulate import (
    BlunderTruth,
    add_blunders,
    random_joints,
    realistic_truth,
    simulate,
)

from ..errors import UsageError
from ..flags.choices import MAX_SIMULATED_POSES
from ..request import FiniteFloat, Request
from .inputs import error_model_of, load_model_with
from .outputs import check_outputs, existing_paths


class SimulateRequest(Request):
    """The flags of ``cellcal simulate`` (defaults as the parser's)."""

    model: str = Field(alias="--model")
    effect_file: tuple[str, ...] = Field((), alias="--effect-file")
    hidden: str = Field("", alias="--hidden")
    poses: int = Field(300, alias="--poses", ge=1, le=MAX_SIMULATED_POSES)
    valid: int = Field(300, alias="--valid", ge=0, le=MAX_SIMULATED_POSES)
    sigma: FiniteFloat = Field(0.015, alias="--sigma", gt=0)
    blunders: FiniteFloat = Field(0.0, alias="--blunders", ge=0, le=1)
    seed: int = Field(1, alias="--seed", ge=0)
    out: str = Field(alias="--out")
    truth: str | None = Field(None, alias="--truth")


@dataclass
class SimulatedData:
    """What :func:`simulate_dataset` wrote: the ``data`` (in ``out``), the ``model``, the
    hidden ``error_model`` and its true parameters ``x``, the blunders added (or None)."""

    data: Dataset
    model: RobotModel
    error_model: ErrorModel
    x: np.ndarray
    blunders: BlunderTruth | None


def simulate_dataset(request: SimulateRequest) -> SimulatedData:
    """Simulate, write ``--out`` and ``--truth``.

    Raises
    ------
    UsageError, calibration.errors.InputError
        Bad input (exit 2).
    """
    check_outputs({"--out": request.out, "--truth": request.truth},
                  existing_paths(request.model, request.effect_file))
    model = load_model_with(request.model, request.effect_file)
    if request.poses + request.valid > MAX_SIMULATED_POSES:
        raise UsageError(f"--poses plus --valid must be at most {MAX_SIMULATED_POSES}")
    spec = DEFAULT_EFFECTS + ("," + request.hidden if request.hidden else "")
    em = error_model_of(model, spec, "--hidden")
    rng = np.random.default_rng(request.seed)
    x = realistic_truth(em, rng)
    n = request.poses + request.valid
    q = random_joints(model, n, rng)
    data = simulate(em, x, q, request.sigma, rng, is_valid=np.arange(n) >= request.poses)
    blunders = None
    if request.blunders > 0:
        data, blunders = add_blunders(data, request.blunders,
                                      np.random.default_rng([request.seed, 1]),
                                      rows=~data.is_valid)
    source = (f"cellcal simulate --model {request.model} --seed {request.seed}"
              + (f" --hidden {request.hidden}" if request.hidden else "")
              + (f" --blunders {request.blunders:g}" if request.blunders else ""))
    data = replace(data, meta={"source": source, **data.meta})
    data.to_csv(request.out)
    if request.truth:
        write_atomic(request.truth, json.dumps(_truth(em, x, blunders), indent=1))
    return SimulatedData(data, model, em, x, blunders)


def _truth(em: ErrorModel, x: np.ndarray, blunders: BlunderTruth | None) -> dict:
    """The ``--truth`` file: the hidden effects, their parameters (display units), the
    blunders."""
    rows = []
    for k, name in enumerate(em.names):
        unit, f = display_unit(em.units[k])
        rows.append({"name": name, "value": float(x[k] * f), "unit": unit})
    truth = {"effects": em.labels, "parameters": rows}
    if blunders is not None:
        truth["blunders"] = blunders.to_json()
    return truth
