"""``cellcal zero``: joint zero corrections from postures that put the tool tip on one
fixed point (:mod:`calibration.zero_point`), and the updated model or params written.

:class:`ZeroRequest` is what the user asked; :func:`recalibrate_zero` reads the postures
(:mod:`cellcal.usecases.zero_inputs`), runs the seed and/or the rigorous method, and
returns a :class:`ZeroOutcome`: the ``zero --json`` document (docs/formats.md §4) and
the results it was made from.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import Field

from ..errors import UsageError
from ..request import Request


class ZeroRequest(Request):
    """The postures (a CSV, or ``db`` with ``run`` / ``robot_id``), the model, a
    calibration of the cell (``params``), the method and its settings, a previous result to
    start from (``replay``) and the file to write (``out``)."""

    postures: str | None = Field(None, alias="POSTURES.csv")
    db: str | None = Field(None, alias="--db")
    run: int | None = Field(None, alias="--run")
    robot_id: str | None = Field(None, alias="--robot-id")
    model: str | None = Field(None, alias="--model")
    params: str | None = Field(None, alias="--params")
    effect_file: list[str] = Field([], alias="--effect-file")
    method: str = Field("both", alias="--method")
    tolerance_deg: float = Field(0.01, alias="--tolerance-deg")
    sigma: float = Field(0.02, alias="--sigma")
    replay: str | None = Field(None, alias="--replay")
    keep_outliers: bool = Field(False, alias="--keep-outliers")
    seed: int = Field(0, alias="--seed")
    out: str | None = Field(None, alias="--out")

    def out_path(self) -> Path | None:
        """``out``, checked: never an input, a store or a folder; a .yaml or .json file (a
        .json one needs ``params``). UsageError otherwise."""
        from .outputs import check_outputs, existing_paths

        if not self.out:
            return None
        check_outputs({"--out": self.out}, existing_paths(
            self.model, self.params, self.postures, self.replay, self.db, self.effect_file))
        path = Path(self.out)
        if path.suffix not in (".yaml", ".yml", ".json"):
            raise UsageError(f"--out {self.out}: give a .yaml (model) or .json (params) file")
        if path.suffix == ".json" and not self.params:
            raise UsageError("--out *.json updates a params file: give --params")
        return path


@dataclass(frozen=True)
class ZeroOutcome:
    """The ``zero --json`` document (``doc``; ``doc["status"]`` ok or poor), the result
    reported (``main``, a :class:`~calibration.zero_point.ZeroResult`), every method's
    result (``results``, by name) and the file asked for (``out``; written when
    ``doc["out_file"]`` is set)."""

    doc: dict
    main: Any
    results: dict
    out: Path | None

    @property
    def decided(self) -> bool:
        return self.doc["status"] == "ok"


def _methods(req: ZeroRequest, fk, postures, offsets0, measured) -> dict:
    from calibration.zero_point import rigorous_method, seed_method

    results = {}
    if req.method in ("seed", "both"):
        results["seed"] = seed_method(fk, postures, offsets0=offsets0,
                                      rng=np.random.default_rng(req.seed), sigma_mm=req.sigma)
    if req.method in ("rigorous", "both"):
        results["rigorous"] = rigorous_method(fk, postures, offsets0=offsets0,
                                              measured_base=measured, sigma_mm=req.sigma,
                                              reject_outliers=not req.keep_outliers)
    return results


def _document(req: ZeroRequest, model, postures, results: dict, measured) -> dict:
    from presentation.summaries import zero_summary

    main = results.get("rigorous", results.get("seed"))
    doc = zero_summary(main, model.name, postures.n, tolerance_deg=req.tolerance_deg,
                       sigma_mm=req.sigma, measured=measured is not None
                       and main.method != "seed")
    if "seed" in results and main is not results["seed"]:
        s = results["seed"]
        sdoc = zero_summary(s, model.name, postures.n, tolerance_deg=req.tolerance_deg,
                            sigma_mm=req.sigma)
        doc["seed"] = {k: sdoc[k] for k in ("offsets_deg", "tool_mm", "target_mm", "rms_mm",
                                            "status", "reasons", "converged", "reason",
                                            "iterations", "solve_s")}
        both = main.determined & s.determined
        diff = np.degrees(np.abs(main.offsets - s.offsets))[both]
        doc["max_difference_deg"] = float(diff.max()) if diff.size else None
    doc["pose_ids"] = postures.pose_id
    doc["residuals_mm"] = [round(float(v), 6) for v in np.linalg.norm(main.residuals, axis=1)]
    return doc


def _write_out(out: Path, model, params_path: str | None, result) -> None:
    """The updated params (``.json``, :func:`calibration.exports.params_io.write_zero_update`) or
    model (``.yaml``: the corrections added to the joints' ``theta_offset``)."""
    from calibration.exports.params_io import write_zero_update
    from calibration.files import write_atomic

    off = np.where(result.determined, result.offsets, 0.0)
    if out.suffix == ".json":
        write_zero_update(params_path, out, off)
        return
    joints = [j.model_dump() for j in model.joints]
    for j, v in enumerate(off):
        joints[j]["theta_offset"] = joints[j]["theta_offset"] + math.degrees(v)
    write_atomic(out, model.with_changes(joints=joints).to_yaml())


def recalibrate_zero(req: ZeroRequest, note: Callable[[str], None] = lambda _: None
                     ) -> ZeroOutcome:
    """The zero-point recalibration of the request; the file ``req.out`` written when the
    status is ok. ``note`` receives remarks on the inputs as they are read (the notes on
    the result are in ``doc["notes"]``). UsageError (or a reader's error) for bad input."""
    from calibration.effects import load_effect_file

    from . import zero_inputs
    from .input_errors import wrap_errors

    if (req.postures is None) == (req.db is None):
        raise UsageError("give a postures CSV or --db cell.db (not both)")
    if (req.run is not None or req.robot_id is not None) and req.db is None:
        raise UsageError("--run and --robot-id need --db")
    out = req.out_path()
    for f in req.effect_file:
        wrap_errors(lambda f=f: load_effect_file(f))
    if req.db is not None:  # tips stay in the tracker frame when --params gives the base
        inputs = zero_inputs.from_store(req.db, req.run, req.robot_id, req.model,
                                        to_base=not req.params)
    else:
        inputs = zero_inputs.from_csv(req.postures, req.model)
    model, notes = inputs.model, []
    fk, base = zero_inputs.chain(model, req.params, note)
    postures = (zero_inputs.joints_as_calibrated(req.params, inputs, notes) if req.params
                else inputs.postures)
    offsets0 = zero_inputs.replay_start(req.replay, model.n_joints) if req.replay else None
    measured = postures.base_p_tip
    if postures.tracker_p_tip is not None:
        if base is not None:  # the calibrated model's base: tracker_T_base
            measured = postures.tips_in_base(*base).base_p_tip
        else:
            notes.append("measured tips are in the tracker frame and the base pose is unknown "
                         + ("(no base in --params)" if req.params else
                            "(no frame run, no --params)") + ": not used")
    results = _methods(req, fk, postures, offsets0, measured)
    doc = _document(req, model, postures, results, measured)
    main = results.get("rigorous", results.get("seed"))
    doc["source"] = inputs.source
    doc["notes"] = notes
    doc["out_file"] = None
    if out is not None and doc["status"] == "ok":
        _write_out(out, model, req.params, main)
        doc["out_file"] = str(out)
    return ZeroOutcome(doc, main, results, out)
