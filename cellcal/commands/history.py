"""``cellcal history ROBOT --db STORE``: a robot's calibrations over time.

Reads the calibrations recorded with ``cellcal calibrate ... --db STORE --robot-id ROBOT``
and prints: the calibrations (when their data were measured, UTC; source; effects;
RMS), one line per parameter (first and last value ± std, net change, the largest
change between consecutive calibrations in combined standard uncertainties, a trend
line), every change larger than ``--sigma`` (default 3) combined sigma
(sqrt(σ1² + σ2²), :mod:`calibration.diagnosis.history`), the value over time with its
uncertainty of the parameters that changed (or of those named with ``--param``), and the
robot's accuracy on new poses over time (its checks, ``cellcal check ... --db STORE``).
``--plot FILE.html|FILE.png`` draws the trends; ``--json`` prints one object
(docs/formats.md §4).

Exit codes (docs/formats.md §6): 0 done (whether or not a change was flagged), 2 bad
input (no such store or robot). The work is :mod:`cellcal.usecases.history`'s, the text
:mod:`presentation.history_text`'s.
"""

from __future__ import annotations

from .common import positive_float
from .parsers import command_parser

#: flag a change larger than this many combined sigma
#: (:data:`calibration.diagnosis.history.DEFAULT_SIGMA`,
#: kept equal by tests/cellcal/test_cli_help.py)
DEFAULT_SIGMA = 3.0


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "history", help="a robot's calibrations over time: drift and changes",
        description="A robot's calibrations, recorded with `cellcal calibrate ... --db STORE "
        "--robot-id ROBOT`, over time: the calibrations (when their data were measured, "
        "UTC; source; effects; RMS), one line per parameter (first and last value ± std, "
        "net change, the largest change between consecutive calibrations in combined "
        "standard uncertainties, a trend line), every change larger than --sigma combined "
        "sigma (sqrt(σ1² + σ2²)), and the value over time of the parameters that changed "
        "(or of those named with --param), and the accuracy on new poses over time (the "
        "checks recorded with `cellcal check ... --db STORE`). The store is opened "
        "read-only (docs/history.md)."
        "\n\nExit codes: 0 done (whether or not a change was flagged), 2 bad input (no "
        "such store or robot); docs/formats.md §6.")
    p.add_argument("robot_id", metavar="ROBOT", help="the robot (as given with --robot-id)")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--param", action="append", default=[], metavar="GLOB",
                   help="print the value over time of these parameters (repeatable; "
                   "shell-style patterns, e.g. 'geometric.j2.*'; default: those that changed)")
    p.add_argument("--sigma", type=positive_float, default=DEFAULT_SIGMA, metavar="K",
                   help=f"flag a change larger than K combined sigma (default {DEFAULT_SIGMA:g})")
    p.add_argument("--plot", metavar="FILE.html|FILE.png",
                   help="draw the trends of the parameters printed (all when none)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.history_text import history_summary, history_text

    from ..usecases.history import HistoryRequest, robot_history
    from .common import print_json

    request = HistoryRequest.from_args(args)
    h = robot_history(request)
    if args.json:
        out = history_summary(request.robot_id, h.calibrations, h.summaries, h.histories,
                              request.sigma, h.checks)
        if request.plot:
            out["plot"] = request.plot
        print_json(out)
        return 0
    print(history_text(request.robot_id, h.address, h.calibrations, h.summaries,
                       h.histories, h.shown, request.sigma, h.checks))
    if request.plot:
        print()
        print(f"trends drawn in {request.plot}")
    return 0
