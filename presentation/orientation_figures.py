"""The orientation residuals in the report, when the data have orientations (a 6-DoF
target): each calibration pose's orientation error (the angle of the turn from predicted
to measured, and its parts about the flange's x, y and z axes) and the joints ranked by
their share of the orientation residual.

The numbers are those ``calibrate`` and ``diagnose`` print
(:func:`calibration.diagnosis.orientation_view.orientation_view`); this module only draws them and
says what they mean.
"""

from __future__ import annotations

import html
from collections.abc import Callable

import numpy as np
from matplotlib.figure import Figure

from calibration.diagnosis.orientation_view import OrientationView, orientation_view
from calibration.fit.identify import Fit

from .plot_base import FIG_WIDTH, FLOOR_COLOUR, marker_size
from .summaries import orientation_floor_deg

#: colours of the flange's x, y, z parts
AXIS_COLOURS = ("#c0392b", "#2a9d3a", "#1f6fb4")


def fig_orientation(view: OrientationView, floor_deg: float | None) -> Figure:
    """Two panels: the orientation error per pose (angle and flange-axis parts, deg) and
    each joint's share of the orientation residual (bars, largest first)."""
    fig = Figure(figsize=(FIG_WIDTH, 2.8), layout="constrained")
    ax, bx = fig.subplots(1, 2, width_ratios=(2.2, 1))
    n = view.flange_deg.shape[0]
    i = np.arange(1, n + 1)
    s = marker_size(n)
    ax.scatter(i, np.linalg.norm(view.flange_deg, axis=1), s=s * 1.6, c="black",
               label="angle")
    for k, (name, colour) in enumerate(zip("xyz", AXIS_COLOURS, strict=True)):
        ax.scatter(i, view.flange_deg[:, k], s=s, c=colour, alpha=0.7,
                   label=f"flange {name}")
    if floor_deg:
        ax.axhline(floor_deg, color=FLOOR_COLOUR, ls="--", lw=1, label="noise floor")
    ax.axhline(0.0, color="#777777", lw=0.6)
    ax.set_xlabel("calibration pose (capture order)")
    ax.set_ylabel("orientation error, deg")
    ax.legend(loc="lower center", bbox_to_anchor=(0.5, 1.0), ncols=4, frameon=False)
    rows = view.ranked_joints()
    bx.bar([f"j{r['joint']}" for r in rows], [100 * r["share"] for r in rows],
           color="#1f6fb4")
    bx.set_ylabel("share of the orientation residual, %")
    bx.set_title("along each joint's axis")
    return fig


def orientation_section(figure: Callable[[str, Figure, str, str], str], fit: Fit) -> str:
    """The report's orientation section for ``fit`` (HTML; empty without orientations).
    ``figure(id, fig, title, caption)`` turns a figure into the page's block."""
    view = orientation_view(fit)
    if view is None:
        return ""
    floor = orientation_floor_deg(fit)
    how = ("fitted with the positions (full pose)" if view.fitted else
           "predicted by this position-only model (the target's mounting fitted)")
    x, y, z = view.axis_rms_deg
    top = view.ranked_joints()[0]
    caption = (
        f"Orientations of the 6-DoF target, {how}. Left: each calibration pose's "
        "orientation error — the angle of the turn from predicted to measured (black) and "
        "its parts about the flange's x, y and z axes — with the noise floor √3·σ "
        "(dashed) when σ is known. RMS about the flange's axes: "
        f"x {x:.4f}°, y {y:.4f}°, z {z:.4f}°. Tilts about x and y point at a wrist axis's "
        "alignment, a spin about z at a joint zero or the tool's mounting. Right: the share "
        "of the orientation residual along each joint's axis (largest first): joint "
        f"{top['joint']} carries {100 * top['share']:.0f} %, the place to look first.")
    return ("<h2>Where the orientations fail</h2>\n"
            + figure("fig-orientation", fig_orientation(view, floor),
                     "Orientation residual per pose and per joint", html.escape(caption)))
