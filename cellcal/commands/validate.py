"""``cellcal validate``: a program's waypoints (or a targets CSV) run on the cell as
written, compensated and with the calibrated DH table alone; the tracker measures where
the tool went (a run of the ``validate`` routine: resumable with ``cellcal resume``).

Exit codes (docs/formats.md §6): 0 the run completed; 1 it paused or failed, or the
devices cannot be reached; 2 bad input (a program that does not parse, no frame run in
the store, a plan refused by the dry run); 3 a waypoint the tracker would not see; 130
stopped with Ctrl-C (resumable).
"""

from __future__ import annotations

import sys

from ..flags.capture_flags import (
    EXEC_FLAGS,
    add_common,
    add_flag_table,
    add_plan_flags,
    add_sight_flags,
    add_tracker_flags,
)
from ..flags.program_flags import add_program_flags
from ..flags.routine_args import ROUTINE_ARGS
from .motion_prompt import confirm_with
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "validate",
        help="run a program's waypoints as written and compensated; measure the error",
        description="Run the waypoints of a robot program (URScript, KUKA KRL .dat, ABB "
        "RAPID .mod) or of a targets CSV (x, y, z and q1..qN nominal joints, deg) on the "
        "cell, by joint moves: as the nominal controller runs the program as written, as it "
        "runs the program compensated with the calibration (cellcal compensate --program), "
        "and as a controller that carries only the calibration's DH deltas (a UR's "
        "calibration.conf; 'geometry only' on an ABB) runs it. The tracker measures every "
        "waypoint; the run is stored (resumable) and its summary gives each variant's error, "
        "ISO 9283 AP per waypoint and RP with --cycles 2 or more, beside the calibration's "
        "validation RMS. Needs a frame run in --db "
        "(cellcal capture frame). docs/programs.md.\n\n"
        "Waypoints beyond the calibrated envelope (the ranges the calibration measured) are "
        "named in the notes; --strict-range refuses them (exit 3).\n\n"
        "Exit codes: 0 completed; 1 paused or failed, or the devices cannot be reached; 2 "
        "bad input, no frame run, a plan refused by the dry run; 3 a waypoint the tracker "
        "would not see, or beyond the envelope with --strict-range; 130 stopped with Ctrl-C "
        "(resumable) (docs/formats.md §6).",
    )
    p.add_argument("targets", metavar="TARGETS.csv", nargs="?",
                   help="targets to run instead of a program (x, y, z, q1..qN deg)")
    p.add_argument("--params", required=True, metavar="params.json",
                   help="the calibration (`cellcal calibrate --out`)")
    add_program_flags(p, program_help="the robot program whose waypoints run "
                      "(URScript .script, KUKA KRL .dat, ABB RAPID .mod)")
    p.add_argument("--start", metavar="Q1,..,QN",
                   help="joints (deg) near which a program's first pose targets are solved "
                   "when no joint target comes before them")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (repeatable)")
    p.add_argument("--strict-range", action="store_true",
                   help="refuse waypoints beyond the calibrated envelope (the joint ranges "
                   "the calibration data covered): exit 3, nothing run; without it they "
                   "run and are named in the notes")
    ROUTINE_ARGS["validate"].add(p)
    add_common(p)
    add_plan_flags(p)
    add_sight_flags(p)
    add_flag_table(p, EXEC_FLAGS)
    add_tracker_flags(p)
    p.set_defaults(func=run, routine="validate")


def run(args) -> int:
    from ..logs import RunLog

    with RunLog(args) as run_log:
        return _run(args, run_log)


def _run(args, run_log) -> int:
    from presentation.run_outcome import outcome_exit_code, outcome_lines
    from presentation.validation_text import validation_lines, validation_summary

    from ..usecases.capture import CaptureArgs
    from ..usecases.validate import ValidateRequest, validate
    from .capture import print_dry_run
    from .common import print_json, print_note
    from .run_outcome import with_progress

    request = ValidateRequest.from_args(args)
    capture_args = CaptureArgs.from_args(args, model="(the calibration's)")

    def started(run_id: int, _done: int) -> None:
        run_log.open(capture_args.db, run_id)
        if not args.json:
            print(f"run {run_id}: validate, plan stored", file=sys.stderr)

    done, failed = with_progress("validate", args.json, lambda progress: validate(
        request, capture_args, progress=progress, on_started=started,
        confirm=confirm_with(args.yes)))
    if failed is not None:
        return failed
    if done.outside_range:
        print(f"warning: {len(done.outside_range)} of {done.n_waypoints} waypoints lie beyond "
              "the calibrated envelope (see the notes)", file=sys.stderr)
    if done.result.outcome is None:
        print_dry_run(done.result, args.json)
        for note in done.notes:  # what will not run, the thermal state, the frame
            print_note(note)
        return 0
    out = done.result.outcome.to_json()
    summary = out.get("summary") or {}
    if args.json:
        print_json({**out, **validation_summary(summary, done.valid_rms_mm, done.n_waypoints,
                                                done.notes),
                    "log": None if run_log.path is None else str(run_log.path),
                    "outside_range": done.outside_range})
    else:
        print("\n".join(outcome_lines(out)
                        + validation_lines(summary, done.valid_rms_mm, done.notes,
                                         robot=capture_args.robot)))
    return outcome_exit_code(out)
