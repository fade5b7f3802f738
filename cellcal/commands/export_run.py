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

from .common import positive_int
from .parsers import command_parser


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
    from ..usecases.export_run import ExportRequest, export_run

    res = export_run(ExportRequest.from_args(args))
    if res.text is not None:
        sys.stdout.write(res.text)
    else:
        print(written(res, args.out), file=sys.stderr)
    return 0


def written(res, out: str) -> str:
    """``run 3: 120/120 points written to data.csv``: what an export wrote, and what it
    left out."""
    if res.postures:
        return (f"run {res.run_id}: {res.rows} postures written to {out} (tips in the "
                f"{res.tip_frame} frame)")
    note = "" if res.status == "completed" else f" (run is {res.status})"
    what = f"{res.rows}/{res.n_points} points"
    if res.rejected is not None:
        what = (f"{res.rows - res.rejected}/{res.n_points} points and {res.rejected} rejected "
                "readings")
    if res.unresolved:
        note += (f" ({res.unresolved} unresolved point(s) left out: their readings agree "
                 "neither with each other nor with the model)")
    return f"run {res.run_id}: {what} written to {out}{note}"
