"""The residual seen from each joint: small multiples against the joint's angle or gravity
torque (the diagnosis' view), and the before/after pair of every step of the automatic
diagnosis (:func:`fig_step`), captioned by what the added effect looks like.

Conventions shared by every panel: the joint-equivalent residual (µrad) is shown only
where the joint's lever arm to the target is at least
:data:`~presentation.residual_points.LEVER_ARM_MIN_MM` (the poses left out are counted in
the panel's title); the black line is the median in bins of x and breaks where a bin holds
too few poses; an overlay (orange) is always on the same basis as the cloud under it: the
change of the model's prediction, projected on the same joint column as the residual.
"""

from __future__ import annotations

import html
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from calibration.diagnosis.diagnosis import Diagnosis
from calibration.effects import JointEffect
from calibration.fit.identify import Fit
from calibration.model.gravity import gravity_torques
from calibration.workflow import joint_view

from .plot_base import (
    CANDIDATE_COLOUR,
    FIG_WIDTH,
    STAGE_COLOURS,
    Stage,
    binned_median,
    grid,
    mark_blunders,
    marker_size,
    robust_ylim,
    subsample,
)
from .residual_points import LEVER_ARM_MIN_MM, Points
from .thermal_figures import drift_what, drift_x

_DIR_COLOURS = {1: "#1f6fb4", -1: "#8e44ad", 0: "#9a9a9a"}
_DIR_MEDIAN = {1: "#0b3d66", -1: "#4a1f5c"}


# ---- the diagnosis' view ------------------------------------------------------------------
def torque_joints(points: Points) -> list[int]:
    """0-based joints whose gravity torque varies over the poses."""
    tau = points.torque_nm
    if tau is None:
        return []
    span = np.ptp(tau, axis=0)
    return [j for j in range(tau.shape[1]) if span[j] > 1e-6 * max(float(span.max()), 1e-300)]


def same_basis_overlay(diag: Diagnosis, stages: list[Stage], cloud: Points):
    """(0-based joint, (n,) rad) of the recommended joint effect: what the stage that adds
    it changes in the prediction of the cloud's poses, projected on the joint's column
    exactly as the residual is (so the cloud scatters around it by what that stage still
    leaves); None when no stage adds it."""
    best = diag.best
    if best is None or best.joint is None:
        return None
    for s in stages:
        em = s.fit.error_model
        if best.effect not in em.labels or s.fit is diag.fit:
            continue
        eff = em.effects[em.labels.index(best.effect)]
        if not isinstance(eff, JointEffect):
            return None
        rows = diag.fit.data
        d = s.fit.predict(rows) - diag.fit.predict(rows)
        return eff.joint - 1, joint_view(diag.fit, rows).project(d)[:, eff.joint - 1]
    return None


def _panel(ax, x, y, shown, *, colour=STAGE_COLOURS[1], colours=None, overlay=None,
           ylim=None, groups=None):
    """One joint's cloud (only ``shown`` poses), its binned median and an overlay; returns
    the y values drawn (for limits). ``groups`` (n,) of -1/0/+1 (approach directions)
    draws one median per direction instead of one over both bands."""
    idx = subsample(len(x))
    idx = idx[shown[idx]]
    s = marker_size(len(idx))
    c = colour if colours is None else colours[idx]
    ax.scatter(x[idx], y[idx], s=s, c=c, alpha=0.55, linewidths=0)
    if groups is None:
        bx, by = binned_median(x[shown], y[shown])
        ax.plot(bx, by, color="black", lw=1.4)
    else:
        for g in (1, -1):
            sel = shown & (groups == g)
            bx, by = binned_median(x[sel], y[sel])
            ax.plot(bx, by, color=_DIR_MEDIAN[g], lw=1.4)
    ys = [y[idx]]
    if overlay is not None:
        ax.scatter(x[idx], overlay[idx], s=s * 0.7, color=CANDIDATE_COLOUR, alpha=0.8,
                   linewidths=0)
        ys.append(overlay[idx])
    ax.axhline(0, color="#666", lw=0.6)
    ax.set_ylim(*(ylim or robust_ylim(*ys)))
    return ys


def _panel_title(joint: int, notes: list[str], shown: np.ndarray) -> str:
    """``joint 2`` and what the panel shows besides (on a second line when long)."""
    hidden = int((~shown).sum())
    notes = notes + ([f"{hidden} of {shown.size} masked"] if hidden else [])
    text = ", ".join(notes)
    if not text:
        return f"joint {joint}"
    return f"joint {joint} ({text})" if len(text) < 22 else f"joint {joint}\n{text}"


def _empty(ax, title: str) -> None:
    ax.set_title(title)
    ax.text(0.5, 0.5, f"lever arm < {LEVER_ARM_MIN_MM:g} mm\nat every pose:\nnot shown",
            transform=ax.transAxes, ha="center", va="center", color="#5b6470", fontsize=8.5)
    ax.set_xticks([])
    ax.set_yticks([])


def residual_grid(cloud: Points, joints: list[int], xs: np.ndarray, xs_blunders, xlabel: str,
                   overlay, blunders: Points | None, by_direction: int | None = None) -> Figure:
    fig, axes = grid(len(joints))
    for ax, j in zip(axes, joints, strict=False):
        shown = cloud.shown(j)
        notes = []
        if not shown.any():
            _empty(ax, f"joint {j + 1}")
            continue
        ov = overlay[1] * 1e6 if overlay is not None and overlay[0] == j else None
        colours = groups = None
        if by_direction == j and cloud.dirs is not None:
            groups = cloud.dirs[:, j]
            colours = np.array([_DIR_COLOURS.get(int(d), "#9a9a9a") for d in groups])
            notes.append("by direction")
        _panel(ax, xs[:, j], cloud.joint_rad[:, j] * 1e6, shown, overlay=ov, colours=colours,
               groups=groups)
        if ov is not None:
            notes.append("orange: the fix")
        if blunders is not None:
            b = blunders.shown(j)
            mark_blunders(ax, xs_blunders[b, j], blunders.joint_rad[b, j] * 1e6)
        ax.set_title(_panel_title(j + 1, notes, shown))
        ax.set_xlabel(xlabel.format(j=j + 1))
        ax.set_ylabel("equivalent joint error, µrad")
    return fig


def fig_joints(cloud: Points, overlay=None, blunders: Points | None = None,
               by_direction: int | None = None) -> Figure:
    """Each joint's equivalent residual against its angle; on joint ``by_direction``
    (0-based) coloured by approach direction, with a median for each (backlash)."""
    return residual_grid(cloud, list(range(cloud.q.shape[1])), np.degrees(cloud.q),
                          None if blunders is None else np.degrees(blunders.q),
                          "q{j}, deg", overlay, blunders, by_direction)


def fig_joint_temps(cloud: Points, blunders: Points | None = None) -> Figure:
    """Each joint's equivalent residual against its own temperature (``joint_tempJ``): a
    joint zero drifting as its drive warms is a slope (:mod:`presentation.thermal_figures`)."""
    return residual_grid(cloud, list(range(cloud.q.shape[1])), cloud.joint_temp,
                         None if blunders is None else blunders.joint_temp,
                         "joint {j} temperature, °C", None, blunders)


def fig_torque(cloud: Points, overlay=None, blunders: Points | None = None,
               by_direction: int | None = None) -> Figure:
    """Each joint's equivalent residual against its gravity torque (``by_direction`` as
    in :func:`fig_joints`)."""
    return residual_grid(cloud, torque_joints(cloud), cloud.torque_nm,
                          None if blunders is None else blunders.torque_nm,
                          "gravity torque on joint {j}, N·m", overlay, blunders, by_direction)


def masked_note(cloud: Points, joints: list[int] | None = None) -> str:
    """The caption's sentence on masked poses, empty when none is."""
    joints = range(cloud.q.shape[1]) if joints is None else joints
    parts = []
    for j in joints:
        hidden = int((~cloud.shown(j)).sum())
        if hidden:
            parts.append(f"joint {j + 1}: {hidden} of {cloud.n}")
    if not parts:
        return ""
    return (f" Masked: poses where the joint moves the target by less than "
            f"{LEVER_ARM_MIN_MM:g} mm per radian (its lever arm; nearer its axis a few µm "
            f"of residual read as thousands of µrad and mean nothing) are left out — "
            + ", ".join(parts) + ".")


# ---- what one step of the automatic diagnosis fixed ----------------------------------------------
@dataclass
class StepFigure:
    figure: Figure
    title: str
    caption: str  # HTML


def fig_step(before: Fit, after: Fit, effect: str, rows, number: int,
             explanation: str = "") -> StepFigure:
    """The residual before and after the step that added ``effect``, side by side, seen the
    way that effect shows (see the module docstring); ``rows`` are the poses shown."""
    em = after.error_model
    i = em.labels.index(effect)
    eff = em.effects[i]
    p = after.values[em.slices[i]]
    view = joint_view(before, rows)
    r_after = rows.tracker_p_smr - after.predict(rows)
    fig = Figure(figsize=(FIG_WIDTH, 3.0), layout="constrained")
    ax_b, ax_a = fig.subplots(1, 2, sharex=True)
    what = _what(eff, p, rows, before)
    if isinstance(eff, JointEffect):
        j = eff.joint - 1
        y_b = view.joint_residual_rad[:, j] * 1e6
        y_a = view.project(r_after)[:, j] * 1e6
        shown = view.lever_arm_mm[:, j] >= LEVER_ARM_MIN_MM
        x, xlabel = _step_x(eff, rows, before)
        colours = direction = None
        if eff.family == "backlash":
            direction = _directions(eff, rows, after)
            colours = np.array([_DIR_COLOURS.get(int(d), "#9a9a9a") for d in direction])
        ylabel = f"joint {j + 1} equivalent error, µrad"
        masked = int((~shown).sum())
    else:
        r_b = view.residuals
        d = r_b - r_after
        u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        y_b, y_a = np.sum(r_b * u, axis=1) * 1e3, np.sum(r_after * u, axis=1) * 1e3
        shown = np.ones(rows.n, bool)
        x, xlabel = _step_x(eff, rows, before)
        colours = direction = None
        masked = 0
        ylabel = "residual along the change, µm"
    if not shown.any():
        _empty(ax_b, "before")
        _empty(ax_a, "after")
    else:
        ylim = robust_ylim(y_b[shown], (y_b - y_a)[shown])
        _panel(ax_b, x, y_b, shown, colours=colours, overlay=y_b - y_a, ylim=ylim,
               groups=direction)
        _panel(ax_a, x, y_a, shown, colours=colours, colour=STAGE_COLOURS[2], ylim=ylim,
               groups=direction)
    rms_b, rms_a = before.calib["rms_mm"], after.calib["rms_mm"]
    ax_b.set_title(f"before: RMS {rms_b:.4f} mm (orange: what the step changes)")
    ax_a.set_title(f"after + {effect}: RMS {rms_a:.4f} mm")
    for ax in (ax_b, ax_a):
        ax.set_xlabel(xlabel)
    ax_b.set_ylabel(ylabel)
    if eff.family == "backlash":
        ax_a.legend(handles=[Line2D([], [], ls="", marker="o", color=_DIR_COLOURS[1],
                                    label="approached turning +"),
                             Line2D([], [], ls="", marker="o", color=_DIR_COLOURS[-1],
                                    label="approached turning −")],
                    loc="upper right", frameon=False, fontsize=7.5)
    caption = (
        f"<b>Step {number}: + <code>{html.escape(effect)}</code></b>"
        + (f" — {html.escape(explanation)}." if explanation else ".")
        + f" {what} Left: the residual of the model before the step"
        + (f", seen from joint {eff.joint}" if isinstance(eff, JointEffect) else
           ", along the direction the step moved each prediction")
        + "; orange: what the step changed in the model's prediction, on the same basis "
        "(the cloud scatters around it by what the new model still leaves). Right: the "
        "residual after the step, same scale. "
        + ("Dark lines: the median of each approach direction"
           if eff.family == "backlash" else "Black: the median")
        + " in bins of x, broken where a bin holds fewer than 5 poses."
        + (f" {masked} of {rows.n} poses are masked: there joint {eff.joint} moves the "
           f"target by less than {LEVER_ARM_MIN_MM:g} mm per radian." if masked else ""))
    return StepFigure(fig, f"Step {number}: what adding {effect} fixed", caption)


def _directions(eff, rows, fit: Fit) -> np.ndarray:
    """The approach direction (-1, 0, +1) of the backlash effect's joint, as it was fitted."""
    em = fit.error_model
    bound = em.bind(rows)
    return np.asarray(bound.states[em.labels.index(eff.label)][0], float)


def _step_x(eff, rows, fit: Fit) -> tuple[np.ndarray, str]:
    """What the effect is a function of: the x axis of its step figure."""
    fam = eff.family
    drift = drift_x(eff, rows)
    if drift is not None:
        return drift
    if fam == "compliance":
        em = fit.error_model
        tau = gravity_torques(em.model, em.bind(rows).nominal, rows.payload_kg)
        return tau[:, eff.joint - 1], f"gravity torque on joint {eff.joint}, N·m"
    if fam == "coupling":
        return np.degrees(rows.q[:, eff.joint - 2]), f"q{eff.joint - 1}, deg"
    if eff.joint is not None:
        return np.degrees(rows.q[:, eff.joint - 1]), f"q{eff.joint}, deg"
    if fam == "thermal" and rows.temp_c is not None:
        return rows.temp_c, "temperature, °C"
    if fam == "tracker_scale":
        return np.linalg.norm(rows.tracker_p_smr, axis=1), "distance from the tracker, mm"
    return np.arange(rows.n, dtype=float), "capture order"


def _what(eff, p: np.ndarray, rows, fit: Fit) -> str:
    """What the effect looks like in its step figure, with the fitted size (HTML)."""
    fam, j = eff.family, eff.joint
    drift = drift_what(eff, p)
    if drift is not None:
        return drift
    if fam == "compliance":
        c = float(p[0]) * 1e6
        return (f"Compliance shows as a straight line through zero against the gravity torque "
                f"on joint {j}: fitted c = {c:.3g} µrad/(N·m).")
    if fam == "backlash":
        b = float(p[0]) * 1e6
        return (f"Backlash does not show against the angle but as two bands, one per "
                f"approach direction (colours), ±b about the middle: fitted b = {b:.3g} µrad "
                f"(lost motion 2b = {2 * abs(b):.3g} µrad).")
    if fam == "harmonic":
        k = eff.order or 1
        amp = float(np.hypot(*p[:2])) * 1e6
        cycles = "one cycle" if k == 1 else f"{k} cycles"
        return (f"A periodic error shows as a sinusoid of order {k} ({cycles} per turn) "
                f"against joint {j}'s angle: fitted amplitude {amp:.3g} µrad.")
    if fam == "scale":
        return (f"A scale (gear ratio) error shows as a straight line through zero against "
                f"joint {j}'s angle: fitted {float(p[0]) * 1e6:.3g} µrad per rad.")
    if fam == "coupling":
        return (f"Coupling shows as a straight line against joint {j - 1}'s angle (the "
                f"x axis): fitted {float(p[0]) * 1e6:.3g} µrad per rad.")
    if fam == "table":
        return (f"An irregular error shows as a smooth curve over joint {j}'s angle (a "
                f"correction table, knots every {eff.spacing_deg:g}° from "
                f"{eff.knots_deg[0]:g}° to {eff.knots_deg[-1]:g}°).")
    if fam == "thermal":
        return ("Thermal growth shows as a straight line against the temperature: the links "
                "grow in proportion to it.")
    if fam == "tracker_scale":
        return ("A tracker scale error shows as a straight line through zero against the "
                "distance from the tracker.")
    return f"{html.escape(eff.summary or eff.label)}."
