"""``cellcal resume [RUN]``: continue a paused, stopped or killed run where it left off.

The points already stored are skipped, the rest are done; the plan comes from
the store (its hash is checked). The devices are reached with the URLs stored
in the run, or with ``--robot``/``--tracker`` when given. A run found still
``running`` (its process was killed) gets a ``killed`` interruption first.
Exit codes as ``cellcal capture``.
"""

from __future__ import annotations

import sys

from ..cli import UsageError
from .capture import (
    EXEC_FLAGS,
    ConnectFailed,
    add_common,
    confirm_motion,
    open_drivers,
    options_from_args,
    report,
    run_executor,
)


def register(sub) -> None:
    p = sub.add_parser("resume", help="continue an interrupted run (default: the latest)",
                       description=__doc__.splitlines()[0])
    p.add_argument("run_id", nargs="?", type=int, default=None, metavar="RUN")
    add_common(p, resume=True)
    for flag, _, typ, hlp in EXEC_FLAGS:
        p.add_argument(flag, type=typ, default=None, help=hlp)
    p.set_defaults(func=run)


def run(args) -> int:
    from calibration import ModelError, load_model

    from ..plans import Plan
    from ..store import StoreError
    from .common import open_store

    store = open_store(args.db, synchronous=args.synchronous)
    try:
        try:
            r = store.run(args.run_id)
        except StoreError as e:
            raise UsageError(str(e)) from None
        plan = Plan.from_json(r.plan_json)
        if plan.hash != r.plan_hash:
            raise UsageError(f"run {r.id}: stored plan does not match its hash (edited store?)")
        if r.status == "completed":
            n = store.n_samples(r.id)
            print(f"run {r.id} is already completed ({n}/{r.n_points} points)", file=sys.stderr)
            return 0
        if r.status == "running":
            store.add_interruption(r.id, None, "killed",
                                   "found still running on resume: the process was killed or "
                                   "crashed")
        try:
            model = load_model(r.model or plan.model)
            if r.options.get("tool_mm") is not None:
                model = model.with_changes(tool=tuple(r.options["tool_mm"]))
        except ModelError as e:
            raise UsageError(f"run {r.id}: model {r.model!r}: {e}") from None
        robot_url = args.robot or r.robot_url
        tracker_url = args.tracker or r.tracker_url
        if not robot_url or not tracker_url:
            raise UsageError(f"run {r.id}: no stored URLs; pass --robot and --tracker")
        confirm_motion([robot_url, tracker_url], args.yes)
        options = options_from_args(args, r.options)
        try:
            robot, tracker = open_drivers(robot_url, tracker_url)
        except ConnectFailed as e:
            store.add_interruption(r.id, None, "connection", f"resume: cannot connect: {e}")
            print(f"cellcal resume: cannot connect: {e}", file=sys.stderr)
            return 1
        try:
            if robot_url != r.robot_url or tracker_url != r.tracker_url:
                store.update_run(r.id, robot_url=robot_url, tracker_url=tracker_url)
            done = store.n_samples(r.id)
            if not args.json:
                print(f"run {r.id}: resuming {r.routine}, {done}/{r.n_points} points stored",
                      file=sys.stderr)
            store.add_interruption(r.id, None, "resume", f"resumed with {done}/{r.n_points} "
                                   "points stored")
            _, out = run_executor(store, r.id, plan, robot, tracker, options, model, args)
        finally:
            robot.close()
            tracker.close()
        return report(out, args)
    finally:
        store.close()
