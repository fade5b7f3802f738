"""The report's figures of the whole story: the RMS stage by stage (:func:`fig_story`) and
step by step (:func:`fig_steps`), the error histograms, the residual vectors in the
workspace, the error over the capture and the harmonic periodogram. The residual seen from
each joint is :mod:`presentation.joint_figures`; what they share is
:mod:`presentation.plot_base`.

The figures show fits, a diagnosis and the stages of the story (:class:`Stage`); they
compute nothing the calibration core does not already give, beyond what a plot needs
(subsampling, binned medians, axis limits).
"""

from __future__ import annotations

import math

import matplotlib.colors as mcolors
import numpy as np
import scipy.stats
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from calibration.diagnosis.diagnosis import ALPHA, Diagnosis
from calibration.fit.identify import Fit

from .plot_base import (
    BLUNDER_COLOUR,
    CANDIDATE_COLOUR,
    FIG_WIDTH,
    FLOOR_COLOUR,
    MAX_POINTS,
    STAGE_COLOURS,
    Stage,
    binned_median,
    grid,
    mark_blunders,
    marker_size,
    nice,
    png_bytes,
    style,
    subsample,
)
from .residual_points import Points
from .thermal_figures import varies

__all__ = ["MAX_POINTS", "STAGE_COLOURS", "Stage", "fig_hist", "fig_periodogram", "fig_steps",
           "fig_story", "fig_time", "fig_workspace", "png_bytes", "style"]

_subsample = subsample  # the name the tests know


def fig_story(stages: list[Stage], floor: float | None) -> Figure:
    fig = Figure(figsize=(FIG_WIDTH, 2.9), layout="constrained")
    ax = fig.subplots()
    x = np.arange(len(stages))
    w = 0.36
    values = []
    for k, s in enumerate(stages):
        for dx, st, hatch in ((-w / 2, s.fit.calib, None), (w / 2, s.fit.valid, "///")):
            if st is None or st["rms_mm"] is None:
                continue
            v = st["rms_mm"]
            values.append(v)
            ax.bar(x[k] + dx, v, w * 0.95, color=s.colour if hatch is None else "white",
                   edgecolor=s.colour, hatch=hatch, linewidth=1.2)
            ax.annotate(f"{v:.3f}", (x[k] + dx, v), xytext=(0, 2), textcoords="offset points",
                        ha="center", va="bottom", fontsize=8)
    ax.set_yscale("log")
    lo = min(values + ([floor] if floor else []))
    ax.set_ylim(lo / 2.5, max(values) * 2.5)
    handles = [Patch(facecolor="#777", edgecolor="#777", label="calibration poses"),
               Patch(facecolor="white", edgecolor="#777", hatch="///", label="validation poses")]
    if floor:
        handles.append(ax.axhline(floor, color=FLOOR_COLOUR, ls="--", lw=1.2,
                                  label=f"noise floor {floor:.3f} mm"))
    ax.set_xticks(x, [f"{s.label}\n{_short(s.effects)}" for s in stages])
    ax.set_ylabel("RMS 3-D error, mm")
    ax.grid(axis="x", visible=False)
    ax.legend(handles=handles, loc="upper right", frameon=False)
    return fig


def _short(effects: str, width: int = 34) -> str:
    return effects if len(effects) <= width else effects[: width - 1] + "…"


def fig_hist(stages: list[Stage], floor: float | None) -> Figure:
    """Histograms of the per-pose error of every stage (calibration and validation poses);
    one legend under both panels."""
    sets = [("calibration poses", lambda f: f.residuals)]
    if any(s.fit.valid_residuals is not None for s in stages):
        sets.append(("validation poses", lambda f: f.valid_residuals))
    fig = Figure(figsize=(FIG_WIDTH, 3.5), layout="constrained")
    axes = fig.subplots(1, len(sets), squeeze=False, sharex=True).ravel()
    errs_all = [np.linalg.norm(get(s.fit), axis=1) for _, get in sets for s in stages
                if get(s.fit) is not None]
    v = np.concatenate(errs_all)
    v = v[v > 0]
    lo = min(float(v.min()), floor / 3 if floor else np.inf)
    edges = np.geomspace(lo * 0.9, float(v.max()) * 1.1, 60)
    sigma = floor / math.sqrt(3.0) if floor else None
    handles = {}
    for ax, (name, get) in zip(axes, sets, strict=True):
        n_max = 0
        for s in stages:
            r = get(s.fit)
            if r is None:
                continue
            e = np.linalg.norm(r, axis=1)
            ax.hist(e, bins=edges, histtype="stepfilled", color=s.colour, alpha=0.25)
            h = ax.hist(e, bins=edges, histtype="step", color=s.colour, lw=1.4)[2][0]
            handles.setdefault(s.label, h)
            n_max = max(n_max, len(e))
        if sigma:
            cdf = scipy.stats.maxwell.cdf(edges, scale=sigma)
            expect = n_max * np.diff(cdf)
            handles.setdefault("pure tracker noise (expected)",
                               ax.stairs(expect, edges, color="#222", ls="--", lw=1.1))
            handles.setdefault(f"noise floor {floor:.3f} mm",
                               ax.axvline(floor, color=FLOOR_COLOUR, lw=1.2))
        ax.set_xscale("log")
        ax.set_xlabel("3-D error per pose, mm (log scale)")
        ax.set_ylabel("poses per bin")
        ax.set_title(name)
    fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncols=2,
               frameon=False)
    return fig


def fig_workspace(fit: Fit, blunders: Points | None = None) -> tuple[Figure, float, float]:
    """Residual arrows at the measured points, three views; blunders as orange crosses."""
    pts = [(fit.data.tracker_p_smr, fit.residuals, "o")]
    if fit.valid_data is not None and fit.valid_residuals is not None:
        pts.append((fit.valid_data.tracker_p_smr, fit.valid_residuals, "^"))
    xyz = np.vstack([p for p, _, _ in pts])
    res = np.vstack([r for _, r, _ in pts])
    mag = np.linalg.norm(res, axis=1)
    span = float(np.max(np.ptp(xyz, axis=0))) or 1.0
    p95 = float(np.percentile(mag, 95)) or 1e-3
    scale = nice(0.07 * span / p95)
    ref = nice(p95)
    norm = mcolors.Normalize(0.0, float(np.percentile(mag, 99)))
    fig = Figure(figsize=(FIG_WIDTH, 3.4), layout="constrained")
    axes = fig.subplots(1, 3)
    views = ((0, 1, "top view: X–Y"), (0, 2, "side view: X–Z"), (1, 2, "side view: Y–Z"))
    n_total = len(xyz)
    quivers = []
    for ax, (a, b, name) in zip(axes, views, strict=True):
        for p, r, marker in pts:
            idx = subsample(len(p), max(MAX_POINTS * len(p) // n_total, 1))
            p, r = p[idx], r[idx]
            m = np.linalg.norm(r, axis=1)
            ax.scatter(p[:, a], p[:, b], s=marker_size(n_total) * 0.5, marker=marker,
                       facecolors="none" if marker == "^" else "#bbbbbb",
                       edgecolors="#888888", linewidths=0.4, zorder=1)
            quivers.append(ax.quiver(p[:, a], p[:, b], r[:, a] * scale, r[:, b] * scale, m,
                             cmap="viridis", norm=norm, angles="xy", scale_units="xy",
                             scale=1.0, width=0.005, headwidth=3.5, headlength=4,
                             headaxislength=3.5, zorder=2))
        if blunders is not None and blunders.n:
            ax.scatter(blunders.xyz[:, a], blunders.xyz[:, b], marker="X", s=50,
                       color=BLUNDER_COLOUR, edgecolors="white", linewidths=0.6, zorder=5,
                       label="left out (blunder)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(name)
        ax.set_xlabel(f"{'XYZ'[a]}, mm")
        ax.set_ylabel(f"{'XYZ'[b]}, mm")
        ax.tick_params(axis="x", labelrotation=30)
    if blunders is not None and blunders.n:
        axes[-1].legend(loc="upper right", frameon=False, fontsize=7.5)
    axes[0].quiverkey(quivers[0], 0.04, 0.04, ref * scale, f"{ref:g} mm (×{scale:g})",
                      labelpos="E", coordinates="axes", color="#333",
                      fontproperties={"size": 7.5})
    fig.colorbar(quivers[-1], ax=axes, shrink=0.8, label="3-D error, mm", extend="max")
    return fig, scale, ref


def time_axes(cloud: Points):
    """The panels of :func:`fig_time`: (name, x of a Points, label) for capture order or
    time, the (air) temperature and the joints' mean temperature when they vary."""
    def order(p):
        return p.position

    panels = [("order", order, "capture order (calibration poses)")]
    if cloud.t_s is not None and np.ptp(cloud.t_s) > 0:
        t0 = float(cloud.t_s.min())
        unit, f = ("h", 3600.0) if np.ptp(cloud.t_s) > 3 * 3600 else ("min", 60.0)
        panels = [("time", lambda p: (p.t_s - t0) / f, f"time since the first pose, {unit}")]
    if cloud.temp_c is not None and np.ptp(cloud.temp_c) > 0:
        panels.append(("temperature", lambda p: p.temp_c, "temperature, °C"))
    if varies(cloud.joint_temp):
        panels.append(("joint temperature", lambda p: None if p.joint_temp is None else
                       p.joint_temp.mean(axis=1), "joints' mean temperature, °C"))
    return panels


def fig_time(cloud: Points, floor: float | None, blunders: Points | None = None) -> Figure:
    """Each pose's 3-D error in capture order (or time) and against the temperature."""
    panels = time_axes(cloud)
    fig = Figure(figsize=(FIG_WIDTH, 2.8), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False).ravel()
    e = cloud.error_mm
    idx = subsample(len(e))
    for ax, (_, get, label) in zip(axes, panels, strict=True):
        x = np.asarray(get(cloud), float)
        ax.scatter(x[idx], e[idx], s=marker_size(len(idx)), color=STAGE_COLOURS[1],
                   alpha=0.6, linewidths=0)
        bx, by = binned_median(x, e, bins=20)
        ax.plot(bx, by, color="black", lw=1.4, label="median")
        if floor:
            ax.axhline(floor, color=FLOOR_COLOUR, ls="--", lw=1.1, label="noise floor")
        ax.set_ylim(0, float(np.percentile(e, 99.5)) * 1.15)
        if blunders is not None and blunders.n and get(blunders) is not None:
            mark_blunders(ax, get(blunders), blunders.error_mm, "left out (blunder)")
        ax.set_xlabel(label)
        ax.set_ylabel("3-D error, mm")
        ax.legend(loc="upper right", frameon=False)
    return fig


def fig_steps(labels: list[str], calib: list[float], heldout: list[float | None],
              floor: float | None, heldout_label: str = "held-out poses") -> Figure:
    """The RMS after every step: calibration (solid) and held-out (dashed), log scale, the
    noise floor as a red line."""
    n = len(labels)
    fig = Figure(figsize=(FIG_WIDTH, 3.1 + (0.35 if n > 5 else 0.0)), layout="constrained")
    ax = fig.subplots()
    x = np.arange(n)
    ax.plot(x, calib, "-o", color=STAGE_COLOURS[1], lw=1.6, ms=5, label="calibration poses")
    h = np.array([np.nan if v is None else v for v in heldout], float)
    if np.isfinite(h).any():
        ax.plot(x, h, "--o", color=STAGE_COLOURS[2], lw=1.6, ms=5, mfc="white",
                label=heldout_label)
    for k in range(n):
        ax.annotate(f"{calib[k]:.3f}", (x[k], calib[k]), xytext=(0, -11),
                    textcoords="offset points", ha="center", fontsize=7, color=STAGE_COLOURS[1])
        if np.isfinite(h[k]):
            ax.annotate(f"{h[k]:.3f}", (x[k], h[k]), xytext=(0, 5), textcoords="offset points",
                        ha="center", fontsize=7, color=STAGE_COLOURS[2])
    values = [v for v in [*calib, *h] if np.isfinite(v) and v > 0]
    if floor:
        ax.axhline(floor, color=FLOOR_COLOUR, ls="--", lw=1.2, label=f"noise floor {floor:.3f} mm")
        values.append(floor)
    ax.set_yscale("log")
    ax.set_ylim(min(values) / 1.8, max(values) * 1.8)
    ax.set_xticks(x, labels, rotation=30 if n > 4 else 0, ha="right" if n > 4 else "center")
    ax.set_xlim(-0.5, n - 0.5)
    ax.set_ylabel("RMS 3-D error, mm")
    ax.grid(axis="x", visible=False)
    ax.legend(loc="upper right", frameon=False)
    return fig


def _harmonic_threshold(diag: Diagnosis) -> float | None:
    """Explained fraction a 2-parameter harmonic needs to be significant."""
    fit = diag.fit
    dof = 3 * fit.data.n - int(fit.free.sum()) - 2
    if dof < 1 or diag.at_floor:
        return None
    F = float(scipy.stats.f.isf(ALPHA / max(diag.n_screened, 1), 2, dof))
    if not math.isfinite(F):
        return None
    g = 2.0 * F / dof
    return g / (1.0 + g)


def fig_periodogram(diag: Diagnosis) -> Figure:
    per = diag.where.periodogram
    joints = sorted(per)
    fig, axes = grid(len(joints))
    thr = _harmonic_threshold(diag)
    best = diag.best
    for ax, j in zip(axes, joints, strict=False):
        orders, frac = per[j]
        ax.vlines(orders, 0, frac * 100, color=STAGE_COLOURS[1], lw=1.6)
        k = int(np.argmax(frac))
        ax.annotate(f"K={orders[k]}", (orders[k], frac[k] * 100), xytext=(3, 3),
                    textcoords="offset points", ha="left" if orders[k] < 8 else "center",
                    fontsize=7.5)
        if best is not None and best.family == "harmonic" and best.joint == j:
            kk = int(np.flatnonzero(orders == best.order)[0])
            ax.vlines([orders[kk]], 0, frac[kk] * 100, color=CANDIDATE_COLOUR, lw=2.4)
        if thr is not None:
            ax.axhline(thr * 100, color=FLOOR_COLOUR, ls="--", lw=1.0,
                       label="significance threshold")
            if j == joints[0]:
                ax.legend(loc="upper right", frameon=False)
        ax.set_xlim(0, max(orders) + 1)
        top = max(float(np.max(frac)), thr or 0.0) * 100 * 1.22
        ax.set_ylim(0, top if top > 0 else 1.0)
        ax.set_title(f"joint {j}")
        ax.set_xlabel("harmonic order K (cycles per turn)")
        ax.set_ylabel("explains, %")
    return fig
