"""A robot's calibration history: each parameter's value over a series of calibrations,
and the changes between consecutive calibrations that their uncertainties cannot explain.

A change from calibration i to i+1 is ``Δ = v[i+1] - v[i]`` with the combined standard
uncertainty ``σ = sqrt(σ[i]² + σ[i+1]²)`` (the two fits are independent: different
measurements); it is flagged when ``|Δ| > k σ`` (``k`` = 3 by default: a calibration
pair without any real change flags a given parameter about once in 370). A parameter
whose uncertainty is unknown in either calibration (held fixed, not identifiable) is
never flagged.

Parameters are matched by their params.json names; a calibration without a parameter
(another effect list) leaves a gap in its series. Changing the model's effects between
two calibrations can shift the parameters they share (each effect absorbs part of the
error): :attr:`CalibrationSummary.effects` says when that happened.

Input: params.json documents (docs/formats.md) in time order; values and uncertainties
in the units they carry (``deg``, ``mm``, ...).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: the default threshold, in combined standard uncertainties
DEFAULT_SIGMA = 3.0


@dataclass(frozen=True)
class CalibrationSummary:
    """What a calibration was: model, effects and its calibration/validation RMS (mm)."""

    model: str
    effects: tuple[str, ...]
    calib_rms_mm: float | None
    valid_rms_mm: float | None

    @classmethod
    def of(cls, params: dict) -> CalibrationSummary:
        stats = params.get("stats") or {}

        def rms(part: str) -> float | None:
            v = (stats.get(part) or {}).get("rms_mm")
            return None if v is None else float(v)

        return cls(str(params.get("model", "")), tuple(params.get("effects") or ()),
                   rms("calib"), rms("valid"))


@dataclass(frozen=True)
class ParameterHistory:
    """One parameter over the calibrations that have it.

    Attributes
    ----------
    name, unit : str
    index : (k,) int, the calibrations (positions in the series) that have it
    value, std : (k,) in ``unit``; ``std`` NaN where the fit could not determine it
    change, sigma : (k-1,) from each of these calibrations to the next, and the combined
        standard uncertainty (NaN when either std is unknown)
    flagged : (k-1,) bool, ``|change| > threshold * sigma``
    threshold : float
    """

    name: str
    unit: str
    index: np.ndarray
    value: np.ndarray
    std: np.ndarray
    change: np.ndarray
    sigma: np.ndarray
    flagged: np.ndarray
    threshold: float

    @property
    def z(self) -> np.ndarray:
        """|change| / sigma, (k-1,) (NaN where sigma is unknown)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.abs(self.change) / self.sigma

    @property
    def net_change(self) -> float:
        """Last value minus first (NaN with fewer than two)."""
        return float(self.value[-1] - self.value[0]) if self.value.size > 1 else math.nan

    @property
    def determined(self) -> bool:
        """True when some calibration determined the parameter (a finite std)."""
        return bool(np.isfinite(self.std).any())

    @property
    def net_z(self) -> float:
        """|last - first| in their combined standard uncertainty (NaN when unknown)."""
        if self.value.size < 2:
            return math.nan
        s = math.hypot(self.std[0], self.std[-1])
        return abs(self.net_change) / s if s > 0 else math.nan

    def decimals(self) -> int:
        """Decimals that show the smallest std with two significant digits (1 to 8; 4 for a
        parameter never determined)."""
        s = self.std[np.isfinite(self.std) & (self.std > 0)]
        if s.size == 0:
            return 4
        return int(np.clip(1 - math.floor(math.log10(float(s.min()))), 1, 8))

    def largest_step(self) -> int | None:
        """The position (in ``change``) of the change with the largest z, or None."""
        z = self.z
        if not np.isfinite(z).any():
            return None
        return int(np.nanargmax(z))


def parameter_histories(documents: list[dict], threshold: float = DEFAULT_SIGMA
                        ) -> list[ParameterHistory]:
    """Every parameter's history over ``documents`` (params.json dicts in time order), in
    the order the parameters first appear."""
    if not threshold > 0:
        raise ValueError(f"threshold must be positive, got {threshold}")
    series: dict[str, list] = {}
    units: dict[str, str] = {}
    for i, doc in enumerate(documents):
        for row in doc.get("parameters") or ():
            name = row["name"]
            units.setdefault(name, str(row.get("unit") or ""))
            std = row.get("std")
            if std is None or not row.get("identifiable", True):
                std = math.nan
            series.setdefault(name, []).append((i, float(row["value"]), float(std)))
    out = []
    for name, rows in series.items():
        a = np.array(rows, float).reshape(-1, 3)
        value, std = a[:, 1], a[:, 2]
        change = np.diff(value)
        sigma = np.hypot(std[:-1], std[1:])
        with np.errstate(invalid="ignore"):
            flagged = np.abs(change) > threshold * sigma  # NaN sigma: False
        out.append(ParameterHistory(name, units[name], a[:, 0].astype(int), value, std,
                                    change, sigma, flagged, float(threshold)))
    return out
