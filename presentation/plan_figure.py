"""A capture plan as the tracker sees it: the robot, the planned SMR positions in their
order, the tracker and the beams (``cellcal capture ROUTINE --plot plan.png``).

Two views of the robot base frame: a 3-D view and the top view (x-y). Each planned SMR
position is a dot (calibration, validation, spare), its opening a short line, its beam
a faint line to the tracker; points the tracker would not see (with the cell's margins)
are red crosses. The robot's link capsules are drawn at the first target, the visiting
order as a thin line, the cell's fixtures as outlines. Computes nothing beyond
:mod:`calibration.cell.visibility`.
"""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from calibration.cell.visibility import assess, link_capsules, smr_pose

matplotlib.use("Agg")

_SET_STYLE = {"calib": ("#1f6fb4", "calibration"), "valid": ("#2a9d3a", "validation"),
              "spare": ("#9a9a9a", "spare")}


def _box_edges(box) -> list[np.ndarray]:
    R, c = box.rotation(), np.asarray(box.centre, float)
    h = np.asarray(box.size, float) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    P = c + (corners * h) @ R.T
    return [P[[i, j]] for i in range(8) for j in range(i + 1, 8)
            if np.sum(corners[i] != corners[j]) == 1]


def _cylinder_edges(cyl, n: int = 24) -> list[np.ndarray]:
    s0, s1 = np.asarray(cyl.start, float), np.asarray(cyl.end, float)
    u = (s1 - s0) / np.linalg.norm(s1 - s0)
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    a = np.linspace(0, 2 * np.pi, n + 1)
    ring = cyl.radius * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)
    return [s0 + ring, s1 + ring] + [np.array([s0 + ring[k], s1 + ring[k]]) for k in (0, 6, 12, 18)]


def plan_figure(model, plan, cell=None) -> Figure:
    """The figure of ``plan`` (a :class:`daq.plans.Plan`) for ``model`` in ``cell``
    (:class:`~calibration.cell.cell.CellSpec`; None or no tracker: no beams)."""
    rows = [t for t in plan.targets if t.q is not None and len(t.q) == model.n_joints]
    q = np.array([t.q for t in rows], float).reshape(-1, model.n_joints)
    kind = np.array(["spare" if t.spare else t.set for t in rows])
    axis = (0.0, 0.0, 1.0) if cell is None else cell.smr.axis_unit()
    p, a = smr_pose(model, q, axis) if len(q) else (np.zeros((0, 3)), np.zeros((0, 3)))
    T = None if cell is None else cell.tracker_mm
    visible = assess(model, q, cell).visible if T is not None and len(q) else np.ones(len(q), bool)

    fig = Figure(figsize=(12, 6))
    FigureCanvasAgg(fig)
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    top = fig.add_subplot(1, 2, 2)
    views = ((ax3, slice(0, 3)), (top, slice(0, 2)))
    for ax, sl in views:
        def line(P, ax=ax, sl=sl, **kw):
            ax.plot(*np.asarray(P)[:, sl].T, **kw)

        if T is not None:
            for k in np.flatnonzero(visible):
                line(np.array([p[k], T]), color="#f0a030", lw=0.4, alpha=0.25)
            line(T[None], marker="^", ms=12, color="#d9480f", ls="", label="tracker")
        if len(q):
            caps = link_capsules(model, q[:1])
            for k in range(caps.a.shape[1]):
                line(np.array([caps.a[0, k], caps.b[0, k]]), color="#555555",
                     lw=1.0 + caps.radius[k] / 15.0, alpha=0.5, solid_capstyle="round")
            line(p, color="#bbbbbb", lw=0.5)  # the visiting order
            for name, (colour, label) in _SET_STYLE.items():
                sel = (kind == name) & visible
                if sel.any():
                    line(p[sel], marker="o", ms=3, ls="", color=colour,
                         label=f"{label} ({int(sel.sum())})")
                    for k in np.flatnonzero(sel):
                        line(np.array([p[k], p[k] + 60.0 * a[k]]), color=colour, lw=0.6)
            if (~visible).any():
                line(p[~visible], marker="x", ms=5, ls="", color="#c0392b",
                     label=f"not visible ({int((~visible).sum())})")
        for f in [] if cell is None else cell.fixtures:
            for e in _box_edges(f.box) if f.box is not None else _cylinder_edges(f.cylinder):
                line(e, color="#8e44ad", lw=0.8)
        line(np.zeros((1, 3)), marker="s", ms=7, ls="", color="black", label="robot base")
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x, mm (robot base)")
    top.set_ylabel("y, mm")
    top.legend(loc="best", fontsize=8)
    top.grid(True, color="#e3e3e3")
    ax3.set_xlabel("x, mm")
    ax3.set_ylabel("y, mm")
    ax3.set_zlabel("z, mm")
    pts = np.vstack([p, np.zeros((1, 3))] + ([] if T is None else [T[None]]))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    mid, half = (lo + hi) / 2, max(float((hi - lo).max()) / 2, 500.0)
    ax3.set_xlim(mid[0] - half, mid[0] + half)
    ax3.set_ylim(mid[1] - half, mid[1] + half)
    ax3.set_zlim(mid[2] - half, mid[2] + half)
    where = ("tracker position unknown" if T is None else
             f"tracker at {np.round(T).astype(int).tolist()} mm ({cell.tracker_source})")
    fig.suptitle(f"{plan.routine}: {len(rows)} points, {int(visible.sum())} visible; {where}")
    fig.tight_layout()
    return fig
