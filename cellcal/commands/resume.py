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
air), not its two faces. A run that ended ``incomplete`` is not resumed: its skipped
points are named (exit 3). Exit codes as ``cellcal capture`` (docs/formats.md §6).
"""

from __future__ import annotations

import sys

from ..flags.capture_flags import EXEC_FLAGS, add_common, add_flag_table, add_tracker_flags
from ..flags.routine_args import ACQUIRE_FLAGS
from .common import positive_int
from .motion_prompt import confirm_with
from .parsers import command_parser


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
    add_flag_table(p, EXEC_FLAGS + ACQUIRE_FLAGS)
    p.add_argument("--other-cell", action="store_true",
                   help="the robot or tracker given is not the run's (another model or "
                   "serial number): start a new run of the same plan with them instead of "
                   "refusing")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..logs import RunLog

    with RunLog(args) as run_log:
        return _run(args, run_log)


def _run(args, run_log) -> int:
    from ..usecases.resume import ResumeArgs, resume
    from .run_outcome import print_outcome, with_progress

    req = ResumeArgs.from_args(args)

    def started(r, run_id: int, done: int) -> None:
        run_log.open(req.db, run_id)
        if args.json:
            return
        if run_id != r.id:
            print(f"run {run_id}: the plan of run {r.id} ({r.routine}, {r.n_points} "
                  "points) in another cell", file=sys.stderr)
        else:
            print(f"run {run_id}: resuming {r.routine}, {done}/{r.n_points} points "
                  "stored", file=sys.stderr)

    result, failed = with_progress("resume", args.json, lambda progress: resume(
        req, progress=progress, on_started=started, confirm=confirm_with(args.yes)))
    if failed is not None:
        return failed
    if result.outcome is None:
        r = result.resumable.run
        if not result.resumable.completed:  # incomplete: nothing to resume, say what is missing
            print(f"run {r.id} is {r.status} ({result.resumable.done}/{r.n_points} points), "
                  f"nothing to resume: {r.reason}", file=sys.stderr)
            return 3
        print(f"run {r.id} is already completed ({result.resumable.done}/{r.n_points} points)",
              file=sys.stderr)
        return 0
    return print_outcome(result.outcome, args.json, run_log.path)
