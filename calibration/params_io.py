"""params.json: every parameter of a fit with value, uncertainty and units, readable back.

The file embeds the nominal model, so it is self-contained::

    {"format": "cellcal-params", "version": 1,
     "model": "ur10e", "model_definition": {...model YAML as a mapping...},
     "effects": ["geometric", "base", "tool"], "effect_files": [],
     "solver": "lm",
     "parameters": [{"name": "geometric.j2.a", "value": 0.21, "std": 0.004,
                     "unit": "mm", "identifiable": true}, ...],
     "stats": {"calib": {...}, "valid": {...}}, "noise_floor_mm": 0.029,
     "correlation": {"names": [...free parameters...], "matrix": [[1.0, ...], ...]},
     "strongest_correlations": [{"a": "geometric.j5.d", "b": "geometric.j5.alpha",
                                 "r": -0.99}, ...],
     "solver_info": {"xi": 2e-05, "condition_class": "strong", "rejected": ["17"], ...},
     "outliers": [{"pose_id": "p017", "residual_mm": 2.41, "along_beam": true,
                   "excluded": true, "line": 19, "angle_to_beam_deg": 8.2}, ...],
     "outlier_check": {"mode": "exclude", "clean_cloud": true, "threshold_mm": 0.07, ...},
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
about its capture (:class:`~calibration.capture_meta.CaptureMeta`: run and store, model,
the controller's tool, SMR radius, measurement frame, tracker sigma; :func:`capture_of`
reads it back). The capture's tool is also the nominal tool of ``model_definition``.

Angles are in degrees (``unit: "deg"``). Geometric parameters are deltas to the
nominal table; base and tool parameters are absolute.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .capture_meta import CaptureMeta
from .effects import EffectError, display_unit, load_effect_file, parse_effects
from .error_model import ErrorModel
from .identify import Fit
from .robot_model import model_from_dict
from .uncertainty import correlations

FORMAT = "cellcal-params"


class ParamsError(ValueError):
    """A params.json that cannot be used."""


def fit_to_dict(fit: Fit, effect_files: list[str] | None = None, auto=None,
                capture: CaptureMeta | None = None) -> dict:
    """The params.json mapping of ``fit``; ``auto`` (an
    :class:`~calibration.auto_diagnosis.AutoDiagnosis` whose final fit ``fit`` is) adds
    its steps as ``auto_steps``; ``capture`` the capture's context as ``capture``."""
    em = fit.error_model
    out = {
        "format": FORMAT,
        "version": 1,
        "model": em.model.name,
        "model_definition": json.loads(em.model.model_dump_json(exclude_none=True)),
        "effects": em.labels,
        "effect_files": [str(Path(f).resolve()) for f in (effect_files or [])],
        "solver": fit.solver,
        "parameters": fit.parameter_rows(),
        "unidentifiable": fit.identifiability.fixed,
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
    smoothing = {e.label: e.smoothing for e in em.effects if hasattr(e, "penalty_matrix")}
    if smoothing:
        out["smoothing"] = smoothing
    if fit.outliers is not None:
        out["outliers"] = fit.outliers.to_json()
        out["outlier_check"] = fit.outliers.check_json()
    if auto is not None:
        out["auto_steps"] = auto_steps_json(auto)
    if capture is not None and capture.known:
        out["capture"] = capture.to_json()
    return out


def auto_steps_json(auto) -> dict:
    """The ``auto_steps`` record of an :class:`~calibration.auto_diagnosis.AutoDiagnosis`:
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
    data = source if isinstance(source, dict) else _read_json(Path(source))
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
    data = source if isinstance(source, dict) else _read_json(Path(source))
    return list(data.get("outliers", []))


def capture_of(path: str | Path) -> CaptureMeta:
    """The ``capture`` metadata of a params.json (empty when it has none)."""
    try:
        return CaptureMeta.from_json(json.loads(Path(path).read_text()).get("capture"))
    except (OSError, ValueError, TypeError, AttributeError):
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


def save_params(fit: Fit, path: str | Path, effect_files: list[str] | None = None,
                auto=None, capture: CaptureMeta | None = None) -> None:
    """Write :func:`fit_to_dict` (with ``auto``'s steps, ``capture``'s context) as JSON."""
    Path(path).write_text(json.dumps(fit_to_dict(fit, effect_files, auto, capture),
                                     indent=1) + "\n")


def params_from_dict(
    data: dict, source: str = "<params>"
) -> tuple[ErrorModel, np.ndarray, np.ndarray]:
    """(error model, values, std) in internal units from a params mapping."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ParamsError(f"{source}: not a cellcal params file (format {FORMAT!r} expected)")
    for f in data.get("effect_files", []):
        load_effect_file(f)
    model = model_from_dict(data["model_definition"], f"{source}: model_definition")
    try:
        effects = parse_effects(",".join(data["effects"]), model)
    except EffectError as e:
        raise ParamsError(f"{source}: {e}") from None
    names = [str(row.get("name")) for row in data["parameters"]]
    for i, e in enumerate(effects):
        if hasattr(e, "with_parameter_names"):  # a table: its knots are in the names
            local = [n[len(e.prefix) + 1 :] for n in names if n.startswith(e.prefix + ".")]
            try:
                effects[i] = e.with_parameter_names(local)
            except EffectError as err:
                raise ParamsError(f"{source}: {err}") from None
    for e in effects:
        if e.label in data.get("smoothing", {}):
            e.smoothing = float(data["smoothing"][e.label])
    em = ErrorModel(model, effects)
    x = np.zeros(em.n_params)
    std = np.zeros(em.n_params)
    seen = set()
    for row in data["parameters"]:
        try:
            k = em.index(row["name"])
        except KeyError:
            raise ParamsError(f"{source}: unknown parameter {row['name']!r}") from None
        unit, factor = display_unit(em.units[k])
        if row.get("unit") != unit:
            raise ParamsError(
                f"{source}: parameter {row['name']}: unit {row.get('unit')!r}, expected {unit!r}"
            )
        x[k] = float(row["value"]) / factor
        std[k] = float(row["std"] or 0.0) / factor
        seen.add(row["name"])
    missing = [n for n in em.names if n not in seen]
    if missing:
        raise ParamsError(f"{source}: parameters missing: {', '.join(missing)}")
    return em, x, std


def load_params(path: str | Path) -> tuple[ErrorModel, np.ndarray, np.ndarray]:
    """Read a params.json written by :func:`save_params`."""
    path = Path(path)
    return params_from_dict(_read_json(path), str(path))


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise ParamsError(f"{path}: no such file") from None
    except json.JSONDecodeError as e:
        raise ParamsError(f"{path}: not valid JSON: {e}") from None
