"""The thermal state in the report: what a drift effect is a function of (the x axis of
its step figure and the sentence that says what it looks like), and the residual seen
from each joint against that joint's temperature.

A robot drifts while it warms up (:mod:`calibration.effects.drift`): ``thermal_zero:J``
moves with joint J's temperature, ``thermal_growth`` with the joints' mean temperature,
``time_growthK`` and ``base_driftK`` with the time over the capture. The report plots each
against what it depends on, so a straight line (or a smooth curve in time) is the drift the
effect removes. Joint temperatures are the ``joint_temp1..N`` columns, the time ``t_s``.
"""

from __future__ import annotations

import html

import numpy as np

from .residual_points import Points

#: the drift families plotted against the time over the capture
TIME_FAMILIES = ("time_growth", "base_drift")


def varies(values: np.ndarray | None) -> bool:
    """Whether a column (or every column's union) changes over the poses."""
    return values is not None and len(values) > 0 and float(np.ptp(values)) > 0.0


def minutes(t_s: np.ndarray, t0: float | None = None) -> np.ndarray:
    """Seconds (epoch) as minutes since ``t0`` (default: the first of them)."""
    t_s = np.asarray(t_s, float)
    return (t_s - (float(t_s.min()) if t0 is None else t0)) / 60.0


def drift_x(eff, rows) -> tuple[np.ndarray, str] | None:
    """What a drift effect is a function of, for its step figure: (x of every row, axis
    label), or None for an effect that is no drift or data without the column."""
    fam = eff.family
    if fam == "thermal_zero" and rows.joint_temp is not None:
        return rows.joint_temp[:, eff.joint - 1], f"joint {eff.joint} temperature, °C"
    if fam == "thermal_growth" and rows.joint_temp is not None:
        return rows.joint_temp.mean(axis=1), "joints' mean temperature, °C"
    if fam in TIME_FAMILIES and rows.t_s is not None:
        return minutes(rows.t_s), "time since the first pose, min"
    return None


def drift_what(eff, p: np.ndarray) -> str | None:
    """What a drift effect looks like in its step figure, with the fitted size (HTML), or
    None for an effect that is no drift."""
    fam = eff.family
    if fam == "thermal_zero":
        return (f"A joint zero that drifts with temperature shows as a straight line against "
                f"joint {eff.joint}'s temperature: fitted {float(p[0]) * 1e6:.3g} µrad/K.")
    if fam == "thermal_growth":
        return ("Thermal growth of the arm shows as a straight line against the joints' mean "
                f"temperature: the links grow by {float(p[0]) * 1e6:.3g} ppm/K.")
    if fam == "time_growth":
        return ("Growth over the capture shows as a smooth curve against the time: the links "
                f"have grown by {float(np.sum(p)) * 1e6:.3g} ppm at the capture's end.")
    if fam == "base_drift":
        end = np.asarray(p, float).reshape(-1, 3).sum(axis=0)
        return ("A base that moves over the capture shows as a smooth curve against the "
                f"time: {float(np.linalg.norm(end)) * 1e3:.3g} µm at the capture's end "
                f"({html.escape(', '.join(f'{v * 1e3:.3g}' for v in end))} µm in x, y, z).")
    return None


def joint_temps_caption(cloud: Points) -> str:
    """The caption of the residual seen from each joint against its temperature
    (:func:`presentation.joint_figures.fig_joint_temps`), HTML."""
    lo, hi = float(np.min(cloud.joint_temp)), float(np.max(cloud.joint_temp))
    return ("For every joint, the correction of that joint's angle that would explain each "
            "pose's residual on its own (µrad), against that joint's temperature as the "
            f"controller reported it ({lo:.1f}–{hi:.1f} °C over the capture); the black line "
            "is the median in bins of temperature. A slope is a joint zero that moves as the "
            "drive warms (<code>thermal_zero:J</code>); every joint sloping alike is the arm "
            "growing (<code>thermal_growth</code>). A flat cloud around zero: the model "
            "already accounts for the warm-up, or there was none.")
