"""The calibration report: one self-contained HTML page that shows at a glance where the
model fails and what fixed it.

:func:`build_report` fits the stages itself (:func:`calibration.workflow.staged_fit`:
uncalibrated → current model → current plus the effect the diagnosis recommends) and
renders them; :func:`render_report` renders already-computed fits and a
:class:`~calibration.diagnosis.Diagnosis` (for callers such as ``cellcal demo`` that have
them at hand). The figures are drawn by :mod:`presentation.figures`.

The page has no external reference: plots are PNGs (matplotlib, Agg backend) embedded as
``data:`` URIs, the style is a short inline ``<style>``. The output is deterministic for
given inputs (no timestamps, seeded subsampling, PNGs without metadata).
"""

from __future__ import annotations

import base64
import html
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from calibration.dataset import Dataset
from calibration.diagnosis import Diagnosis, describe_effect
from calibration.effects import DEFAULT_EFFECTS
from calibration.files import write_atomic
from calibration.identify import Fit, error_stats
from calibration.robot_model import RobotModel
from calibration.workflow import ParamsSource, staged_fit

from .figures import (
    STAGE_COLOURS,
    Stage,
    candidate_overlay,
    fig_hist,
    fig_joints,
    fig_periodogram,
    fig_story,
    fig_time,
    fig_torque,
    fig_workspace,
    png_bytes,
    style,
    torque_joints,
)

#: resolution of the embedded PNGs (dots per inch)
DPI = 100
#: rows of the candidate ranking shown
TOP_CANDIDATES = 12


class ReportError(ValueError):
    """Inputs the report cannot use (the message says why)."""


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
        """Write the page atomically (an interrupted write leaves the old page whole)."""
        write_atomic(path, self.html)
        return Path(path)


# ---- computing the stages ------------------------------------------------------------
def build_report(data: Dataset, model: RobotModel, effects: str = DEFAULT_EFFECTS,
                 params: ParamsSource | None = None, *, solver: str = "lm",
                 title: str | None = None, refit: bool = True) -> Report:
    """Fit, diagnose and render the report for one data set.

    The fits are :func:`calibration.workflow.staged_fit`'s (the measured poses, the
    nominal robot, the current effects or given parameters, the solver, and whether to
    refit with the recommended effect); its errors (``ParamsError`` for parameters of
    another robot, ``EffectError``...) pass through. ``title`` is the page's heading
    (default: from the data's source).
    """
    t0 = time.perf_counter()
    sf = staged_fit(data, model, effects, params, solver=solver, refit=refit)
    current_label = "given parameters" if sf.given else "current model"
    stages = [Stage("uncalibrated", sf.uncalibrated), Stage(current_label, sf.current)]
    if sf.improved is not None:
        stages.append(Stage(f"{current_label} + {sf.added_effect}", sf.improved))
    rep = render_report(sf.diagnosis, stages, title=title)
    rep.timings = {**sf.timings, "render_s": rep.timings["render_s"],
                   "total_s": time.perf_counter() - t0}
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
        uncalibrated fit (:func:`~calibration.workflow.fit_uncalibrated`), the current model
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
        s.colour = STAGE_COLOURS[min(k, len(STAGE_COLOURS) - 1)]
        if s.fit is diagnosis.fit:
            s.colour = STAGE_COLOURS[1]
    fit = diagnosis.fit
    title = title or f"Calibration report: {fit.data.source}"
    page = _Page(dpi)
    with style():
        body = _body(page, diagnosis, stages, title)
    out = _HEAD.format(title=html.escape(title), css=_CSS) + body + "</main></body></html>\n"
    return Report(out, stages, diagnosis, page.figures,
                  {"render_s": time.perf_counter() - t0})


class _Page:
    """Collects figures as <figure> blocks with data: URIs."""

    def __init__(self, dpi: int):
        self.dpi = dpi
        self.figures: list[tuple[str, str]] = []

    def figure(self, fig_id: str, fig, title: str, caption: str) -> str:
        b64 = base64.b64encode(png_bytes(fig, self.dpi)).decode("ascii")
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
    parts.append(page.figure("fig-story", fig_story(stages, floor), "RMS error by model",
                             "Bars: RMS of the 3-D error on the calibration poses (solid) and "
                             "on held-out validation poses (hatched), log scale. The dashed "
                             "line is the noise floor — the RMS a perfect model would leave "
                             "with this tracker. A model is done when its bars reach it; a "
                             "validation bar well above its calibration bar means overfitting."))
    parts.append(page.figure("fig-hist", fig_hist(stages, floor), "Per-pose error distribution",
                             "Histogram of each pose's 3-D error for every model (log axis). "
                             "The black dashed outline is what pure tracker noise alone would give "
                             "(Maxwell distribution), the red line the noise floor. Look for "
                             "the last model's histogram sitting on the noise outline, and for "
                             "a tail to the right: a few poses the model cannot explain."))
    parts.append("<h2>Where the current model fails</h2>")
    worst = ", ".join(f"pose {html.escape(str(p))} (line {line}) {e:.3f} mm"
                      for p, line, e in diag.where.worst)
    parts.append(f"<p>Worst calibration poses: {worst}.</p>")
    fig, scale, ref = fig_workspace(fit)
    parts.append(page.figure(
        "fig-workspace", fig, "Residual vectors in the workspace",
        f"Measured target positions (tracker frame) seen from three sides; each arrow is "
        f"that pose's residual (measured − predicted) of the <i>current model</i>, drawn "
        f"<b>{scale:g}×</b> enlarged (the key arrow is {ref:g} mm of error), coloured by its "
        "3-D magnitude. Circles: calibration poses, triangles: validation poses. Arrows that "
        "line up over a region (all pointing the same way, or growing with reach) point at a "
        "physical effect; random arrows at the noise floor are what a finished model leaves."))
    best = diag.best
    overlay = candidate_overlay(diag, stages)
    cand_txt = (f" Orange: what the recommended <code>{html.escape(best.effect)}</code> "
                "fitted (its joint correction, per pose) on that joint."
                if overlay is not None else "")
    joint_txt = cand_txt if overlay is not None and best.family != "compliance" else ""
    torque_txt = cand_txt if overlay is not None and best.family == "compliance" else ""
    parts.append(page.figure(
        "fig-joints", fig_joints(diag, overlay), "Residual seen from each joint vs its angle",
        "For every joint, the correction of that joint's angle that would explain each "
        "pose's residual on its own (µrad), against the joint's angle; the black line is "
        "the median in bins of angle. A flat cloud around zero means nothing depends on "
        "this joint's angle; a wave is a periodic (harmonic) error, a slope a scale (gear "
        "ratio) error, a step at 0 backlash. Wrist joints move the target little, so their "
        "points scatter more." + joint_txt))
    no_torque = sorted(set(range(diag.where.q.shape[1])) - set(torque_joints(diag)))
    if torque_joints(diag):
        parts.append(page.figure(
            "fig-torque", fig_torque(diag, overlay), "Residual seen from each joint vs "
            "its gravity torque",
            "The same joint-equivalent residual against the gravity torque on that joint "
            "(model's mass model). A straight sloped line is joint compliance (deflection "
            "proportional to load): the slope is the missing stiffness term."
            + (f" Joint(s) {', '.join(str(j + 1) for j in no_torque)} carry no gravity "
               "torque in the mass model and are not shown." if no_torque else "")
            + torque_txt))
    parts.append(page.figure(
        "fig-time", fig_time(diag), "Error over the capture",
        "Each calibration pose's 3-D error in capture order"
        + (" (time since the first pose)" if diag.where.t_s is not None else "")
        + (" and against the temperature" if diag.where.temp_c is not None else "")
        + "; black: running median, red: noise floor. A drift or a trend with temperature "
        "is thermal growth or a moving tracker, not the robot's geometry."
        + _correlations_text(diag)))
    if diag.where.periodogram:
        parts.append(page.figure(
            "fig-periodogram", fig_periodogram(diag), "Harmonic periodogram per joint",
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
        if r["weak"]:
            status = f"weakly identified: {r['weak']}"
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
        "|value|/σ below 2 means the data cannot tell the parameter from zero; weakly "
        "identified: σ at least |value|, or |r| >= 0.999 with another parameter. "
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
