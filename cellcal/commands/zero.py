"""``cellcal zero``: zero-point recalibration from 20 postures on one fixed point.

The postures come from a postures CSV (docs/formats.md §1) or straight from the run
store (``--db cell.db [--run N]``: a ``zero20`` capture, default the latest
completed one; planes from the plan, joints as read, tips as measured).

Two-pass flow of the seed method (a second, fine pass after a manual adjustment)::

    cellcal capture zero20 --target-xyz X,Y,Z ... --db cell.db      # run 1
    cellcal zero --db cell.db --params params.json --json > first_pass.json   # first pass
    # apply first_pass.json's offsets at the controller (its joint zeros)
    cellcal capture zero20 --replay 1 ... --db cell.db              # the same 20 postures
    cellcal zero --db cell.db --params params.json --replay first_pass.json   # fine pass

The fine pass starts from the first pass's offsets and reports what remains to
correct relative to the adjusted controller's readings: about 0 when the
adjustment took.

Exit codes (docs/formats.md §6): 0 the recalibration is decided (within tolerance),
3 the data are too poor to decide (an offset that matters is undetermined, the
uncertainty exceeds the tolerance, the residual is far above the tip scatter, or no
convergence), 2 bad input.
"""

from __future__ import annotations

from .common import positive_float, positive_int, print_json, print_note, seed_int, table
from .parsers import command_parser

#: tip scatter per axis of taught postures, mm (:data:`calibration.zero_point.DEFAULT_SIGMA_MM`,
#: kept equal by tests/cellcal/test_cli_help.py)
DEFAULT_SIGMA_MM = 0.02

_EPILOG = """two-pass flow (seed method: a second, fine pass after a manual adjustment):

  cellcal capture zero20 --target-xyz X,Y,Z ... --db cell.db    # run 1
  cellcal zero --db cell.db --params params.json --json > first_pass.json
  (apply first_pass.json's offsets to the controller's joint zeros)
  cellcal capture zero20 --replay 1 ... --db cell.db            # same postures, loop again
  cellcal zero --db cell.db --params params.json --replay first_pass.json   # remaining ~0
"""


def register(sub) -> None:
    p = command_parser(
        sub, "zero",
        help="recalibrate joint zero offsets from 20 postures on one point",
        description="Estimate joint zero corrections (true = reported + offset) from "
        "postures that all put the tool tip on one fixed point (a zero-point postures CSV, "
        "docs/formats.md §1, or a zero20 run in the store with --db): the published seed "
        "method and a rigorous least-squares method.\n\n"
        "The measured tips make joint 1 and the last joint determinable only in the robot "
        "base frame: give --params from a calibration of the same cell (its base pose); "
        "without it they stay undetermined and, when they matter, the status is poor (exit "
        "3). The nominal tool is the capture's (the run's --tool-mm, or the CSV's `# "
        "tool_mm:` line).\n\n"
        "Exit 0 when decided, 3 when the data are too poor to decide, 2 for bad input "
        "(docs/formats.md §6).",
        epilog=_EPILOG,
    )
    p.add_argument("postures", metavar="POSTURES.csv", nargs="?", default=None,
                   help="zero-point postures CSV (or --db)")
    p.add_argument("--db", metavar="cell.db|URL",
                   help="read the postures from a zero20 run in this run store (a SQLite file "
                   "or a postgresql:// URL) instead of a CSV")
    p.add_argument("--run", type=positive_int, default=None, metavar="N",
                   help="with --db: the zero20 run (default: the latest completed one)")
    p.add_argument("--robot-id", metavar="NAME", default=None,
                   help="with --db: the latest completed zero20 run of this robot")
    p.add_argument("--model", default=None, metavar="NAME|PATH",
                   help="built-in model name or a model YAML file (default: the run's model, "
                   "or the CSV's `# model:` line)")
    p.add_argument("--params", metavar="params.json",
                   help="a calibration of the cell (geometric deltas; its base pose puts the "
                   "measured tips in the robot base frame)")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (needed when the "
                   "calibration in --params used one; repeatable)")
    p.add_argument("--method", choices=("seed", "rigorous", "both"), default="both",
                   help="seed (published), rigorous, or both compared (default; the "
                   "rigorous result is reported)")
    p.add_argument("--tolerance-deg", type=positive_float, default=0.01, metavar="T",
                   help="a joint changed when |offset| > T; decided when 2 sigma < T "
                   "(default 0.01)")
    p.add_argument("--sigma", type=positive_float, default=DEFAULT_SIGMA_MM, metavar="MM",
                   help=f"tip scatter per axis (teaching repeatability), mm "
                   f"(default {DEFAULT_SIGMA_MM})")
    p.add_argument("--replay", metavar="previous.json",
                   help="fine pass: start from a previous `zero --json` result (after "
                   "applying its offsets at the controller and recapturing the same postures "
                   "with `capture zero20 --replay RUN`, the result is the remaining "
                   "correction, about 0)")
    p.add_argument("--keep-outliers", action="store_true",
                   help="do not leave out postures with improbable residuals")
    p.add_argument("--seed", type=seed_int, default=0,
                   help="random seed of the seed method's resampling (default 0: the same "
                   "result every time)")
    p.add_argument("--out", metavar="FILE",
                   help="write the updated model (.yaml) or params (.json, needs --params); "
                   "never the input file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation.zero_text import ZERO_HEADER, zero_head, zero_rows, zero_tail

    from ..usecases.zero import ZeroRequest, recalibrate_zero

    res = recalibrate_zero(ZeroRequest.from_args(args), note=print_note)
    if args.json:
        print_json(res.doc)
    else:
        print("\n".join(zero_head(res.doc, res.main, res.results)))
        print()
        print(table(zero_rows(res.doc, res.main, res.results.get("seed")), ZERO_HEADER))
        print()
        print("\n".join(zero_tail(res.doc, res.main, res.out)))
    return 0 if res.decided else 3
