"""``cellcal export [RUN]``: write a run's samples as a measurement CSV (docs/formats.md §1).

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
(docs/formats.md §1): ``pose_id``, ``plane`` (from the plan), ``q1..qN`` (deg, as
read), ``x y z`` (the measured tips, mm: in the robot base frame when the run
knows its measurement frame, else in the tracker frame, said by a
``# xyz_frame: tracker`` comment), read by ``cellcal zero``.

Only the accepted reading of each point is written. ``--all-readings`` adds the
readings the capture did not accept (a suspect that was re-measured,
:mod:`daq.remeasure`), each with its point's ``pose_id``, and two columns:
``reading`` (``accepted`` or ``rejected``) and ``reason``. ``cellcal calibrate``
leaves the rejected rows out. A point whose readings the capture could not
resolve (none agreed with another or with the model) has no accepted reading:
it is left out (rejected, with ``--all-readings``).
"""

from __future__ import annotations

import sys

from ..cli import UsageError, command_parser
from .common import check_outputs, positive_int


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "export", help="write a run's samples as a measurement CSV",
        description="Write a run's samples as a measurement CSV (docs/formats.md §1), read "
        "directly by `cellcal calibrate`, `diagnose` and `report`. Columns: pose_id, q1..qN "
        "(deg, as read), x y z (mm, tracker frame), cmd_x/y/z (the controller's TCP, when "
        "known for every point), temp_c, t_s, sigma_mm, dir1..dirN (approach directions), "
        "set (when some rows are validation rows).\n\n"
        "The `# key: value` header carries the run's context: run, store, model, tool_mm "
        "(the controller's TCP: the nominal tool of later fits), robot_id, smr_radius_mm, "
        "frame_run and tracker_T_base (the measurement frame), tracker_sigma_mm, URLs, "
        "software.")
    p.add_argument("run_id", nargs="?", type=positive_int, default=None, metavar="RUN",
                   help="run id (default: the latest)")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--out", required=True, metavar="data.csv", help="CSV to write ('-': stdout)")
    p.add_argument("--postures", action="store_true",
                   help="a zero20 run: write the zero-point postures CSV (pose_id, plane, "
                   "q1..qN, x, y, z) for `cellcal zero`")
    p.add_argument("--sigma-mode", choices=("std", "mean"), default="std",
                   help="sigma_mm from the tracker's std (default) or std/sqrt(n)")
    p.add_argument("--all-readings", action="store_true",
                   help="also the readings the capture rejected (re-measured suspects), with "
                   "columns reading (accepted/rejected) and reason")
    p.set_defaults(func=run)


def run(args) -> int:
    from daq.run_data import dataset_from_run
    from daq.store import StoreError

    from .common import open_store, store_errors

    check_outputs({"--out": args.out}, [args.db], stdout=True)
    store = open_store(args.db, read_only=True)
    with store, store_errors(args.db):
        if args.postures:
            return _postures(store, args)
        try:
            r = store.run(args.run_id)
            extra = None
            if args.all_readings:
                data, reading, reason = dataset_from_run(store, r.id, sigma_mode=args.sigma_mode,
                                                         all_readings=True)
                extra = {"reading": reading, "reason": reason}
            else:
                data = dataset_from_run(store, r.id, sigma_mode=args.sigma_mode)
        except StoreError as e:
            raise UsageError(str(e)) from None
        text = data.to_csv(None if args.out == "-" else args.out, extra=extra)
        if args.out == "-":
            sys.stdout.write(text)
        else:
            note = "" if r.status == "completed" else f" (run is {r.status})"
            what = f"{data.n}/{r.n_points} points"
            if extra is not None:
                n_rej = extra["reading"].count("rejected")
                what = f"{data.n - n_rej}/{r.n_points} points and {n_rej} rejected readings"
            unresolved = store.remeasure_counts(r.id)["unresolved"]
            if unresolved:
                note += (f" ({unresolved} unresolved point(s) left out: their readings agree "
                         "neither with each other nor with the model)")
            print(f"run {r.id}: {what} written to {args.out}{note}", file=sys.stderr)
        return 0


def _postures(store, args) -> int:
    """Write a zero20 run's postures CSV (docs/formats.md §1)."""
    from daq.run_data import postures_from_run
    from daq.store import StoreError

    try:
        post, r = postures_from_run(store, args.run_id)  # default: the latest zero20
    except StoreError as e:
        raise UsageError(str(e)) from None
    from daq.run_data import run_meta

    meta = {"run": r.id, "routine": r.routine, **run_meta(store, r), "plan_hash": r.plan_hash,
            "robot": r.robot_url or "", "tracker": r.tracker_url or ""}
    text = post.to_csv(None if args.out == "-" else args.out, meta=meta)
    if args.out == "-":
        sys.stdout.write(text)
    else:
        print(f"run {r.id}: {post.n} postures written to {args.out} (tips in the "
              f"{post.tip_frame} frame)", file=sys.stderr)
    return 0
