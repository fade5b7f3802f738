"""What every report figure shares: the style, the stages' colours, deterministic PNGs, and
the small things a plot needs (subsampling, binned medians that break over empty bins,
axis limits that show the bulk, blunder markers).

Figures are drawn on Agg canvases (never pyplot): no display, no global figure registry.
"""

from __future__ import annotations

import io
import math
from contextlib import AbstractContextManager
from dataclasses import dataclass

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from calibration.fit.identify import Fit

matplotlib.use("Agg")

#: at most this many points per scatter plot (a seeded random subsample beyond)
MAX_POINTS = 3000
#: width of every figure, inches: at the report's 100 dpi, about what an 800 px wide window
#: shows, so the figures are read at their natural size there and never blown up
FIG_WIDTH = 8.0

STAGE_COLOURS = ("#9a9a9a", "#1f6fb4", "#2a9d3a", "#8e44ad", "#c0392b")
CANDIDATE_COLOUR = "#d9480f"
FLOOR_COLOUR = "#c0392b"
BLUNDER_COLOUR = "#e8590c"
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


def subsample(n: int, limit: int = MAX_POINTS) -> np.ndarray:
    """Indices of at most ``limit`` of ``n`` points (seeded, sorted)."""
    if n <= limit:
        return np.arange(n)
    return np.sort(np.random.default_rng(0).choice(n, limit, replace=False))


def marker_size(n: int) -> float:
    return float(np.clip(1800.0 / max(n, 1), 2.5, 9.0))


#: a bin of a binned median needs this many points, else the median line breaks there
MIN_PER_BIN = 5


def binned_median(x: np.ndarray, y: np.ndarray, bins: int = 16):
    """Median of y in equal-width bins of x, at the bins' centres.

    A bin with fewer than :data:`MIN_PER_BIN` points has a NaN median, so that a line
    drawn through the result breaks there instead of bridging an empty stretch."""
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if x.size < 2 * MIN_PER_BIN or np.ptp(x) == 0:
        return np.zeros(0), np.zeros(0)
    edges = np.linspace(x.min(), x.max(), bins + 1)
    idx = np.clip(np.digitize(x, edges) - 1, 0, bins - 1)
    cx = 0.5 * (edges[:-1] + edges[1:])
    cy = np.full(bins, np.nan)
    for b in range(bins):
        sel = idx == b
        if sel.sum() >= MIN_PER_BIN:
            cy[b] = float(np.median(y[sel]))
    return cx, cy


def robust_ylim(*ys: np.ndarray) -> tuple[float, float]:
    """Limits that show the bulk of the points (2nd-98th percentile, padded), not outliers."""
    parts = [np.ravel(y) for y in ys if y is not None and np.size(y)]
    v = np.concatenate(parts) if parts else np.zeros(0)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return -1.0, 1.0
    lo, hi = np.percentile(v, [2, 98])
    span = max(hi - lo, 1e-12)
    lo, hi = lo - 0.35 * span, hi + 0.35 * span
    return float(min(lo, -0.05 * span)), float(max(hi, 0.05 * span))


def nice(v: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above v."""
    if not v > 0:
        return 1.0
    e = math.floor(math.log10(v))
    for m in (5, 2, 1):
        if m * 10**e <= v:
            return m * 10.0**e
    return 10.0**e


def grid(n: int, cols: int | None = None, height: float = 2.5):
    """A figure of ``n`` small panels, :data:`FIG_WIDTH` wide (3 per row beyond 3)."""
    cols = cols or (n if n <= 3 else 3)
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(FIG_WIDTH, height * rows + 0.3), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax in axes[n:]:
        ax.set_visible(False)
    return fig, axes


def mark_blunders(ax, x: np.ndarray, y: np.ndarray, label: str | None = None) -> None:
    """Blunders as orange crosses; one beyond the y range sits on its edge as a triangle
    pointing the way it went."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if not x.size:
        return
    lo, hi = ax.get_ylim()
    inside = (y >= lo) & (y <= hi)
    kw = {"color": BLUNDER_COLOUR, "zorder": 5, "clip_on": False}
    pad = 0.02 * (hi - lo)
    up, down = y > hi, y < lo
    groups = [(inside, y, "X"), (up, np.full(x.size, hi - pad), "^"),
              (down, np.full(x.size, lo + pad), "v")]
    for sel, yy, marker in groups:
        if sel.any():
            ax.scatter(x[sel], yy[sel], marker=marker, s=46 if marker == "X" else 40,
                       linewidths=0.6 if marker == "X" else 0,
                       edgecolors="white" if marker == "X" else None, label=label, **kw)
            label = None
    ax.set_ylim(lo, hi)
