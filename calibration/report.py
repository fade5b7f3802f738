"""The calibration report: one self-contained HTML page that shows at a glance where the
model fails and what fixed it.

:func:`build_report` fits the stages itself (uncalibrated → current model → current plus
the effect the diagnosis recommends) and renders them; :func:`render_report` renders
already-computed fits and a :class:`~calibration.diagnosis.Diagnosis` (for callers such
as ``cellcal demo`` that have them at hand).

The page has no external reference: plots are PNGs (matplotlib, Agg backend) embedded as
``data:`` URIs, the style is a short inline ``<style>``. The output is deterministic for
given inputs (no timestamps, seeded subsampling, PNGs without metadata).
"""

from __future__ import annotations

import base64
import html
import io
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import matplotlib.colors as mcolors
import numpy as np
import scipy.stats
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from .dataset import Dataset
from .diagnosis import Diagnosis, describe_effect, diagnose
from .effects import DEFAULT_EFFECTS, JointEffect
from .error_model import ErrorModel
from .identify import Fit, error_stats, fit_at, fit_uncalibrated, identify
from .params_io import load_params
from .robot_model import RobotModel

# figures are drawn on Agg canvases (never pyplot): no display, no global figure registry
matplotlib.use("Agg")

#: resolution of the embedded PNGs (dots per inch)
DPI = 100
#: at most this many points per scatter plot (a seeded random subsample beyond)
MAX_POINTS = 3000
#: rows of the candidate ranking shown
TOP_CANDIDATES = 12

_STAGE_COLOURS = ("#9a9a9a", "#1f6fb4", "#2a9d3a", "#8e44ad", "#c0392b")
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


class ReportError(ValueError):
    """Inputs the report cannot use (the message says why)."""


@dataclass
class Stage:
    """One model in the story: a label, its fit and a colour."""

    label: str
    fit: Fit
    colour: str = "#1f6fb4"

    @property
    def effects(self) -> str:
        return ",".join(self.fit.error_model.labels)


@dataclass
class Report:
    """A rendered report.

    Attributes
    ----------
    html : the page
    stages : the models shown, uncalibrated first
    diagnosis : the diagnosis of the current model
    figures : (id, caption title) of every embedded figure, in page order
    timings : seconds spent fitting, diagnosing and rendering
    """

    html: str
    stages: list[Stage]
    diagnosis: Diagnosis
    figures: list[tuple[str, str]] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)

    def write(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_text(self.html, encoding="utf-8")
        return path


# ---- computing the stages ------------------------------------------------------------
def build_report(
    data: Dataset,
    model: RobotModel,
    effects: str = DEFAULT_EFFECTS,
    params: str | Path | tuple[ErrorModel, np.ndarray] | None = None,
    *,
    solver: str = "lm",
    title: str | None = None,
    refit: bool = True,
) -> Report:
    """Fit, diagnose and render the report for one data set.

    Parameters
    ----------
    data : the measured poses (calibration and ``set=valid`` rows)
    model : the nominal robot
    effects : the current model's effects (ignored with ``params``)
    params : a params.json path, or (error model, values): the current model's parameters
        are taken from there instead of fitted
    solver : identification method for the fits
    title : the page's heading (default: from the data's source)
    refit : add the recommended effect (when significant) and refit, as the third stage

    Raises :class:`ReportError` (a ``ValueError``) for inputs that do not fit together;
    the loaders' own errors (``ParamsError``, ``EffectError``...) pass through.
    """
    t0 = time.perf_counter()
    if params is not None:
        em, x = (load_params(params)[:2] if isinstance(params, (str, Path)) else params)
        if em.model.n_joints != model.n_joints:
            raise ReportError(f"{params}: model has {em.model.n_joints} joints, "
                              f"the data {model.n_joints}")
        current = fit_at(em, data, x)
        current_label = "given parameters"
    else:
        em = ErrorModel(model, effects)
        current = identify(em, data, solver)
        current_label = "current model"
    uncalibrated = fit_uncalibrated(model, data, solver=solver)
    t1 = time.perf_counter()
    diag = diagnose(current, data)
    t2 = time.perf_counter()
    improved = None
    if refit and diag.best is not None:
        improved = identify(current.error_model.with_effects(diag.best.effect), data, solver)
    t3 = time.perf_counter()
    stages = [Stage("uncalibrated", uncalibrated), Stage(current_label, current)]
    if improved is not None:
        stages.append(Stage(f"{current_label} + {diag.best.effect}", improved))
    rep = render_report(diag, stages, title=title)
    rep.timings = {"fit_s": t1 - t0 + t3 - t2, "diagnose_s": t2 - t1,
                   "render_s": rep.timings["render_s"], "total_s": time.perf_counter() - t0}
    return rep


# ---- rendering ---------------------------------------------------------------------------
def render_report(
    diagnosis: Diagnosis,
    stages: list[Stage] | list[tuple[str, Fit]],
    *,
    title: str | None = None,
    dpi: int = DPI,
) -> Report:
    """Render already-computed fits and a diagnosis into the HTML page.

    Parameters
    ----------
    diagnosis : the diagnosis of the current model (its ``fit`` is the current model)
    stages : the story, in order, as :class:`Stage` or (label, fit): typically the
        uncalibrated fit (:func:`~calibration.identify.fit_uncalibrated`), the current model
        and the current model plus the recommended effect. The last stage's parameters are
        tabulated.
    title : the page's heading
    dpi : resolution of the plots
    """
    t0 = time.perf_counter()
    stages = [s if isinstance(s, Stage) else Stage(*s) for s in stages]
    if not stages:
        raise ReportError("a report needs at least one fitted model")
    for k, s in enumerate(stages):
        s.colour = _STAGE_COLOURS[min(k, len(_STAGE_COLOURS) - 1)]
        if s.fit is diagnosis.fit:
            s.colour = _STAGE_COLOURS[1]
    fit = diagnosis.fit
    title = title or f"Calibration report: {fit.data.source}"
    page = _Page(dpi)
    with matplotlib.rc_context(_RC):
        body = _body(page, diagnosis, stages, title)
    out = _HEAD.format(title=html.escape(title), css=_CSS) + body + "</main></body></html>\n"
    return Report(out, stages, diagnosis, page.figures,
                  {"render_s": time.perf_counter() - t0})


class _Page:
    """Collects figures as <figure> blocks with data: URIs."""

    def __init__(self, dpi: int):
        self.dpi = dpi
        self.figures: list[tuple[str, str]] = []

    def figure(self, fig_id: str, fig: Figure, title: str, caption: str) -> str:
        buf = io.BytesIO()
        FigureCanvasAgg(fig)
        try:
            fig.savefig(buf, format="png", dpi=self.dpi, metadata={"Software": None})
        finally:
            fig.clear()
        b64 = base64.b64encode(buf.getvalue()).decode("ascii")
        self.figures.append((fig_id, title))
        n = len(self.figures)
        return (
            f'<figure id="{fig_id}"><img alt="{html.escape(title)}" '
            f'src="data:image/png;base64,{b64}">'
            f"<figcaption><b>Figure {n}. {html.escape(title)}.</b> {caption}</figcaption>"
            "</figure>\n"
        )


def _body(page: _Page, diag: Diagnosis, stages: list[Stage], title: str) -> str:
    fit = diag.fit
    em = fit.error_model
    floor = diag.noise_floor_mm
    d = fit.data
    parts = [f"<h1>{html.escape(title)}</h1>"]
    n_valid = fit.valid["n"] if fit.valid else 0
    parts.append(
        '<p class="meta">'
        f"robot <b>{html.escape(em.model.name)}</b> ({html.escape(em.model.convention)}) · "
        f"{d.n} calibration poses" + (f" + {n_valid} validation poses" if n_valid else "")
        + f" · current effects <code>{html.escape(','.join(em.labels))}</code> · "
        + (f"tracker σ {floor / math.sqrt(3):.4f} mm per axis (noise floor {floor:.4f} mm RMS)"
           if floor else "tracker noise unknown (no noise floor: give --sigma)")
        + "</p>"
    )
    parts.append(_story(diag, stages))
    parts.append(_stats_table(stages, floor))
    parts.append(page.figure("fig-story", _fig_story(stages, floor), "RMS error by model",
                             "Bars: RMS of the 3-D error on the calibration poses (solid) and "
                             "on held-out validation poses (hatched), log scale. The dashed "
                             "line is the noise floor — the RMS a perfect model would leave "
                             "with this tracker. A model is done when its bars reach it; a "
                             "validation bar well above its calibration bar means overfitting."))
    parts.append(page.figure("fig-hist", _fig_hist(stages, floor), "Per-pose error distribution",
                             "Histogram of each pose's 3-D error for every model (log axis). "
                             "The black dashed outline is what pure tracker noise alone would give "
                             "(Maxwell distribution), the red line the noise floor. Look for "
                             "the last model's histogram sitting on the noise outline, and for "
                             "a tail to the right: a few poses the model cannot explain."))
    parts.append("<h2>Where the current model fails</h2>")
    worst = ", ".join(f"pose {html.escape(str(p))} (line {line}) {e:.3f} mm"
                      for p, line, e in diag.where.worst)
    parts.append(f"<p>Worst calibration poses: {worst}.</p>")
    fig, scale, ref = _fig_workspace(fit)
    parts.append(page.figure(
        "fig-workspace", fig, "Residual vectors in the workspace",
        f"Measured target positions (tracker frame) seen from three sides; each arrow is "
        f"that pose's residual (measured − predicted) of the <i>current model</i>, drawn "
        f"<b>{scale:g}×</b> enlarged (the key arrow is {ref:g} mm of error), coloured by its "
        "3-D magnitude. Circles: calibration poses, triangles: validation poses. Arrows that "
        "line up over a region (all pointing the same way, or growing with reach) point at a "
        "physical effect; random arrows at the noise floor are what a finished model leaves."))
    best = diag.best
    overlay = _candidate_overlay(diag, stages)
    cand_txt = (f" Orange: what the recommended <code>{html.escape(best.effect)}</code> "
                "fitted (its joint correction, per pose) on that joint."
                if overlay is not None else "")
    joint_txt = cand_txt if overlay is not None and best.family != "compliance" else ""
    torque_txt = cand_txt if overlay is not None and best.family == "compliance" else ""
    parts.append(page.figure(
        "fig-joints", _fig_joints(diag, overlay), "Residual seen from each joint vs its angle",
        "For every joint, the correction of that joint's angle that would explain each "
        "pose's residual on its own (µrad), against the joint's angle; the black line is "
        "the median in bins of angle. A flat cloud around zero means nothing depends on "
        "this joint's angle; a wave is a periodic (harmonic) error, a slope a scale (gear "
        "ratio) error, a step at 0 backlash. Wrist joints move the target little, so their "
        "points scatter more." + joint_txt))
    no_torque = sorted(set(range(diag.where.q.shape[1])) - set(_torque_joints(diag)))
    if _torque_joints(diag):
        parts.append(page.figure(
            "fig-torque", _fig_torque(diag, overlay), "Residual seen from each joint vs "
            "its gravity torque",
            "The same joint-equivalent residual against the gravity torque on that joint "
            "(model's mass model). A straight sloped line is joint compliance (deflection "
            "proportional to load): the slope is the missing stiffness term."
            + (f" Joint(s) {', '.join(str(j + 1) for j in no_torque)} carry no gravity "
               "torque in the mass model and are not shown." if no_torque else "")
            + torque_txt))
    parts.append(page.figure(
        "fig-time", _fig_time(diag), "Error over the capture",
        "Each calibration pose's 3-D error in capture order"
        + (" (time since the first pose)" if diag.where.t_s is not None else "")
        + (" and against the temperature" if diag.where.temp_c is not None else "")
        + "; black: running median, red: noise floor. A drift or a trend with temperature "
        "is thermal growth or a moving tracker, not the robot's geometry."
        + _correlations_text(diag)))
    if diag.where.periodogram:
        parts.append(page.figure(
            "fig-periodogram", _fig_periodogram(diag), "Harmonic periodogram per joint",
            "Share of the remaining error a K-per-turn periodic error of that joint would "
            "explain, K = 1…60 (gear and bearing errors repeat a whole number of times per "
            "turn). The dashed line is the significance threshold (F-test, corrected for "
            "every candidate screened): a bar above it is a real periodic error, bars below "
            "are noise. Each panel has its own scale."))
    parts.append(_candidates_table(diag))
    parts.append(_params_table(stages[-1], diag))
    notes = diag.notes + [n for s in stages for n in s.fit.notes]
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(
            f"<li>{html.escape(n)}</li>" for n in dict.fromkeys(notes)) + "</ul>")
    parts.append('<p class="meta">cellcal report · diagnosis screened '
                 f"{diag.n_screened} candidate effects</p>")
    return "\n".join(parts)


# ---- HTML pieces -------------------------------------------------------------------------
def _fmt(v, digits: int = 4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{v:.{digits}f}"


def _story(diag: Diagnosis, stages: list[Stage]) -> str:
    cards = []
    for k, s in enumerate(stages):
        rms = s.fit.valid["rms_mm"] if s.fit.valid else s.fit.calib["rms_mm"]
        which = "validation" if s.fit.valid else "calibration"
        if k:
            cards.append('<div class="arrow">→</div>')
        cards.append(
            f'<div class="card" style="border-top-color:{s.colour}">'
            f'<div class="lbl">{html.escape(s.label)}</div>'
            f'<div class="big">{rms:.3f}<span> mm</span></div>'
            f'<div class="sub">RMS on {which} poses</div>'
            f'<div class="sub"><code>{html.escape(s.effects)}</code></div></div>'
        )
    floor = diag.noise_floor_mm
    if floor:
        cards.append('<div class="arrow">≥</div>')
        cards.append(f'<div class="card floor"><div class="lbl">noise floor</div>'
                     f'<div class="big">{floor:.3f}<span> mm</span></div>'
                     '<div class="sub">tracker noise alone</div></div>')
    rec = html.escape(diag.recommendation())
    cls = "rec good" if diag.best is not None or diag.at_floor else "rec"
    nxt = (f'<br>Next: <code>--effects {html.escape(diag.next_effects())}</code>'
           if diag.best is not None else "")
    return f'<div class="story">{"".join(cards)}</div><p class="{cls}">{rec}{nxt}</p>'


def _stats_table(stages: list[Stage], floor: float | None) -> str:
    head = ("<tr><th rowspan=2>model</th><th rowspan=2>effects</th><th rowspan=2>params<br>"
            "(identifiable)</th><th colspan=5>calibration poses, mm</th>"
            "<th colspan=5>validation poses, mm</th></tr><tr>"
            + "<th>n</th><th>RMS</th><th>mean</th><th>p95</th><th>max</th>" * 2 + "</tr>")
    rows = []
    for s in stages:
        f = s.fit
        cells = [f'<td><span class="dot" style="background:{s.colour}"></span>'
                 f"{html.escape(s.label)}</td>",
                 f"<td><code>{html.escape(s.effects)}</code></td>",
                 f"<td>{f.error_model.n_params} ({f.identifiability.n_identifiable})</td>"]
        for st in (f.calib, f.valid or error_stats(np.zeros((0, 3)))):
            cells.append(f"<td>{st['n']}</td>")
            for k in ("rms_mm", "mean_mm", "p95_mm", "max_mm"):
                cells.append(f'<td class="num" data-stat="{k}">{_fmt(st[k])}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    foot = (f'<tr class="floor"><td>noise floor</td><td colspan=2>√3 σ of the tracker</td>'
            f'<td></td><td class="num">{floor:.4f}</td><td colspan=3></td>'
            f'<td></td><td class="num">{floor:.4f}</td><td colspan=3></td></tr>'
            if floor else "")
    return ('<table class="stats" id="tab-stats"><caption>Error statistics before and after '
            "(3-D distance between measured and predicted target, per pose)</caption>"
            f"{head}{''.join(rows)}{foot}</table>")


def _candidates_table(diag: Diagnosis) -> str:
    rows = []
    for c in diag.candidates[:TOP_CANDIDATES]:
        held = (f"{c.heldout_before_mm:.4f} → {c.heldout_after_mm:.4f}"
                if c.heldout_after_mm is not None else "")
        after = c.refit_rms_mm or c.rms_after_mm
        cls = ' class="best"' if c is diag.best else ""
        rows.append(
            f"<tr{cls}><td><code>{html.escape(c.effect)}</code></td>"
            f"<td>{html.escape(describe_effect(c))}</td><td>{c.n_params}</td>"
            f'<td class="num">{100 * c.explained_fraction:.1f}</td>'
            f'<td class="num">{_fmt(after)}</td><td class="num">{c.log10_p:.0f}</td>'
            f"<td>{'yes' if c.significant else 'no'}</td><td class=\"num\">{held}</td>"
            f"<td>{html.escape(c.note)}</td></tr>")
    more = len(diag.candidates) - TOP_CANDIDATES
    tail = (f"<p class=\"meta\">{more} more candidates not shown (one harmonic order per "
            "joint is listed; the periodogram shows them all).</p>" if more > 0 else "")
    return (
        '<h2>Candidate effects</h2><table id="tab-candidates"><caption>Every effect not in '
        f"the current model, ranked ({diag.n_screened} screened). <i>Explains</i>: share of the "
        "remaining squared error it would remove; <i>RMS after</i>: refitted when confirmed, "
        "else the linear estimate; <i>log10 p</i>: F-test against the remaining error; "
        "<i>held-out</i>: RMS on poses not used for fitting, without → with the effect."
        "</caption><tr><th>effect</th><th>what</th><th>params</th><th>explains %</th>"
        "<th>RMS after, mm</th><th>log10 p</th><th>significant</th>"
        f"<th>held-out RMS, mm</th><th>note</th></tr>{''.join(rows)}</table>{tail}")


def _params_table(stage: Stage, diag: Diagnosis) -> str:
    fit = stage.fit
    fixed = fit.identifiability.fixed
    new = set() if fit is diag.fit else {
        n for e in fit.error_model.effects if e.label not in diag.fit.error_model.labels
        for n in e.full_names}
    rows = []
    for r in fit.parameter_rows():
        status = "identifiable" if r["identifiable"] else "fixed: " + fixed.get(r["name"], "")
        value, std = _value_std(r["value"], r["std"])
        ratio = ""
        if r["std"]:
            ratio = f"{abs(r['value']) / r['std']:.1f}"
        cls = ' class="best"' if r["name"] in new else (
            ' class="fixed"' if not r["identifiable"] else "")
        rows.append(f"<tr{cls}><td><code>{html.escape(r['name'])}</code></td>"
                    f'<td class="num">{value}</td><td class="num">{std}</td>'
                    f'<td class="num">{ratio}</td><td>{html.escape(r["unit"])}</td>'
                    f"<td>{html.escape(status)}</td></tr>")
    ident = fit.identifiability
    return (
        f'<h2>Parameters: {html.escape(stage.label)}</h2>'
        f'<table id="tab-params"><caption><code>{html.escape(stage.effects)}</code>: '
        f"{fit.error_model.n_params} parameters, {ident.n_identifiable} identifiable "
        f"(condition number {ident.condition_number:.3g}, observability index "
        f"{ident.observability_index:.3g}); solver {html.escape(fit.solver)}"
        f"{'' if fit.converged else ' — did not converge: ' + html.escape(fit.reason)}. "
        "Values in display units (angles in degrees) with their standard uncertainty; "
        "|value|/σ below 2 means the data cannot tell the parameter from zero. "
        + ("Highlighted: the recommended effect's parameters. " if new else "")
        + "Fixed parameters are held at their start value, with the reason.</caption>"
        "<tr><th>parameter</th><th>value</th><th>σ</th><th>|value|/σ</th><th>unit</th>"
        f"<th>status</th></tr>{''.join(rows)}</table>")


def _value_std(value: float, std: float | None) -> tuple[str, str]:
    """A value rounded to its uncertainty (two significant digits of σ)."""
    if not std or not math.isfinite(std):
        return f"{value:.6g}", ""
    d = 1 - math.floor(math.log10(std))
    if 0 <= d <= 7:
        return f"{value:.{d}f}", f"{std:.{d}f}"
    if d < 0:
        return f"{value:.0f}", f"{std:.2g}"
    return f"{value:.3e}", f"{std:.2e}"


def _correlations_text(diag: Diagnosis) -> str:
    corr = diag.where.correlations
    if not corr:
        return ""
    items = ", ".join(f"{html.escape(k)} {v:+.2f}" for k, v in corr.items())
    return f" Spearman correlation of the error with: {items}."


# ---- figures ------------------------------------------------------------------------------
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


def _fig_story(stages: list[Stage], floor: float | None) -> Figure:
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


def _fig_hist(stages: list[Stage], floor: float | None) -> Figure:
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


def _fig_workspace(fit: Fit) -> tuple[Figure, float, float]:
    pts = [(fit.data.xyz, fit.residuals, "o")]
    if fit.valid_data is not None and fit.valid_residuals is not None:
        pts.append((fit.valid_data.xyz, fit.valid_residuals, "^"))
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


def _candidate_overlay(diag: Diagnosis, stages: list[Stage]):
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
        ax.scatter(x, y, s=s, color=_STAGE_COLOURS[1], alpha=0.55, linewidths=0)
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


def _fig_joints(diag: Diagnosis, overlay) -> Figure:
    q = diag.where.q
    return _fig_residual_grid(diag, overlay, list(range(q.shape[1])), np.degrees(q),
                              "q{j}, deg", compliance_overlay=False)


def _torque_joints(diag: Diagnosis) -> list[int]:
    """0-based joints whose gravity torque varies over the poses."""
    tau = diag.where.torque_nm
    if tau is None:
        return []
    span = np.ptp(tau, axis=0)
    return [j for j in range(tau.shape[1]) if span[j] > 1e-6 * max(float(span.max()), 1e-300)]


def _fig_torque(diag: Diagnosis, overlay) -> Figure:
    return _fig_residual_grid(diag, overlay, _torque_joints(diag), diag.where.torque_nm,
                              "gravity torque on joint {j}, N·m", compliance_overlay=True)


def _fig_time(diag: Diagnosis) -> Figure:
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
        ax.scatter(x[idx], e[idx], s=_marker_size(len(idx)), color=_STAGE_COLOURS[1],
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
    from .diagnosis import ALPHA

    F = float(scipy.stats.f.isf(ALPHA / max(diag.n_screened, 1), 2, dof))
    if not math.isfinite(F):
        return None
    g = 2.0 * F / dof
    return g / (1.0 + g)


def _fig_periodogram(diag: Diagnosis) -> Figure:
    per = diag.where.periodogram
    joints = sorted(per)
    fig, axes = _grid(len(joints))
    thr = _harmonic_threshold(diag)
    best = diag.best
    for ax, j in zip(axes, joints, strict=False):
        orders, frac = per[j]
        ax.vlines(orders, 0, frac * 100, color=_STAGE_COLOURS[1], lw=1.6)
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


_HEAD = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{css}</style></head><body><main>
"""

_CSS = """
body{margin:0;background:#f6f7f9;color:#1d232a;font:14px/1.45 -apple-system,"Segoe UI",
Roboto,"Helvetica Neue",Arial,sans-serif}
main{max-width:1180px;margin:0 auto;padding:20px 28px 40px;background:#fff}
h1{font-size:22px;margin:4px 0 2px}h2{font-size:17px;margin:28px 0 8px;
border-bottom:1px solid #e4e6ea;padding-bottom:3px}
.meta{color:#5b6470;font-size:12.5px}
code{font:12.5px/1.3 ui-monospace,Menlo,Consolas,monospace;background:#f1f3f5;
padding:0 3px;border-radius:3px}
.story{display:flex;flex-wrap:wrap;align-items:stretch;gap:8px;margin:16px 0 8px}
.card{border:1px solid #dde1e6;border-top:5px solid #1f6fb4;border-radius:6px;
padding:8px 14px;min-width:150px;background:#fbfcfd}
.card.floor{border-top-color:#c0392b;background:#fff}
.card .lbl{font-weight:600;font-size:13px}.card .big{font-size:26px;font-weight:600}
.card .big span{font-size:14px;font-weight:400;color:#5b6470}
.card .sub{font-size:11.5px;color:#5b6470}
.arrow{align-self:center;font-size:24px;color:#8a939e}
.rec{border-left:4px solid #8a939e;background:#f4f5f7;padding:8px 12px;margin:8px 0 14px}
.rec.good{border-left-color:#2a9d3a;background:#eef8f0}
table{border-collapse:collapse;margin:8px 0 6px;font-size:12.5px}
caption{caption-side:top;text-align:left;color:#5b6470;font-size:12px;padding:4px 0}
th,td{border-bottom:1px solid #e8eaed;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f4f5f7;font-weight:600}
td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.best td{background:#eef8f0}tr.fixed td{color:#8a939e}
tr.floor td{color:#c0392b}
.dot{display:inline-block;width:9px;height:9px;border-radius:50%;margin-right:6px}
figure{margin:18px 0}figure img{max-width:100%;height:auto;display:block}
figcaption{font-size:12.5px;color:#39424c;max-width:980px;margin-top:4px}
"""
