"""The report's tables and page furniture: error statistics, the automatic diagnosis'
steps, the blunders left out, the candidate ranking, the parameters, and the page's
head and style (responsive: readable from an 800 px wide window up).

Every function returns an HTML fragment; numbers are formatted here, nothing is computed
beyond what a table shows.
"""

from __future__ import annotations

import html
import math

import numpy as np

from calibration.diagnosis.diagnosis import Diagnosis, describe_effect
from calibration.fit.envelope import Envelope, split_stats
from calibration.fit.identify import error_stats
from calibration.fit.outliers import BlunderScreen
from calibration.workflow import AutoStory

from .plot_base import Stage

#: rows of the candidate ranking shown
TOP_CANDIDATES = 12


def fmt(v, digits: int = 4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{v:.{digits}f}"


def envelope_section(fit) -> str:
    """The calibrated envelope of ``fit`` (the ranges its calibration rows covered) and its
    validation error inside and beyond it."""
    env = Envelope.of_fit(fit)
    items = "".join(f"<li>{html.escape(line)}</li>" for line in env.lines())
    table = ""
    if fit.valid:
        split = split_stats(env, fit.valid_data, fit.valid_residuals)
        rows = []
        for where in ("inside", "outside"):
            st = split[where]
            rows.append(f"<tr><td>{where} the envelope</td><td>{st['n']}</td>"
                        + "".join(f'<td class="num">{fmt(st[k])}</td>'
                                  for k in ("rms_mm", "mean_mm", "p95_mm", "max_mm"))
                        + "</tr>")
        by = split["outside"]["by_quantity"]
        beyond = (" Beyond it: " + ", ".join(f"{html.escape(k)} {v}" for k, v in by.items())
                  + " poses." if by else "")
        table = ('<div class="scroll"><table id="tab-envelope"><caption>Validation poses '
                 "inside and beyond the calibrated envelope, mm (the final model)."
                 f"{beyond}</caption><tr><th>validation poses</th><th>n</th><th>RMS</th>"
                 f"<th>mean</th><th>p95</th><th>max</th></tr>{''.join(rows)}</table></div>")
    return ("<h2>Where the calibration was measured</h2><p>The calibrated envelope: the "
            "ranges the calibration poses covered (params.json <code>envelope</code>). A "
            "target beyond it is compensated with the model held at its edge, and named "
            f"(<code>outside_range</code>).</p><ul>{items}</ul>{table}")


def stats_table(stages: list[Stage], floor: float | None) -> str:
    head = ("<tr><th rowspan=2>model</th><th rowspan=2>effects</th><th rowspan=2>params<br>"
            "(identifiable)</th><th colspan=5>calibration poses, mm</th>"
            "<th colspan=5>validation poses, mm</th></tr><tr>"
            + "<th>n</th><th>RMS</th><th>mean</th><th>p95</th><th>max</th>" * 2 + "</tr>")
    rows = []
    for s in stages:
        f = s.fit
        cells = [f'<td><span class="dot" style="background:{s.colour}"></span>'
                 f"{html.escape(s.label)}</td>",
                 f"<td>{effects_html(s.effects)}</td>",
                 f"<td>{f.error_model.n_params} ({f.identifiability.n_identifiable})</td>"]
        for st in (f.calib, f.valid or error_stats(np.zeros((0, 3)))):
            cells.append(f"<td>{st['n']}</td>")
            for k in ("rms_mm", "mean_mm", "p95_mm", "max_mm"):
                cells.append(f'<td class="num" data-stat="{k}">{fmt(st[k])}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    foot = (f'<tr class="floor"><td>noise floor</td><td colspan=2>√3 σ of the tracker</td>'
            f'<td></td><td class="num">{floor:.4f}</td><td colspan=3></td>'
            f'<td></td><td class="num">{floor:.4f}</td><td colspan=3></td></tr>'
            if floor else "")
    return ('<div class="scroll"><table class="stats" id="tab-stats"><caption>Error '
            "statistics before and after (3-D distance between measured and predicted target, "
            f"per pose)</caption>{head}{''.join(rows)}{foot}</table></div>")


#: how the diagnosis orders its candidates (:func:`calibration.diagnosis.diagnosis.diagnose`)
RANKING = (
    "Ranked by the diagnosis: first the significant candidates a refit confirmed (the "
    "held-out error falls with the effect), by their held-out RMS with it, lowest first; "
    "then the other significant ones, then the rest, each of these two groups by BIC gain "
    "(the error it explains weighed against the parameters it costs), largest first.")


def candidates_table(diag: Diagnosis) -> str:
    rows = []
    for c in diag.candidates[:TOP_CANDIDATES]:
        held = (f"{c.heldout_before_mm:.4f} → {c.heldout_after_mm:.4f}"
                if c.heldout_after_mm is not None else "")
        after = c.refit_rms_mm or c.rms_after_mm
        cls = ' class="best"' if c is diag.best else ""
        bic = f"{c.score:.1f}" if math.isfinite(c.score) else "–"
        rows.append(
            f"<tr{cls}><td><code>{html.escape(c.effect)}</code></td>"
            f"<td>{html.escape(describe_effect(c))}</td><td>{c.n_params}</td>"
            f'<td class="num">{100 * c.explained_fraction:.1f}</td>'
            f'<td class="num">{fmt(after)}</td><td class="num">{_log10p(c.log10_p)}</td>'
            f"<td>{'yes' if c.significant else 'no'}</td><td class=\"num\">{held}</td>"
            f'<td class="num">{bic}</td><td>{html.escape(c.note)}</td></tr>')
    more = len(diag.candidates) - TOP_CANDIDATES
    tail = (f"<p class=\"meta\">{more} more candidates not shown (one harmonic order per "
            "joint is listed; the periodogram shows them all).</p>" if more > 0 else "")
    return (
        '<h2>Candidate effects</h2><div class="scroll"><table id="tab-candidates"><caption>'
        f"Every effect not in the model, {diag.n_screened} screened. {RANKING} "
        "<i>Explains</i>: share of the remaining squared error it would remove; <i>RMS "
        "after</i>: refitted when confirmed, else the linear estimate; <i>log10 p</i>: "
        "F-test against the remaining error; <i>held-out</i>: RMS on poses not used for "
        "fitting, without → with the effect."
        "</caption><tr><th>effect</th><th>what</th><th>params</th>"
        "<th>explains %</th><th>RMS after, mm</th><th>log10 p</th><th>significant</th>"
        "<th>held-out RMS, mm</th><th>BIC gain</th><th>note</th></tr>"
        f"{''.join(rows)}</table></div>{tail}")


def _log10p(v: float) -> str:
    text = f"{v:.0f}"
    return "0" if text == "-0" else text


def effects_html(effects: str | list[str]) -> str:
    """An effect list as <code>, breakable after its commas."""
    if not isinstance(effects, str):
        effects = ",".join(effects)
    return "<code>" + html.escape(effects).replace(",", ",<wbr>") + "</code>"


def params_table(stage: Stage, new_effects: list[str] | set[str]) -> str:
    """The stage's parameters; those of ``new_effects`` (added by the story) highlighted."""
    fit = stage.fit
    fixed = fit.identifiability.fixed
    new = {n for e in fit.error_model.effects if e.label in set(new_effects)
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
        '<div class="scroll"><table id="tab-params"><caption>'
        f"<code>{html.escape(stage.effects)}</code>: "
        f"{fit.error_model.n_params} parameters, {ident.n_identifiable} identifiable "
        f"(condition number {ident.condition_number:.3g}, observability index "
        f"{ident.observability_index:.3g}); solver {html.escape(fit.solver)}"
        f"{'' if fit.converged else ' — did not converge: ' + html.escape(fit.reason)}. "
        "Values in display units (angles in degrees) with their standard uncertainty; "
        "|value|/σ below 2 means the data cannot tell the parameter from zero; weakly "
        "identified: σ at least |value|, or |r| >= 0.999 with another parameter. "
        + ("Highlighted: the parameters of the effects the story added. " if new else "")
        + "Fixed parameters are held at their start value, with the reason.</caption>"
        "<tr><th>parameter</th><th>value</th><th>σ</th><th>|value|/σ</th><th>unit</th>"
        f"<th>status</th></tr>{''.join(rows)}</table></div>")


def steps_table(story: AutoStory, floor: float | None) -> str:
    """The automatic diagnosis step by step: what each step added and what it bought."""
    rows = []
    for k, st in enumerate(story.steps):
        what = "start" if st.effect is None else f"+ <code>{html.escape(st.effect)}</code>"
        about = (html.escape(st.explanation) if st.effect is not None else
                 "the model the diagnosis starts from: "
                 + effects_html(st.fit.error_model.labels))
        rows.append(
            f'<tr><td class="num">{k}</td><td class="nw">{what}</td>'
            f'<td class="num">{st.n_params}</td>'
            f'<td class="num">{fmt(st.calib_rms_mm)}</td>'
            f'<td class="num">{fmt(st.heldout_rms_mm)}</td>'
            f'<td class="num">{fmt(st.blocked_rms_mm)}</td>'
            f'<td class="num">{"" if st.seconds is None else f"{st.seconds:.1f}"}</td>'
            f"<td>{about}</td></tr>")
    final = story.final.heldout_rms_mm
    verdict = (f" The final held-out RMS is {final / floor:.2f} × the noise floor "
               f"({floor:.4f} mm)." if floor and final else "")
    src = (" Replayed from the steps recorded in the parameters file by "
           "<code>cellcal diagnose --auto</code>: every model refitted on these data."
           if story.recorded else "")
    return (
        '<div class="scroll"><table id="tab-steps"><caption>The automatic diagnosis: the '
        "best missing effect added at each step while the held-out error "
        f"({html.escape(story.heldout_method)}) falls by more than its standard error "
        "and the range-blocked error (the tenth of the poses at either end of each joint's "
        "range, predicted by the model refitted without them: what it does beyond the "
        f"data) does not rise.{src}</caption><tr><th>step</th><th>model</th>"
        "<th>params added</th><th>calibration RMS, mm</th><th>held-out RMS, mm</th>"
        "<th>range-blocked RMS, mm</th><th>time, s</th>"
        f"<th>what it is</th></tr>{''.join(rows)}</table></div>"
        f'<p class="rec">Stopped: {html.escape(story.stop_reason)}.{verdict}</p>')


_BEAM = {True: "along the beam", False: "across the beam", None: "unknown"}


def blunders_section(screens: list[tuple[str, BlunderScreen]],
                     reference: tuple[str, BlunderScreen | None] | None = None) -> str:
    """The measurements left out as blunders: one table over every fit's screen (a pose's
    numbers from the last screen that names it: the fit the diagnosis looks at), and that
    screen's verdict; ``reference`` (the uncalibrated fit's) only in a sentence."""
    ref = ""
    if reference is not None and reference[1] is not None and reference[1].excluded:
        ref = (f'<p class="meta">The {html.escape(reference[0])} reference fit left out '
               + ", ".join(html.escape(b.describe()) for b in reference[1].blunders)
               + ": its residuals are mostly the missing calibration, so its blunder test "
               "speaks only for that fit.</p>")
    named: dict[str, object] = {}
    left_out: dict[str, list[str]] = {}
    for label, sc in screens:
        for b in sc.blunders:
            named[b.pose_id] = b
            if sc.mode == "exclude":
                left_out.setdefault(b.pose_id, []).append(label)
    head = "<h2>Measurements left out (blunders)</h2>"
    if not screens:
        return head + "<p>No blunder test was made.</p>" + ref
    verdict = html.escape(screens[-1][1].message("fit", list_points=False))
    if not named:
        return head + f'<p id="blunders-none">{verdict}</p>' + ref
    verdict += _earlier_sentence(screens, named)
    everywhere = [label for label, _ in screens]
    rows = []
    for pid, b in named.items():
        where = left_out.get(pid, [])
        text = ("every fit" if where == everywhere else ", ".join(where)
                or "kept in the fit (only flagged)")
        rows.append(
            f"<tr><td><code>{html.escape(pid)}</code></td><td class=\"num\">{b.line or '–'}</td>"
            f'<td class="num">{b.residual_mm:.3f}</td><td class="num">{b.ratio:.1f}</td>'
            f"<td>{_BEAM[b.along_beam]}</td><td class=\"num\">{fmt(b.angle_deg, 0)}</td>"
            f"<td>{html.escape(text)}</td></tr>")
    return (
        head + f"<p>{verdict}</p>"
        '<div class="scroll"><table id="tab-blunders"><caption>Each blunder\'s residual is its '
        "distance from what the other poses predict; <i>× threshold</i>: how far beyond "
        "the out-of-line threshold it is; <i>beam</i>: whether the residual runs along the "
        "tracker's line of sight (a range error: a wrong return, a re-seated SMR) or across "
        "it (the robot not yet still, the beam clipped); <i>left out of</i>: the fits that "
        "named it. They are marked with orange crosses in the residual figures.</caption>"
        "<tr><th>pose</th><th>line</th><th>residual, mm</th><th>× threshold</th>"
        "<th>beam</th><th>angle to beam, °</th><th>left out of</th></tr>"
        f"{''.join(rows)}</table></div>{ref}")


def _earlier_sentence(screens: list[tuple[str, BlunderScreen]], named: dict) -> str:
    """The verdict is the last screen's (the fit the diagnosis looks at); the table lists
    every screen's blunders. A pose only an earlier fit named is said to be so, so that the
    sentence and the table agree (``No measurement is out of line`` above a table that
    lists one would contradict it)."""
    last = screens[-1][1]
    last_ids = {b.pose_id for b in last.blunders}
    earlier = [pid for pid in named if pid not in last_ids]
    if not earlier:
        return ""
    who = sorted({label for label, sc in screens[:-1] for b in sc.blunders
                  if b.pose_id in earlier}, key=[label for label, _ in screens].index)
    it = "it" if len(earlier) == 1 else "them"
    return html.escape(
        f" The table also lists {', '.join(earlier)}: only the fit of {' and of '.join(who)} "
        f"left {it} out (out of line with a model that still lacked an effect); the last "
        f"fit keeps {it}.")


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


def correlations_text(diag: Diagnosis) -> str:
    corr = diag.where.correlations
    if not corr:
        return ""
    items = ", ".join(f"{html.escape(k)} {v:+.2f}" for k, v in corr.items())
    return f" Spearman correlation of the error with: {items}."


HEAD = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>{css}</style></head><body><main>
"""

CSS = """
body{margin:0;background:#f6f7f9;color:#1d232a;font:14px/1.45 -apple-system,"Segoe UI",
Roboto,"Helvetica Neue",Arial,sans-serif}
main{max-width:1040px;margin:0 auto;padding:20px 28px 40px;background:#fff}
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
figcaption{font-size:12.5px;color:#39424c;max-width:800px;margin-top:4px}
.scroll{overflow-x:auto;max-width:100%}.nw{white-space:nowrap}
dl.prov{display:grid;grid-template-columns:max-content 1fr;gap:1px 14px;font-size:12.5px;
color:#39424c;margin:6px 0 4px}
dl.prov dt{color:#5b6470}dl.prov dd{margin:0;overflow-wrap:anywhere}
code.hash{font-size:11.5px}
h3{font-size:14.5px;margin:20px 0 4px}
@media (max-width:860px){main{padding:12px 12px 30px}h1{font-size:19px}
.card{min-width:0;flex:1 1 40%;padding:6px 10px}.card .big{font-size:22px}
.arrow{display:none}table{font-size:12px}th,td{padding:3px 5px}}
"""
