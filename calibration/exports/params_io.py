"""params.json: every parameter of a fit with value, uncertainty and units, readable back.

The file embeds the nominal model, so it is self-contained::

    {"format": "cellcal-params", "version": 2,
     "model": "ur10e", "model_definition": {...model YAML as a mapping...},
     "model_hash": "3f1c...",
     "effects": ["geometric", "base", "tool"],
     "effect_files": [{"name": "my_effects.py", "sha256": "9a0b...", "families": ["sag"]}],
     "solver": "lm",
     "parameters": [{"name": "geometric.j2.a", "value": 0.21, "std": 0.004,
                     "unit": "mm", "identifiable": true, "weak": null}, ...],
     "stats": {"calib": {...}, "valid": {...}}, "noise_floor_mm": 0.029,
     "correlation": {"names": [...free parameters...], "matrix": [[1.0, ...], ...]},
     "strongest_correlations": [{"a": "geometric.j5.d", "b": "geometric.j5.alpha",
                                 "r": -0.99}, ...],
     "solver_info": {"xi": 2e-05, "condition_class": "strong", "rejected": ["17"], ...},
     "outliers": [{"pose_id": "p017", "residual_mm": 2.41, "along_beam": true,
                   "excluded": true, "line": 19, "angle_to_beam_deg": 8.2}, ...],
     "outlier_check": {"mode": "exclude", "clean_cloud": true, "threshold_mm": 0.07, ...},
     "envelope": {"version": 1, "n_poses": 150, "joints_deg": [[-170.2, 168.9], ...],
                  "t_s": [1.7e9, 1.7e9 + 3600]},
     "auto_steps": {"start_effects": ["geometric", "base", "tool"],
                    "start_calib_rms_mm": 0.21, "start_heldout_rms_mm": 0.23,
                    "heldout_method": "validation poses", "noise_floor_mm": 0.026,
                    "steps": [{"effect": "compliance:3", "n_params": 1,
                               "calib_rms_mm": 0.03, "heldout_rms_mm": 0.031,
                               "seconds": 1.2, "explanation": "..."}, ...],
                    "stop_reason": "..."}}

``correlation``, ``strongest_correlations``, ``solver_info`` (only for solvers with
extras: ridge, besa, sa), ``outliers`` (the blunders left out of the fit, or only named
with ``--outliers flag``) and ``outlier_check`` were added after version 1 and are
ignored when reading the parameters (:func:`read_outliers` reads the blunders; a file
without them has none); so is ``auto_steps``, written by ``diagnose --auto --out``: the
steps the automatic diagnosis took to reach these parameters (:func:`read_auto_steps`);
``smoothing`` (effect name -> the penalty weight of a correction
table) is read back. A table's knots are its parameter names (``table5.j2.kp010``: +10°),
so a table whose knots span only the data's angles reads back as it was fitted.
``capture`` (also ignored when reading the parameters) is what the measurement file said
about its capture (:class:`~calibration.data.capture_meta.CaptureMeta`: run and store, model,
the controller's tool, SMR radius, measurement frame, tracker sigma; :func:`capture_of`
reads it back). The capture's tool is also the nominal tool of ``model_definition``.
Version 2 added ``model_hash`` (:meth:`RobotModel.definition_hash`), the parameters'
``weak`` (why an identifiable parameter is only weakly determined, else null) and
effect files recorded by name and sha256 (version 1 recorded their paths). Version-1
files still load. Keys a reader does not know are ignored (the format is extended,
never broken). ``thermal`` (a model with a drift effect only) is the time window,
reference temperature and warm state its parameters were fitted against, given back to
the reloaded effects; it carries a version of its own (:mod:`calibration.fit.thermal_state`):
a file without it measures time against the data it meets, as before.
``envelope`` (:class:`~calibration.fit.envelope.Envelope`, a version of its own) is the
range of each joint the calibration rows covered (deg, as the CSV's q1..qN), and of the
air temperature, joint temperatures and time where an effect reads them: what
``compensate`` and ``validate`` check targets against (a file without it checks nothing).

Reading is strict (:class:`ParamsFile`, pydantic): every value a finite number of a
plausible size, std null or >= 0, units as the effect declares them, every parameter of
the effects present once; the embedded model passes the model YAML's own checks and, in
version 2, matches its hash; with ``model`` given (the command's ``--model``) its joints
and convention must be the same. Errors name the file and the field, in one line.

Code runs only when the user asks: a recorded effect file is never imported from here.
Reading a file that records one needs the same file loaded by the caller (the command
line's ``--effect-file``), with the recorded sha256.

Angles are in degrees (``unit: "deg"``). Geometric parameters are deltas to the
nominal table; base and tool parameters are absolute.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, cast

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
)

from ..data.capture_meta import CaptureMeta
from ..effects import REGISTRY, EffectError, display_unit, effect_source, parse_effects
from ..errors import ParamsError
from ..files import json_ready, read_text, write_atomic
from ..fit.envelope import Envelope
from ..fit.error_model import ErrorModel
from ..fit.identify import Fit
from ..fit.thermal_state import apply_thermal_record, check_thermal_record, thermal_record
from ..fit.uncertainty import correlations
from ..model.robot_model import (
    ModelError,
    RobotModel,
    format_validation,
    model_from_dict,
    number_only,
)

FORMAT = "cellcal-params"
#: the version written; readers take 1..VERSION
VERSION = 2
#: the largest params.json read (bytes)
MAX_PARAMS_BYTES = 50 << 20
#: |value| of a parameter in display units above this is no calibration result
MAX_VALUE = 1e6


# ------------------------------------------------------------------------- schema
def _finite_value(v: float) -> float:
    if not math.isfinite(v):
        raise ValueError(f"{v} is not a finite number")
    if abs(v) > MAX_VALUE:
        raise ValueError(f"{v:g} is not a plausible parameter value (|value| <= {MAX_VALUE:g})")
    return v


def _std(v: float | None) -> float | None:
    if v is not None and not (math.isfinite(v) and v >= 0):
        raise ValueError(f"{v} is not a standard uncertainty (a finite number >= 0)")
    return v


Value = Annotated[float, BeforeValidator(number_only), AfterValidator(_finite_value)]
Std = Annotated[float | None, BeforeValidator(lambda v: v if v is None else number_only(v)),
                AfterValidator(_std)]


def _smoothing(v: float) -> float:
    if not (math.isfinite(v) and v >= 0):
        raise ValueError(f"{v} is not a smoothing weight (a finite number >= 0)")
    return v


Smoothing = Annotated[float, BeforeValidator(number_only), AfterValidator(_smoothing)]


class ParamRow(BaseModel):
    """One parameter: value and std in ``unit`` (angles in deg)."""

    model_config = ConfigDict(extra="ignore")
    name: str = Field(min_length=1, max_length=200)
    value: Value
    std: Std = None
    unit: str = Field(max_length=40)
    identifiable: bool = True
    weak: str | None = None


class EffectFileRecord(BaseModel):
    """A user effect file a calibration used: its name, content hash and families."""

    model_config = ConfigDict(extra="ignore")
    name: str = Field(min_length=1, max_length=255)
    sha256: str | None = Field(default=None, pattern=r"^[0-9a-f]{64}$")
    families: list[str] = Field(default_factory=list)


class ParamsFile(BaseModel):
    """The keys of params.json a reader uses (others are kept but not checked)."""

    model_config = ConfigDict(extra="ignore")
    format: Literal["cellcal-params"]
    version: int = Field(ge=1)
    model: str = ""
    model_definition: dict
    model_hash: str | None = None
    effects: list[str] = Field(min_length=1)
    effect_files: list[EffectFileRecord | str] = Field(default_factory=list)
    parameters: list[ParamRow] = Field(min_length=1)
    smoothing: dict[str, Smoothing] = Field(default_factory=dict)

    def records(self) -> list[EffectFileRecord]:
        """Effect files as records (a version-1 path becomes its file name, no hash)."""
        return [r if isinstance(r, EffectFileRecord) else EffectFileRecord(name=Path(r).name)
                for r in self.effect_files]


# ------------------------------------------------------------------------- writing
def effect_file_records(fit: Fit) -> list[dict]:
    """The user effect files the fit's effects come from: name, sha256 and families
    (files loaded but unused are not recorded)."""
    out: dict[str, dict] = {}
    for e in fit.error_model.effects:
        src = effect_source(type(e))
        if src is None:
            continue
        rec = out.setdefault(src[0], {"name": src[0], "sha256": src[1], "families": []})
        if e.family not in rec["families"]:
            rec["families"].append(e.family)
    return list(out.values())


def fit_to_dict(fit: Fit, effect_files: list[str] | None = None, auto: Any = None,
                capture: CaptureMeta | None = None) -> dict:
    """The params.json mapping of ``fit``; ``auto`` (an
    :class:`~calibration.diagnosis.auto_diagnosis.AutoDiagnosis` whose final fit ``fit`` is) adds
    its steps as ``auto_steps``; ``capture`` the capture's context as ``capture``.
    ``effect_files`` (the files the user loaded) is accepted for compatibility: the
    records come from the fit's own effects."""
    em = fit.error_model
    thermal = thermal_record(fit)
    out = {
        "format": FORMAT,
        "version": VERSION,
        "model": em.model.name,
        "model_definition": json.loads(em.model.model_dump_json(exclude_none=True)),
        "model_hash": em.model.definition_hash(),
        "effects": em.labels,
        "effect_files": effect_file_records(fit),
        "solver": fit.solver,
        "parameters": fit.parameter_rows(),
        "unidentifiable": fit.identifiability.fixed,
        "weakly_identified": fit.weakly_identified(),
        "stats": {"calib": fit.calib, **({"valid": fit.valid} if fit.valid else {})},
        "noise_floor_mm": fit.noise_floor_mm,
        "sigma_mm": fit.sigma_mm,
        "converged": fit.converged,
        "reason": fit.reason,
    }
    # added keys (version 1 readers ignore them): correlations of the free parameters,
    # and the robust solver's verdict on the poses
    corr = correlations(fit)
    out["correlation"] = {"names": corr["names"], "matrix": corr["matrix"]}
    out["strongest_correlations"] = corr["strongest"]
    info = solver_summary(fit)
    if info:
        out["solver_info"] = info
    tables: list[Any] = [e for e in em.effects if hasattr(e, "penalty_matrix")]
    smoothing = {e.label: e.smoothing for e in tables}
    if smoothing:
        out["smoothing"] = smoothing
    if fit.outliers is not None:
        out["outliers"] = fit.outliers.to_json()
        out["outlier_check"] = fit.outliers.check_json()
    if auto is not None:
        out["auto_steps"] = auto_steps_json(auto)
    if capture is not None and capture.known:
        out["capture"] = capture.to_json()
    if thermal is not None:
        out["thermal"] = thermal
    out["envelope"] = Envelope.of_fit(fit).to_json()
    return out


def auto_steps_json(auto: Any) -> dict[str, Any]:
    """The ``auto_steps`` record of an :class:`~calibration.diagnosis.auto_diagnosis.AutoDiagnosis`:
    the start model, every step (as in ``diagnose --auto --json``) and why it stopped."""
    return {
        "start_effects": list(auto.start.error_model.labels),
        "start_calib_rms_mm": float(auto.start.calib["rms_mm"]),
        "start_heldout_rms_mm": float(auto.start_heldout_rms_mm),
        "heldout_method": auto.heldout_method,
        "noise_floor_mm": auto.noise_floor_mm,
        "steps": [s.to_json() for s in auto.steps],
        "stop_reason": auto.stop_reason,
    }


def read_auto_steps(source: str | Path | dict) -> dict | None:
    """The ``auto_steps`` record of a params.json (a path or its mapping), None when the
    file has none (written by ``calibrate``, or before steps were recorded) or it is not
    a mapping with a ``steps`` list."""
    data = source if isinstance(source, dict) else _read_json(source)
    if not isinstance(data, dict):
        return None
    rec = data.get("auto_steps")
    if not isinstance(rec, dict) or not isinstance(rec.get("steps"), list):
        return None
    return rec


def params_by_name(fit: Fit) -> dict:
    """The ``params`` object of ``calibrate --json``: every parameter by its params.json
    name, ``{"value", "std", "unit"}`` in display units (std None for a parameter the data
    cannot determine, held at its start value)."""
    return {r["name"]: {"value": r["value"], "std": r["std"], "unit": r["unit"]}
            for r in fit.parameter_rows()}


def read_outliers(source: str | Path | dict) -> list[dict]:
    """The ``outliers`` list of a params.json (a path or its mapping); [] for files written
    before blunders were tested."""
    data = source if isinstance(source, dict) else _read_json(source)
    out = data.get("outliers", []) if isinstance(data, dict) else []
    return list(out) if isinstance(out, list) else []


def read_stats(source: str | Path | dict) -> dict:
    """The ``stats`` of a params.json (a path or its mapping): its calibration's own error
    on its calibration rows (``calib``) and validation rows (``valid``, when it had some),
    each as :func:`~calibration.fit.identify.error_stats` wrote it; {} when absent."""
    data = source if isinstance(source, dict) else _read_json(source)
    out = data.get("stats") if isinstance(data, dict) else None
    if not isinstance(out, dict):
        return {}
    return {k: v for k, v in out.items() if k in ("calib", "valid") and isinstance(v, dict)}


def read_document(path: str | Path) -> dict:
    """The JSON document of a params.json as read (the size limit, UTF-8, JSON syntax:
    ParamsError naming the file otherwise); :func:`read_params` checks its contents."""
    data = _read_json(path)
    if not isinstance(data, dict):
        raise ParamsError(f"{path}: not a cellcal params file (a JSON object expected)")
    return data


def capture_of(path: str | Path | dict) -> CaptureMeta:
    """The ``capture`` metadata of a params.json (a path or its mapping; empty when it has
    none or it is malformed)."""
    try:  # read as the parameters are (size limit, UTF-8); ParamsError is a ValueError
        doc = path if isinstance(path, dict) else _read_json(path)
        return CaptureMeta.from_json(doc.get("capture"))
    except (ValueError, TypeError, AttributeError):
        return CaptureMeta()


def solver_summary(fit: Fit) -> dict:
    """JSON-ready solver extras: ridge (xi, condition class, rejected and down-weighted
    pose ids) and annealing (evaluations, seed); empty for other solvers."""
    keys = ("xi", "xi_method", "condition_number", "condition_class", "scale_mm",
            "rejected", "downweighted", "refixed", "evaluations", "accepted", "seed",
            "f_best_mm2", "ideal_mm2")
    out = {}
    for k in keys:
        if k in fit.info:
            v = fit.info[k]
            out[k] = float(v) if isinstance(v, (np.floating, float)) else v
    return out


def params_json(fit: Fit, effect_files: list[str] | None = None, auto: Any = None,
                capture: CaptureMeta | None = None) -> str:
    """The text of params.json (NaN and infinities written as null: strict JSON)."""
    return json.dumps(json_ready(fit_to_dict(fit, effect_files, auto, capture)), indent=1,
                      allow_nan=False) + "\n"


def save_params(fit: Fit, path: str | Path, effect_files: list[str] | None = None,
                auto: Any = None, capture: CaptureMeta | None = None) -> None:
    """Write params.json atomically (the old file stays whole if writing fails), with
    ``auto``'s steps and ``capture``'s context."""
    write_atomic(path, params_json(fit, effect_files, auto, capture))


# ------------------------------------------------------------------------- reading
@dataclass
class LoadedParams:
    """A params.json read back: the error model, values and std (internal units)."""

    error_model: ErrorModel
    values: np.ndarray
    std: np.ndarray
    source: str
    notes: list[str] = field(default_factory=list)
    #: the ``thermal`` record (:mod:`calibration.fit.thermal_state`), None when none
    thermal: dict | None = None
    #: the calibrated envelope (:class:`~calibration.fit.envelope.Envelope`), None for a
    #: file written before it was recorded
    envelope: Envelope | None = None


def _check_effect_files(doc: ParamsFile, source: str) -> None:
    """Every recorded effect file must have been loaded by the user, with its sha256."""
    loaded: dict[str, str] = {}
    for cls in REGISTRY.values():
        src = effect_source(cls)
        if src is not None:
            loaded[src[0]] = src[1]
    for rec in doc.records():
        if rec.name not in loaded:
            digest = f" (sha256 {rec.sha256[:12]}...)" if rec.sha256 else ""
            raise ParamsError(
                f"{source}: made with the effect file {rec.name}{digest}: give "
                f"--effect-file {rec.name} to load it (cellcal runs no code named in a data "
                "file)")
        if rec.sha256 and loaded[rec.name] != rec.sha256:
            raise ParamsError(
                f"{source}: the effect file {rec.name} has changed since the calibration "
                f"(sha256 {loaded[rec.name][:12]}... given, {rec.sha256[:12]}... recorded); "
                "give the file the calibration was made with")


def model_differences(a: RobotModel, b: RobotModel) -> list[str]:
    """Top-level fields in which two models differ (the name aside)."""
    da, db = a.model_dump(exclude={"name"}), b.model_dump(exclude={"name"})
    return [k for k in da if da[k] != db[k]]


def params_from_doc(data: object, source: str = "<params>", *, model: RobotModel | None = None
                    ) -> LoadedParams:
    """A params mapping read strictly (see the module docstring); ``model``: the model the
    caller works with, whose joints and convention the params' model must have."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ParamsError(f"{source}: not a cellcal params file (a JSON object with format "
                          f"{FORMAT!r} expected)")
    if isinstance(data.get("version"), int) and data["version"] > VERSION:
        raise ParamsError(f"{source}: version {data['version']} is newer than this cellcal "
                          f"reads ({VERSION}); update cellcal")
    try:
        doc = ParamsFile.model_validate(data)
    except ValidationError as e:
        raise ParamsError(format_validation(e, source)) from None
    _check_effect_files(doc, source)
    try:
        pmodel = model_from_dict(doc.model_definition, f"{source}: model_definition")
    except ModelError as e:
        raise ParamsError(str(e)) from None
    if doc.model_hash is not None and doc.model_hash != pmodel.definition_hash():
        raise ParamsError(f"{source}: model_definition does not match its model_hash (edited "
                          "by hand?); calibrate again")
    notes = []
    if model is not None:
        diff = model_differences(pmodel, model)
        if {"convention", "joints"} & set(diff) or pmodel.n_joints != model.n_joints:
            raise ParamsError(
                f"{source}: calibrated for model {pmodel.name!r}, whose "
                f"{' and '.join(d for d in diff if d in ('convention', 'joints'))} differ "
                f"from --model {model.name!r}; give the model the calibration was made for")
        if diff:
            notes.append(f"{source}: the calibration's own {', '.join(diff)} of "
                         f"{pmodel.name} are used (they differ from --model {model.name})")
    try:
        effects = parse_effects(",".join(doc.effects), pmodel)
    except EffectError as e:
        raise ParamsError(f"{source}: effects: {e}") from None
    names = [row.name for row in doc.parameters]
    for eff in effects:
        if eff.label in doc.smoothing:
            cast(Any, eff).smoothing = doc.smoothing[eff.label]  # a table's
    for i, eff in enumerate(effects):
        if hasattr(eff, "with_parameter_names"):  # a table: its knots are in the names
            local = [n[len(eff.prefix) + 1 :] for n in names if n.startswith(eff.prefix + ".")]
            try:
                effects[i] = eff.with_parameter_names(local)
            except EffectError as err:
                raise ParamsError(f"{source}: effects: {err}") from None
    thermal = check_thermal_record(data.get("thermal"), pmodel.n_joints, source)
    apply_thermal_record(effects, thermal)
    em = ErrorModel(pmodel, effects)
    x = np.zeros(em.n_params)
    std = np.zeros(em.n_params)
    seen: dict[str, int] = {}
    for i, row in enumerate(doc.parameters):
        try:
            k = em.index(row.name)
        except KeyError:
            raise ParamsError(f"{source}: parameters.{i}: unknown parameter {row.name!r} for "
                              f"effects {','.join(doc.effects)}") from None
        if row.name in seen:
            raise ParamsError(f"{source}: parameters.{i}: {row.name} given twice "
                              f"(also parameters.{seen[row.name]})")
        unit, factor = display_unit(em.units[k])
        if row.unit != unit:
            raise ParamsError(f"{source}: parameters.{i}: {row.name}: unit {row.unit!r}, "
                              f"expected {unit!r}")
        x[k] = row.value / factor
        std[k] = (row.std or 0.0) / factor
        seen[row.name] = i
    missing = [n for n in em.names if n not in seen]
    if missing:
        shown = ", ".join(missing[:5]) + (f" and {len(missing) - 5} more" if len(missing) > 5
                                          else "")
        raise ParamsError(f"{source}: parameters missing: {shown}")
    envelope = Envelope.from_json(data.get("envelope"), pmodel.n_joints, source)
    return LoadedParams(em, x, std, source, notes, thermal, envelope)


def params_from_dict(data: dict, source: str = "<params>", *, model: RobotModel | None = None
                     ) -> tuple[ErrorModel, np.ndarray, np.ndarray]:
    """(error model, values, std) in internal units from a params mapping."""
    p = params_from_doc(data, source, model=model)
    return p.error_model, p.values, p.std


def read_params(path: str | Path, *, model: RobotModel | None = None) -> LoadedParams:
    """Read a params.json written by :func:`save_params` (see the module docstring)."""
    return params_from_doc(_read_json(path), str(path), model=model)


def _read_json(path: str | Path) -> Any:
    """The JSON document of a params file, read with the size limit; ParamsError naming
    the file, line and column otherwise."""
    text = read_text(path, ParamsError, "params file", MAX_PARAMS_BYTES)
    if not text.strip():
        raise ParamsError(f"{path}: empty file, not a params.json")
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise ParamsError(f"{path}: not valid JSON: line {e.lineno}, column {e.colno}: "
                          f"{e.msg}") from None
    except RecursionError:
        raise ParamsError(f"{path}: not a params.json (nested too deeply)") from None


def load_params(path: str | Path, *, model: RobotModel | None = None
                ) -> tuple[ErrorModel, np.ndarray, np.ndarray]:
    """(error model, values, std) of a params.json (:func:`read_params`)."""
    p = read_params(path, model=model)
    return p.error_model, p.values, p.std


# ---------------------------------------------------------------- zero-point update
def with_zero_offsets(doc: dict[str, Any], offsets_rad: Sequence[float] | np.ndarray,
                      source: str = "<params>") -> dict:
    """A params document (as read, unknown keys kept) with joint zero corrections applied:
    each ``geometric.jN.theta`` shifted by offset N (rad; written in degrees), and the
    update recorded in ``history`` as ``{"zero_point": {"offsets_deg": [...]}}``.

    Raises
    ------
    ParamsError
        The document has no ``geometric.jN.theta`` for a joint (no geometric effect).
    """
    out = json.loads(json.dumps(doc))  # a deep copy of plain JSON
    rows = {r["name"]: r for r in out["parameters"]}
    for j, v in enumerate(offsets_rad):
        name = f"geometric.j{j + 1}.theta"
        if name not in rows:
            raise ParamsError(f"{source}: no parameter {name} (no geometric effect); write a "
                              "model YAML instead")
        rows[name]["value"] = rows[name]["value"] + math.degrees(v)
    out.setdefault("history", []).append(
        {"zero_point": {"offsets_deg": [math.degrees(v) for v in offsets_rad]}})
    return out


def write_zero_update(params_path: str | Path, out: str | Path,
                      offsets_rad: Sequence[float] | np.ndarray) -> None:
    """Write ``out`` (atomically): the params file ``params_path`` with the joint zero
    corrections ``offsets_rad`` applied (:func:`with_zero_offsets`)."""
    doc = _read_json(params_path)
    write_atomic(out, json.dumps(with_zero_offsets(doc, offsets_rad, str(params_path)),
                                 indent=1) + "\n")


__all__ = ["FORMAT", "VERSION", "LoadedParams", "ParamsError", "auto_steps_json", "capture_of",
           "fit_to_dict", "load_params", "params_by_name", "params_from_dict",
           "params_from_doc", "params_json", "read_auto_steps", "read_document", "read_outliers",
           "read_params", "read_stats", "save_params", "solver_summary", "with_zero_offsets",
           "write_zero_update"]
