"""The text ``cellcal diagnose`` prints: the ranking of the effects missing from the model
(:func:`diagnosis_text`) and, with ``--auto``, the start (:func:`auto_header`), one line
per step as it is accepted (:func:`auto_step_line`) and the steps taken
(:func:`auto_text`).

Every function returns text (lines joined by newlines) and prints nothing.
"""

from __future__ import annotations

from calibration.diagnosis.auto_diagnosis import AutoDiagnosis, AutoStep
from calibration.diagnosis.diagnosis import Diagnosis
from calibration.fit.identify import Fit
from calibration.fit.model_check import ModelCheck

from .calibration_text import blunder_lines
from .orientation_text import orientation_lines
from .text_table import fmt, table


def given_lines(given: ModelCheck | None, params: str | None, auto: bool = False) -> list[str]:
    """With ``--params``: the given model's own error first (nothing refitted), and that
    the figures below are of a refit (``auto``: the steps start from one)."""
    if given is None:
        return []
    s = given.stats
    then = ("the steps start from it" if auto else "then what it leaves is ranked")
    return [f"given     RMS {s['rms_mm']:.4f} mm (max {s['max_mm']:.4f} mm) over {s['n']} "
            f"calibration poses: the model of {params} as calibrated, nothing refitted "
            "(`cellcal check` for the whole check)",
            "refit     the figures below are of a refit: every parameter of that model "
            f"refitted on these poses (warm-started from it); {then}"]


def diagnosis_text(diag: Diagnosis, top: int = 12, tool: str | None = None,
                   given: ModelCheck | None = None, params: str | None = None) -> str:
    """The ranking as tables: the ``top`` candidates, the recommendation, the worst poses
    and what the error correlates with (``tool``: what
    :func:`~presentation.calibration_text.tool_text` says); with ``given`` (the model of
    ``--params`` checked as calibrated, :func:`given_lines`) its own error first."""
    fit = diag.fit
    floor = diag.noise_floor_mm
    lines = [
        f"model     {fit.error_model.model.name}, " + (f"{tool}, " if tool else "")
        + f"effects {','.join(fit.error_model.labels)}",
        *given_lines(given, params),
        f"error     RMS {diag.rms_mm:.4f} mm over {fit.data.n} calibration poses"
        + (" (refitted)" if given is not None else "")
        + (f"; noise floor {floor:.4f} mm" if floor else "; noise floor unknown (--sigma)"),
        f"screened  {diag.n_screened} candidate effects in {diag.screen_s:.2f} s; "
        f"best refitted and checked on held-out poses in {diag.confirm_s:.2f} s",
        *blunder_lines(diag.outliers, "ranking"),
        "",
    ]
    rows = []
    for c in diag.candidates[:top]:
        held = (f"{c.heldout_before_mm:.4f} -> {c.heldout_after_mm:.4f}"
                if c.heldout_after_mm is not None else "")
        rows.append([c.effect, c.n_params, f"{100 * c.explained_fraction:.1f}",
                     fmt(c.refit_rms_mm or c.rms_after_mm, 4), f"{c.log10_p:.0f}",
                     "yes" if c.significant else "no", held])
    lines += [table(rows, ["candidate", "params", "explains %", "rms after", "log10 p",
                           "significant", "held-out rms mm"]), "", diag.recommendation()]
    if diag.best is not None:
        lines.append(f"next:     --effects {diag.next_effects()}")
    w = diag.where
    lines += ["", "worst poses: " + ", ".join(f"{p} (line {line}) {e:.3f} mm"
                                              for p, line, e in w.worst)]
    strong = {k: v for k, v in w.correlations.items() if abs(v) >= 0.3}
    if strong:
        lines.append("error correlates with: "
                     + ", ".join(f"{k} ({v:+.2f})" for k, v in strong.items()))
    lines += orientation_lines(fit)
    lines += [f"note: {note}" for note in diag.notes + fit.notes]
    return "\n".join(lines)


def auto_header(fit: Fit, given: ModelCheck | None = None, params: str | None = None) -> str:
    """The start of ``diagnose --auto``: the model, the given model's own error (with
    ``--params``: :func:`given_lines`), the data, the noise floor, the blunders the start
    fit left out."""
    em = fit.error_model
    valid_n = fit.valid["n"] if fit.valid else 0
    floor = fit.data.noise_floor_mm()
    lines = [f"model     {em.model.name}, start effects {','.join(em.labels)}",
             *given_lines(given, params, auto=True),
             f"data      {fit.data.n} calibration poses"
             + (f", {valid_n} validation poses" if valid_n else ""),
             "floor     " + (f"noise floor {floor:.4f} mm" if floor
                             else "noise floor unknown (--sigma)"),
             *blunder_lines(fit.outliers, "ranking")]
    return "\n".join(lines)


def auto_step_line(number: int, step: AutoStep) -> str:
    """One accepted step, as it happens (``number`` from 1)."""
    beyond = ("" if step.blocked_rms_mm is None
              else f", range-blocked {step.blocked_rms_mm:.4f} mm")
    return (f"step {number:>2}  {step.effect:<14} held-out RMS {step.heldout_rms_mm:.4f} mm"
            f"{beyond}  ({step.seconds:.1f} s)")


def auto_text(result: AutoDiagnosis, out: str | None) -> str:
    """The steps of an automatic diagnosis, why it stopped, the final effects (``out``:
    the params.json written)."""
    start = result.start
    rows = [[" 0 (start) " + ",".join(start.error_model.labels), "",
             fmt(start.calib["rms_mm"], 4), fmt(result.start_heldout_rms_mm, 4),
             fmt(result.start_blocked_rms_mm, 4), ""]]
    for i, s in enumerate(result.steps, 1):
        rows.append([f"{i:>2} {s.effect}", str(s.n_params), fmt(s.calib_rms_mm, 4),
                     fmt(s.heldout_rms_mm, 4), fmt(s.blocked_rms_mm, 4), f"{s.seconds:.1f}"])
    lines = [table(rows, ["step, effect added", "params", "calib rms mm", "held-out rms mm",
                          "range-blocked rms mm", "time s"]),
             f"held-out error: {result.heldout_method}; range-blocked: the tenth of the "
             "poses at either end of each joint's range, predicted by the model refitted "
             "without them (what it does beyond the data)"]
    if result.steps:
        lines.append("")
        lines += [f"{i:>2}. {s.effect}: {s.explanation}" for i, s in enumerate(result.steps, 1)]
    lines += ["", f"stopped   {result.stop_reason}"]
    if result.rejected:
        lines.append("          last tried: " + ", ".join(f"{e} (held-out {h:.4f} mm)"
                                                          for e, h in result.rejected))
    floor = result.noise_floor_mm
    final = result.steps[-1].heldout_rms_mm if result.steps else result.start_heldout_rms_mm
    if floor:
        lines.append(f"          held-out RMS {final:.4f} mm is {final / floor:.2f} x the "
                     "noise floor")
    lines += [f"effects   {','.join(result.effects)}", f"time      {result.total_s:.1f} s"]
    if out:
        lines.append(f"wrote     {out}")
    lines += [f"note: {note}" for note in result.notes]
    return "\n".join(lines)
