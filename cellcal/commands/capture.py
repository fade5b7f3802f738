"""``cellcal capture ROUTINE``: make a plan, dry-run it, and run it into the run store.

Before the run is stored the tracker is set up and checked (:mod:`daq.tracker_checks`):
``--reflector``, ``--meteo``, the ready gate and the two-face check.

Before anything moves: the options are checked (exit 2), the plan is dry-run, the robot's
lease is taken (another live process using the robot: exit 2, naming it), the devices
are connected and say who they are, the robot's joint count (and a simulator's robot
model) must be the model's (exit 2), and unless both devices declared themselves
simulators the motion must be confirmed (``--yes``, or typing ``yes`` at a terminal).

Exit codes (docs/formats.md §6): 0 the run completed; 1 it paused (protective stop,
rejected command, retries exhausted, a move refused or not done, the run store
unreachable) or failed, or the devices cannot be reached; 2 bad input, a plan refused by
the dry run (the offending points are named), a busy robot or run, the wrong robot, the
motion not confirmed, a tracker that fails its checks (the check and what to do are
named; nothing is stored), a tracker position unknown (unless ``--no-visibility``); 3 a
plan the tracker would not see enough of, or a run that ended ``incomplete`` (more than
a tenth of its points skipped: :mod:`daq.completeness`); 130 stopped
with Ctrl-C (the run is resumable with ``cellcal resume``); 128 + N stopped at once by
signal N (a second Ctrl-C 130, SIGTERM 143, SIGHUP 129: the controller's stop was sent
and the run is ``paused``).
"""

from __future__ import annotations

import sys

from ..flags.capture_flags import (
    EXEC_FLAGS,
    add_common,
    add_flag_table,
    add_plan_flags,
    add_sight_flags,
    add_thermal_flags,
    add_tracker_flags,
)
from ..flags.routine_args import ROUTINE_ARGS
from .motion_prompt import confirm_motion, confirm_with
from .parsers import add_subcommands, command_parser

__all__ = ["confirm_motion", "register", "run"]


def register(sub) -> None:
    p = command_parser(
        sub, "capture",
        help="run a capture routine into the run store",
        description="Make a routine's plan, dry-run it against the model (joint limits, "
        "reach, floor), then move and measure point by point; every sample is committed to "
        "the run store (a SQLite file or PostgreSQL) at once. Resume an interrupted run with "
        "`cellcal resume`. `cellcal capture ROUTINE --help` describes a routine and its "
        "options.\n\n"
        "Exit codes: 0 completed; 1 paused (protective stop, rejected command, retries "
        "exhausted, run store unreachable) or failed, or the devices cannot be reached; 2 "
        "bad input, a plan refused by the dry run (the offending points are named) or "
        "anything else refused before the run is stored (a tracker position unknown among "
        "them); 3 a plan the tracker would not see enough of, or a run that ended "
        "incomplete (more than a tenth of its points skipped); 130 stopped with Ctrl-C "
        "(resumable); 128 + N stopped at once by signal N (docs/formats.md §6).",
    )
    rsub = add_subcommands(p, "routine", "ROUTINE")
    for name, spec in ROUTINE_ARGS.items():
        if spec.command is not None:  # run by a command of its own (cellcal validate)
            continue
        r = command_parser(rsub, name, help=spec.summary,
                           description=spec.summary[0].upper() + spec.summary[1:] + "\n\n"
                           + spec.description)
        r.add_argument("--model", required=True, metavar="NAME|PATH",
                       help="the robot model: a built-in name (see `cellcal models`) or a "
                       "model YAML file (recorded with the run)")
        add_common(r)
        r.add_argument("--tool-mm", metavar="X,Y,Z", default=None,
                       help="the controller's TCP in the flange frame, mm (overrides the "
                       "model's tool; recorded with the run, exported as `# tool_mm:` and "
                       "the nominal tool of every later fit)")
        r.add_argument("--smr-radius-mm", type=float, default=None, metavar="MM",
                       help="radius of the SMR (recorded; default: the reflector's, when the "
                       "tracker reports it)")
        r.add_argument("--seed", type=int, default=None,
                       help="random seed of the plan (recorded; default 0)")
        add_plan_flags(r)
        r.add_argument("--tracker-at", metavar="X,Y,Z", default=None,
                       help="where the tracker head stands, robot base frame, mm (rough is "
                       "fine; default: from the latest frame run in --db, else --cell)")
        add_sight_flags(r)
        r.add_argument("--plot", metavar="PNG", default=None,
                       help="draw the plan: robot, SMR positions, tracker and beams")
        add_flag_table(r, EXEC_FLAGS + ROUTINE_ARGS[name].acquire_flags)
        add_tracker_flags(r)
        add_thermal_flags(r)
        spec.add(r)
        r.set_defaults(func=run)


def run(args) -> int:
    from ..logs import RunLog

    with RunLog(args) as run_log:
        return _run(args, run_log)


def _run(args, run_log) -> int:
    from ..usecases.capture import CaptureArgs, capture
    from .run_outcome import print_outcome, with_progress

    req = CaptureArgs.from_args(args)
    plan = None

    def planned(result) -> None:
        nonlocal plan
        plan = result.planned.plan
        if args.json:
            return
        if req.plot:
            print(f"wrote {req.plot}", file=sys.stderr)
        sight = result.planned.sight
        if not req.dry_run and (sight.hidden or not sight.checked):
            print(f"cellcal capture: note: {sight.report(limit=5)}", file=sys.stderr)

    def started(run_id: int, _done: int) -> None:
        run_log.open(req.db, run_id)
        if not args.json:
            print(f"run {run_id}: {plan.routine}, {plan.n_planned} points, plan "
                  f"{plan.hash[:16]}", file=sys.stderr)

    result, failed = with_progress("capture", args.json, lambda progress: capture(
        req, on_planned=planned, progress=progress, on_started=started,
        confirm=confirm_with(args.yes)))
    if failed is not None:
        return failed
    if result.outcome is not None:
        return print_outcome(result.outcome, args.json, run_log.path)
    print_dry_run(result, args.json)
    return 0


def print_dry_run(result, as_json: bool) -> None:
    """The plan, its dry run, what the tracker would see and the estimated time."""
    from daq.sight import format_time

    from .common import print_json

    if as_json:
        print_json(result.dry_run_json())
        return
    plan = result.planned.plan
    spares = len(plan) - plan.n_planned
    print(f"{plan.routine}: {plan.n_planned} points"
          f"{f' (+ {spares} spares)' if spares else ''}, plan {plan.hash[:16]}")
    print(result.planned.check.report())
    print(result.planned.sight.report())
    print(format_time(result.estimate))
