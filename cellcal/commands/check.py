"""``cellcal check --params params.json NEW.csv``: is the robot still as accurate as its
calibration says? The given model's error on new poses, exactly as calibrated (nothing
refitted but, when asked or when the data are in another measurement frame, the
tracker-to-base transform), judged against ``--tolerance-mm`` and recorded in the robot's
history with ``--db`` (:mod:`cellcal.usecases.check`)."""

from __future__ import annotations

from .common import add_model_args, positive_float, print_json, print_note
from .parsers import command_parser


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "check",
        help="a calibration's error on new poses, as calibrated",
        description="The error of a calibration (params.json) on newly measured poses, "
        "exactly as calibrated: RMS, mean, p95, max and every pose's error, the worst named. "
        "No parameter is refitted but the tracker-to-base transform, and that only with "
        "--refit-base or when the data recorded another measurement frame than the "
        "calibration's (the tracker was moved); the output says what was refitted. Every "
        "row of the file is checked (a set column is not looked at). The figures are split "
        "inside and outside the calibrated envelope (the ranges the calibration data covered, "
        "params.json envelope), and each pose beyond it is named with what lies beyond "
        "(outside_range).\n\n"
        "Exit codes: 0 done (within --tolerance-mm when given), 1 the RMS error is beyond "
        "--tolerance-mm, 2 bad input, 3 data the check cannot use (docs/formats.md §6).",
    )
    add_model_args(p)
    p.add_argument("--params", required=True, metavar="params.json",
                   help="the calibration to check (from `cellcal calibrate --out`)")
    p.add_argument("--tolerance-mm", type=positive_float, default=None, metavar="T",
                   help="exit 1 when the RMS error on the new poses exceeds T mm, naming the "
                   "poses beyond it")
    p.add_argument("--refit-base", action="store_true",
                   help="refit the tracker-to-base transform (the base effect) to the new "
                   "poses first, every other parameter held: the tracker stood elsewhere")
    p.add_argument("--db", metavar="cell.db|URL",
                   help=f"record the check in the robot's history ({DB_HELP}; made when "
                   "missing), shown by `cellcal history` beside the calibrations")
    p.add_argument("--robot-id", metavar="NAME",
                   help="the robot checked (default with --db: the robot_id the data were "
                   "exported with)")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.check_text import check_summary, check_text

    from ..usecases.check import CheckRequest, check

    request = CheckRequest.from_args(args)

    def summary(done):
        return check_summary(done.result, done.frame, done.refit_reason, params=request.params,
                             calibration_stats=done.calibration_stats,
                             tolerance_mm=request.tolerance_mm, within=done.within_tolerance,
                             notes=done.notes)

    done = check(request, on_note=print_note, summary=summary)
    if args.json:
        out = summary(done)
        if done.recorded is not None:
            out["recorded"] = done.recorded
        print_json(out)
    else:
        print(check_text(done.result, done.frame, done.refit_reason, params=request.params,
                         calibration_stats=done.calibration_stats,
                         tolerance_mm=request.tolerance_mm, within=done.within_tolerance,
                         recorded=done.recorded, db=request.db))
    return 1 if done.within_tolerance is False else 0
