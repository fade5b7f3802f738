"""``cellcal resume [RUN]``: continue a paused, stopped or killed run where it left off.

The points already stored are skipped, the rest are done; the plan comes from
the store (its hash is checked). The devices are reached with the URLs stored
in the run, or with ``--robot``/``--tracker`` when given; they must be the run's
cell (the robot's and the tracker's model and serial number as stored with the
run): another cell is refused (exit 2) unless ``--other-cell``, which starts a
NEW run of the same plan there instead of mixing the two cells' samples. A run
still executed by a live process is refused at once (exit 2, naming it); a run
found ``running`` whose process is gone (killed) gets a ``killed`` interruption
first. The tracker is checked again with the run's setup (``--meteo`` replaces its
air), not its two faces. Exit codes as ``cellcal capture`` (docs/formats.md §6).
"""

from __future__ import annotations

import sys

from ..cli import command_parser
from .capture import (
    EXEC_FLAGS,
    add_common,
    add_tracker_flags,
    check_urls,
    confirm_motion,
    executor_options,
    flag_values,
    metavar,
    run_and_report,
    tracker_setup,
)
from .common import positive_int
from .routine_args import ROUTINE_ARGS

#: every routine's acquisition flags (given, they apply to a run of that routine)
ACQUIRE_FLAGS = [f for spec in ROUTINE_ARGS.values() for f in spec.acquire_flags]


def register(sub) -> None:
    p = command_parser(
        sub, "resume", help="continue an interrupted run (default: the latest)",
        description="Continue a paused, stopped or killed run where it left off: the points "
        "already stored are skipped, the rest are done; the plan comes from the store (its "
        "hash is checked). The devices are reached with the URLs stored in the run, or "
        "with --robot/--tracker when given. A run found still running (its process was "
        "killed) gets a `killed` interruption first. Flags given override the stored "
        "settings for this session. Exit codes as `cellcal capture` (docs/formats.md §6).")
    p.add_argument("run_id", nargs="?", type=positive_int, default=None, metavar="RUN",
                   help="the run to continue (default: the latest run of the store)")
    add_common(p, resume=True)
    add_tracker_flags(p, resume=True)
    for flag, _, typ, hlp in EXEC_FLAGS + ACQUIRE_FLAGS:
        p.add_argument(flag, type=typ, default=None, help=hlp, metavar=metavar(typ))
    p.add_argument("--other-cell", action="store_true",
                   help="the robot or tracker given is not the run's (another model or "
                   "serial number): start a new run of the same plan with them instead of "
                   "refusing")
    p.set_defaults(func=run)


def run(args) -> int:
    from daq.service import prepare_resume, resume_run
    from daq.store.leases import Leases

    from ..cli import UsageError
    from .common import open_store

    executor_options(flag_values(args, EXEC_FLAGS))  # checked before anything else
    check_urls(args.robot, args.tracker)
    store = open_store(args.db, synchronous=args.synchronous)
    try:
        with Leases(store) as leases:
            res = prepare_resume(store, args.run_id, robot_url=args.robot,
                                 tracker_url=args.tracker, leases=leases,
                                 robot_id=args.robot_id)
            r = res.run
            if res.completed:
                print(f"run {r.id} is already completed ({res.done}/{r.n_points} points)",
                      file=sys.stderr)
                return 0
            try:
                setup = tracker_setup(args, r.context.tracker.model_dump())
            except ValueError as e:
                raise UsageError(str(e)) from None

            def started(run_id: int, done: int) -> None:
                if args.json:
                    return
                if run_id != r.id:
                    print(f"run {run_id}: the plan of run {r.id} ({r.routine}, {r.n_points} "
                          "points) in another cell", file=sys.stderr)
                else:
                    print(f"run {run_id}: resuming {r.routine}, {done}/{r.n_points} points "
                          "stored", file=sys.stderr)

            return run_and_report("resume", args.json, lambda progress: resume_run(
                store, res, executor=flag_values(args, EXEC_FLAGS),
                acquire=flag_values(args, ROUTINE_ARGS[r.routine].acquire_flags),
                tracker_setup=setup, progress=progress, on_started=started, leases=leases,
                other_cell=args.other_cell, confirm=lambda cell, robot, tracker:
                confirm_motion(cell, [robot, tracker], args.yes)))
    finally:
        store.close()
