"""``cellcal diagnose``: where the model fails, and which missing effect explains it; with
``--auto``, add missing effects one at a time while the held-out error falls
(:mod:`cellcal.usecases.diagnose`)."""

from __future__ import annotations

from .common import (
    add_current_model_args,
    add_model_args,
    positive_float,
    positive_int,
    print_json,
    print_note,
)
from .parsers import command_parser


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
    g = p.add_argument_group("automatic diagnosis")
    g.add_argument("--auto", action="store_true",
                   help="add the best candidate, refit, and repeat while the held-out error "
                   "(validation rows, else cross-validation) falls by more than its "
                   "standard error; print the steps and why it stopped")
    g.add_argument("--max-steps", type=positive_int, default=12, metavar="N",
                   help="with --auto: add at most N effects (default 12)")
    g.add_argument("--budget-s", type=positive_float, default=None, metavar="S",
                   help="with --auto: stop after S seconds, keeping the steps accepted")
    g.add_argument("--out", metavar="params.json",
                   help="with --auto: write the final model's parameters here (as calibrate)")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.calibration_text import tool_text
    from presentation.diagnosis_text import (
        auto_header,
        auto_step_line,
        auto_text,
        diagnosis_text,
    )

    from ..usecases.diagnose import DiagnoseRequest, diagnose

    request = DiagnoseRequest.from_args(args)
    steps = []

    def on_step(step) -> None:  # each accepted step as it comes (text only)
        steps.append(step)
        print(auto_step_line(len(steps), step), flush=True)

    text = not args.json
    result = diagnose(request, on_note=print_note,
                      on_start=(lambda fit, given: print(auto_header(fit, given, request.params)))
                      if text else None,
                      on_step=on_step if text else None)
    if result.auto is not None:
        if args.json:
            print_json(result.auto.to_json(request.out))
        else:
            print()
            print(auto_text(result.auto, request.out))
    elif args.json:
        from presentation.summaries import diagnosis_summary

        print_json(diagnosis_summary(result.diagnosis, result.given, request.params))
    else:
        print(diagnosis_text(result.diagnosis, request.top,
                             tool_text(result.fit.error_model.model, result.data,
                                       request.params), result.given, request.params))
    return 0
