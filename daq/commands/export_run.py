"""``cellcal export [RUN]``: write a run's samples as a measurement CSV (FORMATS.md §1).

Columns: ``pose_id``, ``q1..qN`` (deg, as read from the controller), ``x y z``
(mm, tracker frame), ``cmd_x/y/z`` (the controller's nominal TCP, when the robot
reported it for every point), ``temp_c``, ``t_s``, ``sigma_mm``, ``pressure_hpa``,
``humidity_pct``, ``reflector``, ``face`` (what the tracker said of each
measurement, when it said it for every point), ``dir1..dirN`` (approach direction
of each joint from the previous commanded pose), ``set`` (when some rows are
validation rows). ``sigma_mm`` is the RMS over the axes
of the tracker's reported per-axis std (``--sigma-mode std``, default) or
that divided by sqrt(n) (``--sigma-mode mean``). The result is read directly
by ``cellcal calibrate`` and ``cellcal diagnose``.

``--postures`` (a ``zero20`` run) writes the zero-point postures CSV instead
(FORMATS.md §1): ``pose_id``, ``plane`` (from the plan), ``q1..qN`` (deg, as
read), ``x y z`` (the measured tips, mm: in the robot base frame when the run
knows its measurement frame, else in the tracker frame, said by a
``# xyz_frame: tracker`` comment), read by ``cellcal zero``.
"""

from __future__ import annotations

import sys

from ..cli import UsageError


def register(sub) -> None:
    from .common import DB_HELP

    p = sub.add_parser("export", help="write a run's samples as a measurement CSV",
                       description=__doc__.splitlines()[0])
    p.add_argument("run_id", nargs="?", type=int, default=None, metavar="RUN",
                   help="run id (default: the latest)")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--out", required=True, metavar="data.csv", help="CSV to write ('-': stdout)")
    p.add_argument("--postures", action="store_true",
                   help="a zero20 run: write the zero-point postures CSV (pose_id, plane, "
                   "q1..qN, x, y, z) for `cellcal zero`")
    p.add_argument("--sigma-mode", choices=("std", "mean"), default="std",
                   help="sigma_mm from the tracker's std (default) or std/sqrt(n)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..run_data import dataset_from_run
    from ..store import StoreError
    from .common import open_store

    store = open_store(args.db)
    try:
        if args.postures:
            return _postures(store, args)
        try:
            r = store.run(args.run_id)
            data = dataset_from_run(store, r.id, sigma_mode=args.sigma_mode)
        except StoreError as e:
            raise UsageError(str(e)) from None
        text = data.to_csv(None if args.out == "-" else args.out)
        if args.out == "-":
            sys.stdout.write(text)
        else:
            note = "" if r.status == "completed" else f" (run is {r.status})"
            print(f"run {r.id}: {data.n}/{r.n_points} points written to {args.out}{note}",
                  file=sys.stderr)
        return 0
    finally:
        store.close()


def _postures(store, args) -> int:
    """Write a zero20 run's postures CSV (FORMATS.md §1)."""
    from ..run_data import postures_from_run
    from ..store import StoreError

    try:
        post, r = postures_from_run(store, args.run_id)  # default: the latest zero20
    except StoreError as e:
        raise UsageError(str(e)) from None
    meta = {"run": r.id, "routine": r.routine, "plan_hash": r.plan_hash, "model": r.model or "",
            "robot": r.robot_url or "", "tracker": r.tracker_url or ""}
    text = post.to_csv(None if args.out == "-" else args.out, meta=meta)
    if args.out == "-":
        sys.stdout.write(text)
    else:
        print(f"run {r.id}: {post.n} postures written to {args.out} (tips in the "
              f"{post.tip_frame} frame)", file=sys.stderr)
    return 0
