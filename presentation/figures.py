"""The report's figures: matplotlib figures on Agg canvases (never pyplot), one function
per figure, and :func:`png_bytes` that renders one deterministically (no metadata).

The figures show fits, a diagnosis and the stages of the story (:class:`Stage`); they
compute nothing the calibration core does not already give, beyond what a plot needs
(subsampling, binned medians, axis limits).
"""

from __future__ import annotations

import io
import math
from contextlib import AbstractContextManager
from dataclasses import dataclass

import matplotlib
import matplotlib.colors as mcolors
import numpy as np
import scipy.stats
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from calibration.diagnosis import ALPHA, Diagnosis
from calibration.effects import JointEffect
from calibration.identify import Fit, error_stats

# figures are drawn on Agg canvases (never pyplot): no display, no global figure registry
matplotlib.use("Agg")

#: at most this many points per scatter plot (a seeded random subsample beyond)
MAX_POINTS = 3000

STAGE_COLOURS = ("#9a9a9a", "#1f6fb4", "#2a9d3a", "#8e44ad", "#c0392b")
_CANDIDATE_COLOUR = "#d9480f"
_FLOOR_COLOUR = "#c0392b"
_RC = {
    "font.size": 9,
    "axes.titlesize": 9.5,
    "axes.labelsize": 9,
    "xtick.labelsize": 8,
    "ytick.labelsize": 8,
    "legend.fontsize": 8,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.grid": True,
    "grid.color": "#e3e3e3",
    "grid.linewidth": 0.6,
    "axes.axisbelow": True,
    "savefig.facecolor": "white",
}


@dataclass
class Stage:
    """One model in the story: a label, its fit and a colour."""

    label: str
    fit: Fit
    colour: str = "#1f6fb4"

    @property
    def effects(self) -> str:
        return ",".join(self.fit.error_model.labels)


def style() -> AbstractContextManager:
    """The figures' matplotlib style (a ``with`` context)."""
    return matplotlib.rc_context(_RC)


def png_bytes(fig: Figure, dpi: int) -> bytes:
    """The figure as PNG bytes (no metadata: the same figure gives the same bytes); the
    figure is cleared afterwards."""
    buf = io.BytesIO()
    FigureCanvasAgg(fig)
    try:
        fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
    finally:
        fig.clear()
    return buf.getvalue()


def _subsample(n: int, limit: int = MAX_POINTS) -> np.ndarray:
    if n <= limit:
        return np.arange(n)
    return np.sort(np.random.default_rng(0).choice(n, limit, replace=False))


def _marker_size(n: int) -> float:
    return float(np.clip(1800.0 / max(n, 1), 2.5, 9.0))


def _binned_median(x: np.ndarray, y: np.ndarray, bins: int = 16):
    """Median of y in equal-width bins of x (bins with fewer than 5 points dropped)."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 10 or np.ptp(x) == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.linspace(x.min(), x.max(), bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    cx, cy = [], []
    for b in range(bins):
        sel = idx == b
        if sel.sum() >= 5:
            cx.append(0.5 * (edges[b] + edges[b + 1]))
            cy.append(float(np.median(y[sel])))
    return np.array(cx), np.array(cy)


def _robust_ylim(*ys: np.ndarray) -> tuple[float, float]:
    """Limits that show the bulk of the points (2nd-98th percentile, padded), not outliers."""
    v = np.concatenate([np.ravel(y) for y in ys if y is not None and np.size(y)])
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -1.0, 1.0
    lo, hi = np.percentile(v, [2, 98])
    span = max(hi - lo, 1e-12)
    lo, hi = lo - 0.35 * span, hi + 0.35 * span
    return float(min(lo, -0.05 * span)), float(max(hi, 0.05 * span))


def _nice(v: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above v."""
    if not v > 0:
        return 1.0
    e = math.floor(math.log10(v))
    for m in (5, 2, 1):
        if m * 10**e <= v:
            return m * 10.0**e
    return 10.0**e


def _grid(n: int):
    cols = n if n <= 4 else 3
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(11, 2.7 * rows + 0.4), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes


def fig_story(stages: list[Stage], floor: float | None) -> Figure:
    fig = Figure(figsize=(8, 2.9), layout="constrained")
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
        handles.append(ax.axhline(floor, color=_FLOOR_COLOUR, ls="--", lw=1.2,
                                  label=f"noise floor {floor:.3f} mm"))
    ax.set_xticks(x, [f"{s.label}\n{_short(s.effects)}" for s in stages])
    ax.set_ylabel("RMS 3-D error, mm")
    ax.grid(axis="x", visible=False)
    ax.legend(handles=handles, loc="upper right", frameon=False)
    return fig


def _short(effects: str, width: int = 34) -> str:
    return effects if len(effects) <= width else effects[: width - 1] + "…"


def fig_hist(stages: list[Stage], floor: float | None) -> Figure:
    sets = [("calibration poses", lambda f: f.residuals)]
    if any(s.fit.valid_residuals is not None for s in stages):
        sets.append(("validation poses", lambda f: f.valid_residuals))
    fig = Figure(figsize=(11, 3.3), layout="constrained")
    axes = fig.subplots(1, len(sets), squeeze=False, sharex=True).ravel()
    errs_all = [np.linalg.norm(get(s.fit), axis=1) for _, get in sets for s in stages
                if get(s.fit) is not None]
    v = np.concatenate(errs_all)
    v = v[v > 0]
    lo = min(float(v.min()), floor / 3 if floor else np.inf)
    edges = np.geomspace(lo * 0.9, float(v.max()) * 1.1, 60)
    sigma = floor / math.sqrt(3.0) if floor else None
    for ax, (name, get) in zip(axes, sets, strict=True):
        n_max = 0
        for s in stages:
            r = get(s.fit)
            if r is None:
                continue
            e = np.linalg.norm(r, axis=1)
            st = error_stats(r)
            ax.hist(e, bins=edges, histtype="stepfilled", color=s.colour, alpha=0.25)
            ax.hist(e, bins=edges, histtype="step", color=s.colour, lw=1.4,
                    label=f"{s.label}: RMS {st['rms_mm']:.3f} mm")
            n_max = max(n_max, len(e))
        if sigma:
            cdf = scipy.stats.maxwell.cdf(edges, scale=sigma)
            expect = n_max * np.diff(cdf)
            ax.stairs(expect, edges, color="#222", ls="--", lw=1.1,
                      label="pure tracker noise (expected)")
            ax.axvline(floor, color=_FLOOR_COLOUR, lw=1.2, label=f"noise floor {floor:.3f} mm")
        ax.set_xscale("log")
        ax.set_ylim(0, ax.get_ylim()[1] * 1.45)
        ax.set_xlabel("3-D error per pose, mm (log scale)")
        ax.set_ylabel("poses per bin")
        ax.set_title(name)
        ax.legend(loc="upper left", frameon=True, framealpha=0.92, edgecolor="none")
    return fig


def fig_workspace(fit: Fit) -> tuple[Figure, float, float]:
    pts = [(fit.data.tracker_p_smr, fit.residuals, "o")]
    if fit.valid_data is not None and fit.valid_residuals is not None:
        pts.append((fit.valid_data.tracker_p_smr, fit.valid_residuals, "^"))
    xyz = np.vstack([p for p, _, _ in pts])
    res = np.vstack([r for _, r, _ in pts])
    mag = np.linalg.norm(res, axis=1)
    span = float(np.max(np.ptp(xyz, axis=0))) or 1.0
    p95 = float(np.percentile(mag, 95)) or 1e-3
    scale = _nice(0.07 * span / p95)
    ref = _nice(p95)
    norm = mcolors.Normalize(0.0, float(np.percentile(mag, 99)))
    fig = Figure(figsize=(11, 4.1), layout="constrained")
    axes = fig.subplots(1, 3)
    views = ((0, 1, "top view: X–Y"), (0, 2, "side view: X–Z"), (1, 2, "side view: Y–Z"))
    n_total = len(xyz)
    quivers = []
    for ax, (a, b, name) in zip(axes, views, strict=True):
        for p, r, marker in pts:
            idx = _subsample(len(p), max(MAX_POINTS * len(p) // n_total, 1))
            p, r = p[idx], r[idx]
            m = np.linalg.norm(r, axis=1)
            ax.scatter(p[:, a], p[:, b], s=_marker_size(n_total) * 0.6, marker=marker,
                       facecolors="none" if marker == "^" else "#bbbbbb",
                       edgecolors="#888888", linewidths=0.4, zorder=1)
            quivers.append(ax.quiver(p[:, a], p[:, b], r[:, a] * scale, r[:, b] * scale, m,
                             cmap="viridis", norm=norm, angles="xy", scale_units="xy",
                             scale=1.0, width=0.004, headwidth=3.5, headlength=4,
                             headaxislength=3.5, zorder=2))
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(name)
        ax.set_xlabel(f"{'XYZ'[a]}, mm")
        ax.set_ylabel(f"{'XYZ'[b]}, mm")
    axes[0].quiverkey(quivers[0], 0.04, 0.04, ref * scale, f"{ref:g} mm (arrows ×{scale:g})",
                      labelpos="E", coordinates="axes", color="#333",
                      fontproperties={"size": 8})
    fig.colorbar(quivers[-1], ax=axes, shrink=0.8, label="3-D error, mm", extend="max")
    return fig, scale, ref


def candidate_overlay(diag: Diagnosis, stages: list[Stage]):
    """(joint index, correction rad (n,)) of the recommended joint effect, as refitted in a
    later stage, on the diagnosis' calibration poses; None when not applicable."""
    best = diag.best
    if best is None or best.joint is None:
        return None
    for s in stages:
        em = s.fit.error_model
        if best.effect not in em.labels or s.fit.data.n != diag.where.q.shape[0]:
            continue
        i = em.labels.index(best.effect)
        eff = em.effects[i]
        if not isinstance(eff, JointEffect):
            return None
        bound = em.bind(s.fit.data)
        delta, _ = eff.delta(s.fit.values[em.slices[i]], bound.data, bound.states[i])
        return eff.joint - 1, np.asarray(delta, float)
    return None


def _fig_residual_grid(diag: Diagnosis, overlay, joints: list[int], x_full: np.ndarray,
                       xlabel: str, compliance_overlay: bool) -> Figure:
    """Small multiples: each joint's equivalent residual (µrad) against ``x_full[:, j]``,
    with a binned median, and the recommended joint effect's correction in orange on its
    joint (compliance only on the torque grid, every other joint effect only on the angle
    grid, where each reads as a clean curve)."""
    w = diag.where
    fig, axes = _grid(len(joints))
    idx = _subsample(len(w.q))
    s = _marker_size(len(idx))
    for ax, j in zip(axes, joints, strict=False):
        x = x_full[idx, j]
        y = w.joint_residual_rad[idx, j] * 1e6
        ax.scatter(x, y, s=s, color=STAGE_COLOURS[1], alpha=0.55, linewidths=0)
        bx, by = _binned_median(x_full[:, j], w.joint_residual_rad[:, j] * 1e6)
        ax.plot(bx, by, color="black", lw=1.4)
        ys = [y]
        title = f"joint {j + 1}"
        if (overlay is not None and overlay[0] == j
                and (diag.best.family == "compliance") == compliance_overlay):
            yc = overlay[1][idx] * 1e6
            ax.scatter(x, yc, s=s * 0.7, color=_CANDIDATE_COLOUR, alpha=0.8, linewidths=0)
            ys.append(yc)
            title += f"  (orange: {diag.best.effect})"
        ax.axhline(0, color="#666", lw=0.6)
        ax.set_ylim(*_robust_ylim(*ys))
        ax.set_title(title)
        ax.set_xlabel(xlabel.format(j=j + 1))
        ax.set_ylabel("equivalent joint error, µrad")
    return fig


def fig_joints(diag: Diagnosis, overlay) -> Figure:
    q = diag.where.q
    return _fig_residual_grid(diag, overlay, list(range(q.shape[1])), np.degrees(q),
                              "q{j}, deg", compliance_overlay=False)


def torque_joints(diag: Diagnosis) -> list[int]:
    """0-based joints whose gravity torque varies over the poses."""
    tau = diag.where.torque_nm
    if tau is None:
        return []
    span = np.ptp(tau, axis=0)
    return [j for j in range(tau.shape[1]) if span[j] > 1e-6 * max(float(span.max()), 1e-300)]


def fig_torque(diag: Diagnosis, overlay) -> Figure:
    return _fig_residual_grid(diag, overlay, torque_joints(diag), diag.where.torque_nm,
                              "gravity torque on joint {j}, N·m", compliance_overlay=True)


def fig_time(diag: Diagnosis) -> Figure:
    w = diag.where
    floor = diag.noise_floor_mm
    panels = [("order", w.order.astype(float), "capture order (calibration poses)")]
    if w.t_s is not None and np.ptp(w.t_s) > 0:
        t = w.t_s - w.t_s.min()
        unit, f = ("h", 3600.0) if np.ptp(t) > 3 * 3600 else ("min", 60.0)
        panels = [("time", t / f, f"time since the first pose, {unit}")]
    if w.temp_c is not None and np.ptp(w.temp_c) > 0:
        panels.append(("temperature", w.temp_c, "temperature, °C"))
    fig = Figure(figsize=(11, 3.0), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False).ravel()
    e = w.error_mm
    idx = _subsample(len(e))
    for ax, (_, x, label) in zip(axes, panels, strict=True):
        ax.scatter(x[idx], e[idx], s=_marker_size(len(idx)), color=STAGE_COLOURS[1],
                   alpha=0.6, linewidths=0)
        bx, by = _binned_median(x, e, bins=20)
        ax.plot(bx, by, color="black", lw=1.4, label="median")
        if floor:
            ax.axhline(floor, color=_FLOOR_COLOUR, ls="--", lw=1.1, label="noise floor")
        ax.set_ylim(0, float(np.percentile(e, 99.5)) * 1.15)
        ax.set_xlabel(label)
        ax.set_ylabel("3-D error, mm")
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
    fig, axes = _grid(len(joints))
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
            ax.vlines([orders[kk]], 0, frac[kk] * 100, color=_CANDIDATE_COLOUR, lw=2.4)
        if thr is not None:
            ax.axhline(thr * 100, color=_FLOOR_COLOUR, ls="--", lw=1.0,
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
