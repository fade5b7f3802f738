"""The calibration report: one self-contained HTML page that tells the story of a
calibration — how far off the robot was, what each step fixed, what is left.

:func:`build_report` fits the stages itself (:func:`calibration.workflow.staged_fit`:
uncalibrated → current model → current plus the effect the diagnosis recommends, or with
``auto`` the automatic diagnosis' steps) and renders them; :func:`render_report` renders
already-computed fits, a :class:`~calibration.diagnosis.diagnosis.Diagnosis` and optionally the
:class:`~calibration.workflow.AutoStory` (for callers such as ``cellcal demo`` that have
them at hand). Figures: :mod:`presentation.figures` and :mod:`presentation.joint_figures`;
tables and style: :mod:`presentation.html_tables`; where it comes from:
:mod:`presentation.provenance`.

The page has no external reference: plots are PNGs (matplotlib, Agg backend) embedded as
``data:`` URIs, the style is a short inline ``<style>``. Apart from the provenance's date,
the output is deterministic for given inputs (seeded subsampling, PNGs without metadata).
"""

from __future__ import annotations

import base64
import html
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from calibration.data.dataset import Dataset
from calibration.diagnosis.diagnosis import Diagnosis
from calibration.effects import DEFAULT_EFFECTS
from calibration.files import write_atomic
from calibration.fit.identify import Fit
from calibration.model.robot_model import RobotModel
from calibration.workflow import AutoStory, ParamsSource, staged_fit

from .figures import (
    fig_hist,
    fig_periodogram,
    fig_steps,
    fig_story,
    fig_time,
    fig_workspace,
)
from .html_tables import (
    CSS,
    HEAD,
    _value_std,  # noqa: F401 - re-exported for the tests
    blunders_section,
    candidates_table,
    correlations_text,
    effects_html,
    envelope_section,
    params_table,
    stats_table,
    steps_table,
)
from .joint_figures import (
    fig_joint_temps,
    fig_joints,
    fig_step,
    fig_torque,
    masked_note,
    same_basis_overlay,
    torque_joints,
)
from .orientation_figures import orientation_section
from .plot_base import STAGE_COLOURS, Stage, png_bytes, style
from .provenance import Provenance
from .residual_points import blunder_rows, points_of
from .thermal_figures import joint_temps_caption, varies

#: resolution of the embedded PNGs (dots per inch)
DPI = 100
#: colour of the intermediate steps of an automatic diagnosis (start blue, final green)
STEP_COLOUR = "#8cc98f"


class ReportError(ValueError):
    """Inputs the report cannot use (the message says why)."""


@dataclass
class Report:
    """A rendered report.

    Attributes
    ----------
    html : the page
    stages : the models shown, uncalibrated first
    diagnosis : the diagnosis of the current model (with a story: of its final model)
    figures : (id, caption title) of every embedded figure, in page order
    timings : seconds spent fitting, diagnosing and rendering
    story : the automatic diagnosis' steps shown, or None
    provenance : what the report was made from, or None
    """

    html: str
    stages: list[Stage]
    diagnosis: Diagnosis
    figures: list[tuple[str, str]] = field(default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    story: AutoStory | None = None
    provenance: Provenance | None = None

    def write(self, path: str | Path) -> Path:
        """Write the page atomically (an interrupted write leaves the old page whole)."""
        write_atomic(path, self.html)
        return Path(path)


# ---- computing the stages ------------------------------------------------------------
def story_stages(uncalibrated: Fit, story: AutoStory, start_label: str = "current model",
                 uncalibrated_label: str = "uncalibrated") -> list[Stage]:
    """The stages of an automatic diagnosis' story: uncalibrated, the start model, then
    the model after every step (labelled ``+ effect``)."""
    return ([Stage(uncalibrated_label, uncalibrated), Stage(start_label, story.start.fit)]
            + [Stage(f"+ {s.effect}", s.fit) for s in story.added])


def build_report(data: Dataset, model: RobotModel, effects: str = DEFAULT_EFFECTS,
                 params: ParamsSource | None = None, *, solver: str = "lm",
                 title: str | None = None, refit: bool = True, auto: bool = False,
                 max_steps: int = 12, budget_s: float | None = None,
                 provenance: Provenance | None = None) -> Report:
    """Fit, diagnose and render the report for one data set.

    The fits are :func:`calibration.workflow.staged_fit`'s (the measured poses, the
    nominal robot, the current effects or given parameters, the solver, whether to refit
    with the recommended effect, or run the automatic diagnosis with ``max_steps`` and
    ``budget_s``); its errors (``ParamsError`` for parameters of another robot,
    ``EffectError``...) pass through. ``title`` is the page's heading (default: from the
    data's source); ``provenance`` is printed under it.
    """
    t0 = time.perf_counter()
    sf = staged_fit(data, model, effects, params, solver=solver, refit=refit, auto=auto,
                    max_steps=max_steps, budget_s=budget_s)
    current_label = "given parameters" if sf.given else "current model"
    if sf.story is not None:
        start = "start (refitted)" if sf.story.recorded else current_label
        stages = story_stages(sf.uncalibrated, sf.story, start)
        if sf.story.recorded:
            stages[-1].label += " = given parameters"
    else:
        stages = [Stage("uncalibrated", sf.uncalibrated), Stage(current_label, sf.current)]
        if sf.improved is not None:
            stages.append(Stage(f"{current_label} + {sf.added_effect}", sf.improved))
    rep = render_report(sf.diagnosis, stages, title=title, story=sf.story, data=data,
                        provenance=provenance)
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
    story: AutoStory | None = None,
    data: Dataset | None = None,
    provenance: Provenance | None = None,
) -> Report:
    """Render already-computed fits and a diagnosis into the HTML page.

    Parameters
    ----------
    diagnosis : the diagnosis of the current model (its ``fit`` is the current model; with
        a ``story``, of the story's final model)
    stages : the story, in order, as :class:`Stage` or (label, fit): typically the
        uncalibrated fit (:func:`~calibration.workflow.fit_uncalibrated`), the current model
        and the current model plus the recommended effect; with a ``story``
        :func:`story_stages`. The last stage's parameters are tabulated.
    title : the page's heading
    dpi : resolution of the plots
    story : the automatic diagnosis' steps: shown first (the RMS step by step) and each
        step's before/after
    data : the whole data set (calibration rows in capture order), to place the blunders
        left out of the fits in the residual figures; without it they are only tabulated
    provenance : what the report was made from, printed under the heading
    """
    t0 = time.perf_counter()
    stages = [s if isinstance(s, Stage) else Stage(*s) for s in stages]
    if not stages:
        raise ReportError("a report needs at least one fitted model")
    _colour(stages, diagnosis, story)
    fit = diagnosis.fit
    title = title or f"Calibration report: {fit.data.source}"
    page = _Page(dpi)
    with style():
        body = _body(page, diagnosis, stages, title, story, data, provenance)
    out = HEAD.format(title=html.escape(title), css=CSS) + body + "</main></body></html>\n"
    return Report(out, stages, diagnosis, page.figures,
                  {"render_s": time.perf_counter() - t0}, story, provenance)


def _colour(stages: list[Stage], diag: Diagnosis, story: AutoStory | None) -> None:
    for k, s in enumerate(stages):
        s.colour = STAGE_COLOURS[min(k, len(STAGE_COLOURS) - 1)]
        if story is None and s.fit is diag.fit:
            s.colour = STAGE_COLOURS[1]
    if story is not None:
        for s in stages[2:]:
            s.colour = STEP_COLOUR
        if len(stages) > 2:
            stages[-1].colour = STAGE_COLOURS[2]


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


def _headline(stages: list[Stage], story: AutoStory | None) -> list[Stage]:
    """The stages the cards and histograms show: all, or with a story the uncalibrated,
    start and final models."""
    if story is None or len(stages) <= 3:
        return stages
    return [stages[0], stages[1], stages[-1]]


def _body(page: _Page, diag: Diagnosis, stages: list[Stage], title: str,
          story: AutoStory | None, data: Dataset | None,
          provenance: Provenance | None) -> str:
    fit = diag.fit
    em = fit.error_model
    floor = diag.noise_floor_mm
    d = fit.data
    parts = [f"<h1>{html.escape(title)}</h1>"]
    if provenance is not None:
        parts.append(provenance.html())
    n_valid = fit.valid["n"] if fit.valid else 0
    model_word = "final effects" if story is not None else "current effects"
    parts.append(
        '<p class="meta">'
        f"robot <b>{html.escape(em.model.name)}</b> ({html.escape(em.model.convention)}) · "
        f"{d.n} calibration poses" + (f" + {n_valid} validation poses" if n_valid else "")
        + f" · {model_word} <code>{html.escape(','.join(em.labels))}</code> · "
        + (f"tracker σ {floor / math.sqrt(3):.4f} mm per axis (noise floor {floor:.4f} mm RMS)"
           if floor else "tracker noise unknown (no noise floor: give --sigma)")
        + "</p>"
    )
    headline = _headline(stages, story)
    parts.append(_cards(diag, headline, story))
    if story is not None:
        parts.append(_steps_figure(page, stages, story, floor))
    parts.append(stats_table(stages, floor))
    if story is None:
        parts.append(page.figure("fig-story", fig_story(stages, floor), "RMS error by model",
                                 "Bars: RMS of the 3-D error on the calibration poses (solid) "
                                 "and on held-out validation poses (hatched), log scale. The "
                                 "dashed line is the noise floor — the RMS a perfect model "
                                 "would leave with this tracker. A model is done when its bars "
                                 "reach it; a validation bar well above its calibration bar "
                                 "means overfitting."))
    else:
        parts.append(_step_section(page, story))
    parts.append(page.figure("fig-hist", fig_hist(headline, floor), "Per-pose error distribution",
                             "Histogram of each pose's 3-D error for "
                             + ("the uncalibrated, start and final models" if headline is not
                                stages else "every model")
                             + " (log axis). The black dashed outline is what pure tracker "
                             "noise alone would give (Maxwell distribution), the red line the "
                             "noise floor. Look for the last model's histogram sitting on the "
                             "noise outline, and for a tail to the right: a few poses the "
                             "model cannot explain."))
    screens = _screens(stages, diag)
    parts.append(blunders_section(screens, (stages[0].label, stages[0].fit.outliers)
                                  if len(stages) > 1 else None))
    parts.append(_where_it_fails(page, diag, stages, story, data, screens))
    parts.append(candidates_table(diag))
    new = ([e for e in stages[-1].fit.error_model.labels
            if e not in story.start.fit.error_model.labels] if story is not None else
           [e for e in stages[-1].fit.error_model.labels if e not in em.labels])
    parts.append(params_table(stages[-1], new))
    parts.append(envelope_section(stages[-1].fit))
    notes = diag.notes + [n for s in stages for n in s.fit.notes]
    if story is not None:
        notes += story.notes
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(
            f"<li>{html.escape(n)}</li>" for n in dict.fromkeys(notes)) + "</ul>")
    parts.append('<p class="meta">cellcal report · diagnosis screened '
                 f"{diag.n_screened} candidate effects</p>")
    return "\n".join(parts)


def _cards(diag: Diagnosis, stages: list[Stage], story: AutoStory | None) -> str:
    cards = []
    for k, s in enumerate(stages):
        rms = s.fit.valid["rms_mm"] if s.fit.valid else s.fit.calib["rms_mm"]
        which = "validation" if s.fit.valid else "calibration"
        label = s.label
        if story is not None and k == len(stages) - 1 and story.added:
            n = len(story.added)
            label = f"after {n} step{'s' if n > 1 else ''}"
        if k:
            cards.append('<div class="arrow">→</div>')
        cards.append(
            f'<div class="card" style="border-top-color:{s.colour}">'
            f'<div class="lbl">{html.escape(label)}</div>'
            f'<div class="big">{rms:.3f}<span> mm</span></div>'
            f'<div class="sub">RMS on {which} poses</div>'
            f'<div class="sub">{effects_html(s.effects)}</div></div>'
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
    if story is not None:
        added = ", ".join(s.effect for s in story.added) or "nothing"
        rec = (f"The automatic diagnosis added {html.escape(added)} and stopped: "
               f"{html.escape(story.stop_reason)}. Of the final model: " + rec)
    return f'<div class="story">{"".join(cards)}</div><p class="{cls}">{rec}{nxt}</p>'


def _steps_figure(page: _Page, stages: list[Stage], story: AutoStory,
                  floor: float | None) -> str:
    labels = ["uncalibrated", "start"] + [f"+ {s.effect}" for s in story.added]
    calib = [stages[0].fit.calib["rms_mm"]] + [s.calib_rms_mm for s in story.steps]
    held = [story.uncalibrated_heldout_rms_mm] + [s.heldout_rms_mm for s in story.steps]
    fig = fig_steps(labels, calib, held, floor, f"held-out ({story.heldout_method})")
    n = len(story.added)
    return page.figure(
        "fig-steps", fig, "RMS error at every step",
        "The error falling step by step: the uncalibrated robot (nominal kinematics, base "
        "and tool fitted), the start model, then the model after "
        + (f"each of the {n} steps" if n != 1 else "the one step")
        + " of the automatic diagnosis (a step adds the one missing effect that lowers the "
        "held-out error most). Solid: RMS of the 3-D error on the calibration poses; "
        f"dashed: on held-out poses ({html.escape(story.heldout_method)}), the figure to "
        "trust; log scale. The red line is the noise floor, what a perfect model would "
        "leave with this tracker.")


def _step_section(page: _Page, story: AutoStory) -> str:
    parts = ["<h2>What each step fixed</h2>", steps_table(story, story.start.fit.noise_floor_mm)]
    rows = story.start.fit.data
    for k, step in enumerate(story.added, 1):
        before = story.steps[k - 1].fit
        if step.effect not in step.fit.error_model.labels:
            continue
        sfig = fig_step(before, step.fit, step.effect, rows, k, step.explanation)
        parts.append(page.figure(f"fig-step-{k}", sfig.figure, sfig.title, sfig.caption))
    return "\n".join(parts)


def _screens(stages: list[Stage], diag: Diagnosis):
    """(label, blunder screen) of every calibrated stage's fit and of the diagnosis, each
    once (the uncalibrated reference is left out: its residuals are the missing
    calibration, its blunder test judges only itself)."""
    out, seen = [], set()
    for label, sc in [(s.label, s.fit.outliers) for s in stages[1:]] + [("diagnosis",
                                                                          diag.outliers)]:
        if sc is not None and id(sc) not in seen:
            seen.add(id(sc))
            out.append((label, sc))
    return out


def _where_it_fails(page: _Page, diag: Diagnosis, stages: list[Stage],
                    story: AutoStory | None, data: Dataset | None, screens) -> str:
    fit = diag.fit
    which = "final" if story is not None else "current"
    parts = [f"<h2>Where the {which} model {'still ' if story is not None else ''}fails</h2>"]
    worst = ", ".join(f"pose {html.escape(str(p))} (line {line}) {e:.3f} mm"
                      for p, line, e in diag.where.worst)
    parts.append(f"<p>Worst calibration poses: {worst}.</p>")
    cloud = points_of(fit, fit.data, order=data)
    in_fit = set(fit.data.pose_id)
    ids = list(dict.fromkeys(b.pose_id for _, sc in screens for b in sc.blunders
                             if b.pose_id not in in_fit))
    rows = blunder_rows(data, ids)
    blunders = points_of(fit, rows, order=data) if rows is not None else None
    marked = (" Orange crosses: the measurements left out as blunders (a triangle on the "
              "edge: beyond the plotted range)." if blunders is not None else "")
    fig, scale, ref = fig_workspace(fit, blunders)
    parts.append(page.figure(
        "fig-workspace", fig, "Residual vectors in the workspace",
        f"Measured target positions (tracker frame) seen from three sides; each arrow is "
        f"that pose's residual (measured − predicted) of the <i>{which} model</i>, drawn "
        f"<b>{scale:g}×</b> enlarged (the key arrow is {ref:g} mm of error), coloured by its "
        "3-D magnitude. Circles: calibration poses, triangles: validation poses. Arrows that "
        "line up over a region (all pointing the same way, or growing with reach) point at a "
        "physical effect; random arrows at the noise floor are what a finished model leaves."
        + marked))
    best = diag.best
    overlay = same_basis_overlay(diag, stages, cloud)
    ov_txt = ""
    if overlay is not None:
        ov_txt = (f" Orange: what adding the recommended <code>{html.escape(best.effect)}"
                  "</code> changes in the model's prediction, seen from that joint on the same "
                  "basis as the cloud (the cloud scatters around it by what the refitted "
                  "model still leaves).")
    is_compliance = best is not None and best.family == "compliance"
    backlash = best.joint - 1 if best is not None and best.family == "backlash" else None
    dir_txt = ("" if backlash is None else
               f" Joint {backlash + 1}, where the diagnosis recommends backlash, is coloured "
               "by approach direction (blue: the joint came turning positive, purple: "
               "negative) with a median for each direction: two bands ±b apart.")
    parts.append(page.figure(
        "fig-joints", fig_joints(cloud, None if is_compliance else overlay, blunders,
                                 backlash),
        "Residual seen from each joint vs its angle",
        "For every joint, the correction of that joint's angle that would explain each "
        "pose's residual on its own (µrad), against the joint's angle; the black line is "
        "the median in bins of angle (broken where a bin holds fewer than 5 poses). A flat "
        "cloud around zero means nothing depends on this joint's angle; a wave is a "
        "periodic (harmonic) error of as many cycles per turn as it has crests, a straight "
        "slope a scale (gear ratio) error, a smooth irregular curve an error for a "
        "correction table. Backlash is not a function of the angle but two bands ±b apart "
        "by approach direction (a single median across both bands means nothing)."
        + dir_txt + masked_note(cloud) + ("" if is_compliance else ov_txt) + marked))
    tj = torque_joints(cloud)
    no_torque = sorted(set(range(cloud.q.shape[1])) - set(tj))
    if tj:
        parts.append(page.figure(
            "fig-torque", fig_torque(cloud, overlay if is_compliance else None, blunders,
                                     backlash),
            "Residual seen from each joint vs its gravity torque",
            "The same joint-equivalent residual against the gravity torque on that joint "
            "(model's mass model). A straight line through zero is joint compliance "
            "(deflection proportional to load): its slope is the missing compliance term."
            + (f" Joint(s) {', '.join(str(j + 1) for j in no_torque)} carry no gravity "
               "torque in the mass model and are not shown." if no_torque else "")
            + (dir_txt if backlash in tj else "") + masked_note(cloud, tj)
            + (ov_txt if is_compliance else "") + marked))
    parts.append(page.figure(
        "fig-time", fig_time(cloud, diag.noise_floor_mm, blunders), "Error over the capture",
        "Each calibration pose's 3-D error in capture order"
        + (" (time since the first pose)" if cloud.t_s is not None else "")
        + (" and against the temperature" if cloud.temp_c is not None else "")
        + (" and the joints' mean temperature" if varies(cloud.joint_temp) else "")
        + "; black: running median (broken over stretches with too few poses), red: noise "
        "floor. A drift or a trend with temperature is thermal growth or a moving tracker, "
        "not the robot's geometry." + marked + correlations_text(diag)))
    if varies(cloud.joint_temp):
        parts.append(page.figure(
            "fig-joint-temps", fig_joint_temps(cloud, blunders),
            "Residual seen from each joint vs its temperature",
            joint_temps_caption(cloud) + masked_note(cloud) + marked))
    parts.append(orientation_section(page.figure, fit))
    if diag.where.periodogram:
        parts.append(page.figure(
            "fig-periodogram", fig_periodogram(diag), "Harmonic periodogram per joint",
            "Share of the remaining error a K-per-turn periodic error of that joint would "
            "explain, K = 1…60 (gear and bearing errors repeat a whole number of times per "
            "turn). The dashed line is the significance threshold (F-test, corrected for "
            "every candidate screened): a bar above it is a real periodic error, bars below "
            "are noise. Each panel has its own scale."))
    return "\n".join(parts)
