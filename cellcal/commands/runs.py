"""``cellcal runs``: list the runs in a run store (or show one with its context,
interruptions and the readings it did not accept).

The list counts each run's interruptions, its beam breaks, the points skipped because
the beam stayed broken (see :mod:`daq.executor`) and ``remeasured``: the points whose
reading was out of line with the running model and re-measured (:mod:`daq.remeasure`);
``--json`` gives every re-measure count under ``remeasure``.
"""

from __future__ import annotations

from .common import positive_int
from .parsers import command_parser


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "runs", help="list the runs in a run store, or show one",
        description="List the runs of a run store (id, routine, status, points stored, "
        "model, robot id, start time, interruptions, beam breaks, points skipped, points "
        "re-measured, why it stopped; --robot-id: only that robot's); "
        "with RUN, show that run: its devices, context (tool, SMR, measurement frame, "
        "tracker checks, executor settings), summary and interruptions.")
    p.add_argument("run_id", nargs="?", type=positive_int, default=None, metavar="RUN",
                   help="show this run in detail, with its interruptions")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--robot-id", metavar="NAME", default=None, help="only this robot's runs")
    p.add_argument("--json", action="store_true",
                   help="print JSON (a list of runs, or one run with its context)")
    p.set_defaults(func=run)


def run(args) -> int:
    from presentation import run_listing as view

    from ..usecases.runs import RunListing, RunsRequest, read_runs
    from .common import print_json, table

    found = read_runs(RunsRequest.from_args(args))
    if isinstance(found, RunListing):
        if args.json:
            print_json(found.runs)
        else:
            print(table(view.runs_rows(found.runs, found.kinds), view.RUNS_HEADER,
                        left=view.RUNS_LEFT))
        return 0
    d = found.doc
    if args.json:
        print_json(d)
        return 0
    print("\n".join(view.run_lines(d, found.executor_defaults)))
    summary = view.summary_rows(d)
    if summary:
        print()
        print(table(summary, ["summary", "value"], left=(0, 1)))
    print()
    if not d["interruptions"]:
        print("interruptions: none")
    else:
        print(table(view.interruption_rows(d["interruptions"]), view.INTERRUPTIONS_HEADER,
                    left=view.INTERRUPTIONS_LEFT))
    for line in view.rejected_lines(d["rejected_readings"]):
        print(line)
    for line in view.drift_lines(d.get("drift_checks", [])):
        print(line)
    return 0
