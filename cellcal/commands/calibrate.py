"""``cellcal calibrate``: identify a robot's error parameters from a measurement CSV."""

from __future__ import annotations

from ..flags.choices import DEFAULT_EFFECTS, OUTLIER_MODES, SOLVERS, solver_help
from .common import add_model_args, bounded_int, print_json, print_note, seed_int
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "calibrate",
        help="identify error parameters from measured poses",
        description="Fit the robot's error model to a measurement CSV and report the "
        "parameters, their uncertainties and the remaining error, on the calibration rows "
        "and on the validation rows (set=valid, or --valid FILE).\n\n"
        "The nominal tool is the capture's (the CSV's `# tool_mm:` line, written by "
        "`cellcal export` from the capture's --tool-mm), so params.json describes the "
        "robot as its controller knows it; --out keeps the capture's metadata with the "
        "parameters (params.json `capture`). Exit 0 converged, 1 not converged, 2 bad "
        "input, 3 data too poor to fit (docs/formats.md §6).",
    )
    add_model_args(p)
    p.add_argument("--effects", default=DEFAULT_EFFECTS, metavar="LIST",
                   help=f"comma-separated effects (default {DEFAULT_EFFECTS}; names in "
                   "docs/formats.md §3, e.g. geometric,base,tool,compliance:2)")
    p.add_argument("--solver", default="lm", choices=list(SOLVERS), metavar="SOLVER",
                   help=solver_help())
    p.add_argument("--valid", metavar="FILE", help="validation CSV (besides set=valid rows)")
    p.add_argument("--params", metavar="params.json",
                   help="start from these parameters (those of the same name; a table of "
                   "the same name also keeps its smoothing)")
    p.add_argument("--out", metavar="params.json", help="write the parameters here")
    p.add_argument("--seed", type=seed_int, default=None,
                   help="random seed of the besa/sa solvers and of --monte-carlo (default 0)")
    p.add_argument("--monte-carlo", type=bounded_int(0, 100_000), default=0, metavar="N",
                   help="re-identify N times from the calibrated model plus instrument noise "
                   "(sigma from the data or --sigma) and report the parameter spread and the "
                   "position uncertainty over the workspace")
    p.add_argument("--outliers", choices=OUTLIER_MODES, default="exclude",
                   help="measurements far out of line with the rest (blunders): exclude them "
                   "from the fit and name them (default), flag: fit every point but name "
                   "them, keep: fit every point, no test")
    p.add_argument("--ridge-plot", metavar="FILE.png",
                   help="with --solver ridge: save the L-curve, GCV and ridge trace here")
    p.add_argument("--db", metavar="cell.db|URL",
                   help="record the calibration (its params.json) in this run store, a SQLite "
                   "file or a postgresql:// URL, for `cellcal history` (needs --robot-id "
                   "unless the data name their robot)")
    p.add_argument("--robot-id", metavar="NAME",
                   help="the robot calibrated (default with --db: the robot_id the data were "
                   "exported with)")
    p.add_argument("--position-only", action="store_true",
                   help="fit positions only, even when the rows have orientations (qw..qz of "
                   "a 6-DoF target): the orientation error is then only predicted")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.calibration_text import calibration_text, recorded_line
    from presentation.summaries import calibration_summary

    from ..usecases.calibrate import CalibrateRequest, calibrate

    request = CalibrateRequest.from_args(args)
    result = calibrate(request, on_note=print_note)
    fit = result.fit
    if args.json:
        out = calibration_summary(fit, result.baseline, params_file=request.out, mc=result.mc,
                                  ridge_plot=request.ridge_plot, blindness=result.blindness)
        if request.db:
            out["calibration"] = result.recorded
        print_json(out)
    else:
        print(calibration_text(fit, result.baseline, request.out, result.mc,
                               request.ridge_plot))
        if request.db:
            print()
            print(recorded_line(result.recorded, request.db))
    return 0 if fit.converged else 1
