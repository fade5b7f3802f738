"""``cellcal resume [RUN]``: continue a paused, stopped or killed run where it left off.

The points already stored are skipped, the rest are done; the plan comes from
the store (its hash is checked). The devices are reached with the URLs stored
in the run, or with ``--robot``/``--tracker`` when given. A run found still
``running`` (its process was killed) gets a ``killed`` interruption first.
Exit codes as ``cellcal capture``.
"""

from __future__ import annotations

import sys

from .capture import EXEC_FLAGS, add_common, confirm_motion, flag_values, run_and_report
from .routine_args import ROUTINE_ARGS

#: every routine's acquisition flags (given, they apply to a run of that routine)
ACQUIRE_FLAGS = [f for spec in ROUTINE_ARGS.values() for f in spec.acquire_flags]


def register(sub) -> None:
    p = sub.add_parser("resume", help="continue an interrupted run (default: the latest)",
                       description=__doc__.splitlines()[0])
    p.add_argument("run_id", nargs="?", type=int, default=None, metavar="RUN")
    add_common(p, resume=True)
    for flag, _, typ, hlp in EXEC_FLAGS + ACQUIRE_FLAGS:
        p.add_argument(flag, type=typ, default=None, help=hlp)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..service import prepare_resume, resume_run
    from .common import open_store

    store = open_store(args.db, synchronous=args.synchronous)
    try:
        res = prepare_resume(store, args.run_id, robot_url=args.robot, tracker_url=args.tracker,
                             robot_id=args.robot_id)
        r = res.run
        if res.completed:
            print(f"run {r.id} is already completed ({res.done}/{r.n_points} points)",
                  file=sys.stderr)
            return 0
        confirm_motion([res.robot_url, res.tracker_url], args.yes)

        def started(run_id: int, done: int) -> None:
            if not args.json:
                print(f"run {run_id}: resuming {r.routine}, {done}/{r.n_points} points "
                      "stored", file=sys.stderr)

        return run_and_report("resume", args.json, lambda progress: resume_run(
            store, res, executor=flag_values(args, EXEC_FLAGS),
            acquire=flag_values(args, ROUTINE_ARGS[r.routine].acquire_flags), progress=progress,
            on_started=started))
    finally:
        store.close()
