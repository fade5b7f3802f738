"""``cellcal report``: one self-contained HTML page showing where the model fails and what
fixed it (uncalibrated → current model → current plus the recommended effect, or with
``--auto`` every step of the automatic diagnosis), with its provenance (software, date,
data file and SHA-256, capture run, model) (:mod:`cellcal.usecases.report`)."""

from __future__ import annotations

from .common import add_current_model_args, add_model_args, print_json, print_note
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "report",
        help="write an HTML report with plots: where the model fails, what fixed it",
        description="Fit the uncalibrated robot (nominal kinematics, best-fit base and tool), "
        "the current model and, when the diagnosis finds a significant missing effect, the "
        "current model plus that effect; write one self-contained HTML page (plots "
        "embedded) with the before/after error statistics, residual plots, the blunders "
        "left out, the candidate ranking and the parameters. Prints one line per model "
        "(RMS on the calibration and validation rows), the recommendation and the file "
        "written. With --auto, the automatic diagnosis (as `diagnose --auto`) adds effects "
        "one at a time and the page shows the error falling step by step; a --params file "
        "written by `diagnose --auto --out` shows its recorded steps.",
    )
    add_model_args(p)
    add_current_model_args(p, "use these parameters (and their model) as the current model")
    p.add_argument("--auto", action="store_true",
                   help="run the automatic diagnosis from the current model and show every "
                   "step (as `cellcal diagnose --auto`)")
    p.add_argument("--max-steps", type=int, default=12, metavar="N",
                   help="with --auto: add at most N effects (default 12)")
    p.add_argument("--budget-s", type=float, default=None, metavar="S",
                   help="with --auto: stop after S seconds, keeping the steps accepted")
    p.add_argument("--title", default=None, help="the page's heading")
    p.add_argument("--out", default="report.html", metavar="FILE.html",
                   help="where to write the page (default report.html)")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.report_summary import report_summary, report_text

    from ..usecases.report import ReportRequest, write_report

    written = write_report(ReportRequest.from_args(args), on_note=print_note)
    if args.json:
        print_json(report_summary(written.report, written.out, written.size,
                                  written.provenance))
    else:
        print(report_text(written.report, written.out, written.size))
    return 0
