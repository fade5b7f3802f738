"""The JSON objects the command line prints for a result of the calibration core
(docs/formats.md §4): :func:`fit_summary` (a fit), :func:`calibration_summary`
(``calibrate --json``: the fit, its parameters, the baseline, a Monte-Carlo check),
:func:`diagnosis_summary` (``diagnose --json``) and :func:`zero_summary`
(``zero --json``). Numbers rounded and units in degrees where a person reads them."""

from __future__ import annotations

import math

import numpy as np

from calibration.diagnosis.diagnosis import Diagnosis
from calibration.diagnosis.orientation_blindness import Blindness
from calibration.diagnosis.orientation_view import orientation_view
from calibration.exports.params_io import params_by_name, solver_summary
from calibration.fit.envelope import Envelope, split_stats
from calibration.fit.identify import Fit
from calibration.fit.model_check import ModelCheck
from calibration.fit.uncertainty import MonteCarlo, correlations
from calibration.zero_point import ZeroResult, assess

#: the orientation keys of ``calib`` and ``valid`` (docs/formats.md §4), with orientations
ORIENTATION_KEYS = ("orientation_rms_deg", "orientation_mean_deg", "orientation_max_deg")


def fit_summary(fit: Fit) -> dict:
    """The ``calibrate --json`` object (docs/formats.md §4), without file names."""
    out = {
        "model": fit.error_model.model.name,
        "effects": fit.error_model.labels,
        "solver": fit.solver,
        "n_params": fit.error_model.n_params,
        "n_identifiable": fit.identifiability.n_identifiable,
        "unidentifiable": fit.identifiability.unidentifiable,
        "calib": {k: fit.calib[k] for k in ("n", "rms_mm", "mean_mm", "max_mm", "p95_mm")
                  + ORIENTATION_KEYS if k in fit.calib},
    }
    if fit.valid is not None:
        out["valid"] = {
            k: fit.valid[k] for k in ("n", "rms_mm", "mean_mm", "max_mm", "p95_mm")
            + ORIENTATION_KEYS if k in fit.valid
        }
    orientation = orientation_summary(fit)
    if orientation is not None:
        out["orientation"] = orientation
    out.update(
        {
            "noise_floor_mm": fit.noise_floor_mm,
            "converged": fit.converged,
            "reason": fit.reason,
            "iterations": fit.iterations,
            "condition_number": fit.identifiability.condition_number,
            "observability_index": fit.identifiability.observability_index,
            "solve_s": fit.solve_s,
        }
    )
    return out


def envelope_summary(fit: Fit) -> dict:
    """``envelope`` (the ranges the calibration rows covered, as params.json records them)
    and, with validation rows, ``valid_inside`` and ``valid_outside`` (their statistics
    inside and beyond it; ``valid_outside.by_quantity``: poses beyond it per quantity)."""
    env = Envelope.of_fit(fit)
    out: dict = {"envelope": env.to_json()}
    if fit.valid is not None:
        split = split_stats(env, fit.valid_data, fit.valid_residuals)
        out["valid_inside"], out["valid_outside"] = split["inside"], split["outside"]
    return out


def calibration_summary(fit: Fit, baseline: Fit, *, params_file: str | None,
                        mc: MonteCarlo | None = None, ridge_plot: str | None = None,
                        blindness: Blindness | None = None) -> dict:
    """The ``calibrate --json`` object (docs/formats.md §4): :func:`fit_summary`, the
    parameters by name, the blunders, the uncalibrated ``baseline``, the strongest
    correlations, the solver's details, a Monte-Carlo check (``mc``) and, when a
    position-only fit leaves the tool's orientation weakly determined, ``blindness``."""
    out = fit_summary(fit)
    out["params_file"] = params_file
    out["params"] = params_by_name(fit)
    out["weakly_identified"] = fit.weakly_identified()
    out["outliers"] = fit.outliers.to_json() if fit.outliers else []
    if fit.outliers:
        out["outlier_check"] = fit.outliers.check_json()
    out["uncalibrated"] = {"calib": baseline.calib, "valid": baseline.valid}
    out.update(envelope_summary(fit))
    out["strongest_correlations"] = correlations(fit)["strongest"]
    info = solver_summary(fit)
    if info:
        out["solver_info"] = info
    if mc is not None:
        out["monte_carlo"] = monte_carlo_summary(mc, fit)
    if ridge_plot:
        out["ridge_plot"] = ridge_plot
    if blindness is not None and blindness.blind:
        out["orientation_blindness"] = blindness.to_json()
    return out


def orientation_summary(fit: Fit) -> dict | None:
    """The ``orientation`` object of ``calibrate --json``: the residual per flange axis
    and per joint (:func:`calibration.diagnosis.orientation_view.orientation_view`) and the noise
    floor; None when the data have no orientations."""
    view = orientation_view(fit)
    if view is None:
        return None
    return {**view.to_json(), "noise_floor_deg": orientation_floor_deg(fit)}


def diagnosis_summary(diag: Diagnosis, given: ModelCheck | None = None,
                      params: str | None = None) -> dict:
    """The ``diagnose --json`` object: :meth:`Diagnosis.to_json` and, when the data have
    orientations, an ``orientation`` object beside it: :func:`orientation_summary` with
    the flange axes ranked (largest RMS first) and the error rows of the calibration and
    validation poses (rms, mean, max, deg). With ``--params``, ``given``: the given
    model's own error on the calibration poses, nothing refitted (``rms_mm`` is then of a
    refit: ``refitted`` true)."""
    out = diag.to_json()
    if given is not None:
        out["given"] = {"params_file": params, **given.stats}
        out["refitted"] = True
    orientation = orientation_summary(diag.fit)
    if orientation is not None:
        axes = sorted(orientation["axis_rms_deg"].items(), key=lambda kv: -kv[1])
        orientation["axes"] = [{"axis": a, "rms_deg": v} for a, v in axes]
        for part in ("calib", "valid"):
            s = getattr(diag.fit, part)
            if s and s.get("orientation_rms_deg") is not None:
                orientation[part] = {"n": s["n"], **{k: s[k] for k in ORIENTATION_KEYS}}
        out["orientation"] = orientation
    return out


def orientation_floor_deg(fit: Fit) -> float | None:
    """sqrt(3) times the data's orientation uncertainty (deg), None when not given."""
    s = fit.data.sigma_deg
    return None if s is None else float(np.sqrt(3.0 * np.mean(np.square(s))))


def monte_carlo_summary(mc: MonteCarlo, fit: Fit) -> dict:
    """The ``monte_carlo`` object of ``calibrate --json``."""
    return {
        "n": int(mc.samples.shape[0]), "sigma_mm": mc.sigma_mm, "n_failed": mc.n_failed,
        "parameters": mc.rows(fit),
        "position_uncertainty_mm": {k: mc.position[k] for k in ("mean_mm", "max_mm")},
        "position_uncertainty_mc_mm": {k: mc.position_mc[k] for k in ("mean_mm", "max_mm")},
    }


def zero_summary(result: ZeroResult, model_name: str, n_poses: int, *, tolerance_deg: float,
            sigma_mm: float, measured: bool = False) -> dict:
    """The ``zero --json`` object (docs/formats.md §4) plus extra keys."""
    status, reasons = assess(result, tolerance_deg=tolerance_deg, sigma_mm=sigma_mm,
                             measured=measured)
    det = result.determined
    off = [round(math.degrees(v), 6) if d else None
           for v, d in zip(result.offsets, det, strict=True)]
    std = [round(math.degrees(s), 6) if d and np.isfinite(s) else None
           for s, d in zip(result.std, det, strict=True)]
    changed = [f"j{j + 1}" for j in range(len(det))
               if det[j] and abs(math.degrees(result.offsets[j])) > tolerance_deg]
    return {
        "model": model_name,
        "n_poses": n_poses,
        "offsets_deg": off,
        "std_deg": std,
        "unidentifiable": result.unidentifiable,
        "tool_mm": [round(float(v), 6) for v in result.tool],
        "target_mm": [round(float(v), 6) for v in result.target],
        "rms_mm": round(result.rms_mm, 6),
        "status": status,
        "method": result.method,
        "changed": changed,
        "tolerance_deg": tolerance_deg,
        "reasons": reasons,
        "outliers": result.outliers,
        "converged": result.converged,
        "reason": result.reason,
        "iterations": result.iterations,
        "solve_s": round(result.solve_s, 6),
        "offsets_rad": [float(v) for v in result.offsets],
    }
