"""``cellcal diagnose``: where the model fails, and which missing effect explains it."""

from __future__ import annotations

from ..cli import command_parser
from .common import (
    add_current_model_args,
    add_model_args,
    check_data,
    current_model,
    fmt,
    load_inputs,
    positive_int,
    print_json,
    print_note,
    print_outliers,
    table,
    tool_text,
    wrap_errors,
)
from .diagnose_auto import add_auto_args, check_auto_args, run_auto


def register(sub) -> None:
    p = command_parser(
        sub, "diagnose",
        help="rank the physical effects missing from the model",
        description="Fit the current model (or read --params), then rank every candidate "
        "effect not in it by how much of the remaining error it explains, with a "
        "significance test against the noise and a held-out check; say which effect to add. "
        "With --auto, add the best effect, refit and repeat while the held-out error falls.",
    )
    add_model_args(p)
    add_current_model_args(p, "use these parameters (and their model) instead of fitting")
    p.add_argument("--top", type=positive_int, default=12, metavar="N",
                   help="rows of the ranking to print (default 12)")
    add_auto_args(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from calibration.diagnosis import diagnose
    from calibration.workflow import current_fit

    check_auto_args(args)
    model, data = load_inputs(args)
    em, params, notes = current_model(args, model)
    for n in notes + check_data(em, data):
        print_note(n)
    fit = wrap_errors(lambda: current_fit(model, data, args.effects, params, args.solver))
    if args.auto:
        return run_auto(args, fit, data)
    diag = diagnose(fit, data)
    if args.json:
        print_json(diag.to_json())
        return 0
    print_diagnosis(diag, args.top, tool_text(fit.error_model.model, data, args.params))
    return 0


def print_diagnosis(diag, top: int = 12, tool: str | None = None) -> None:
    """The ranking as tables (``diag``: a :class:`calibration.diagnosis.Diagnosis`;
    ``tool``: what :func:`~cellcal.commands.common.tool_text` says)."""
    fit = diag.fit
    floor = diag.noise_floor_mm
    print(f"model     {fit.error_model.model.name}, " + (f"{tool}, " if tool else "")
          + f"effects {','.join(fit.error_model.labels)}")
    print(f"error     RMS {diag.rms_mm:.4f} mm over {fit.data.n} calibration poses"
          + (f"; noise floor {floor:.4f} mm" if floor else "; noise floor unknown (--sigma)"))
    print(f"screened  {diag.n_screened} candidate effects in {diag.screen_s:.2f} s; "
          f"best refitted and checked on held-out poses in {diag.confirm_s:.2f} s")
    print_outliers(diag.outliers, "ranking")
    print()
    rows = []
    for c in diag.candidates[:top]:
        held = (f"{c.heldout_before_mm:.4f} -> {c.heldout_after_mm:.4f}"
                if c.heldout_after_mm is not None else "")
        rows.append([c.effect, c.n_params, f"{100 * c.explained_fraction:.1f}",
                     fmt(c.refit_rms_mm or c.rms_after_mm, 4), f"{c.log10_p:.0f}",
                     "yes" if c.significant else "no", held])
    print(table(rows, ["candidate", "params", "explains %", "rms after", "log10 p",
                       "significant", "held-out rms mm"]))
    print()
    print(diag.recommendation())
    if diag.best is not None:
        print(f"next:     --effects {diag.next_effects()}")
    w = diag.where
    print()
    print("worst poses: " + ", ".join(f"{p} (line {line}) {e:.3f} mm" for p, line, e in w.worst))
    strong = {k: v for k, v in w.correlations.items() if abs(v) >= 0.3}
    if strong:
        print("error correlates with: " + ", ".join(f"{k} ({v:+.2f})" for k, v in strong.items()))
    for note in diag.notes + fit.notes:
        print(f"note: {note}")
