"""``cellcal compensate``: joints and corrected Cartesian targets that make the real robot
reach target points, from a calibration (params.json); exports of the calibrated model
(:mod:`cellcal.usecases.compensate`, :mod:`cellcal.usecases.model_exports`)."""

from __future__ import annotations

import sys

from ..flags.choices import JOINTS_TOLERANCE_MM
from .common import print_json
from .compensate_program import add_flags as add_program_flags
from .compensate_program import run_program, uses_program
from .parsers import command_parser


def register(sub) -> None:
    p = command_parser(
        sub, "compensate",
        help="compensate target points with a calibrated model",
        description="For target points of the tool in the robot base frame (CSV: x, y, z "
        "in mm required; optional pose_id, q1..qN nominal joints in deg, dir1..dirN "
        "approach directions, temp_c, payload_kg) compute the joints that reach them on "
        "the real robot and the corrected Cartesian targets (nominal FK of those joints) "
        "for a controller that only knows its nominal model. The nominal model is the "
        "calibration's, with the capture's tool (the controller's TCP). Optionally export "
        "the calibrated model (YAML) or UR deltas.\n\n"
        "Targets without nominal joints get them by inverse kinematics on the nominal "
        "model, from --start (default: a few standard postures, the first that reaches "
        "wins). Exit 0 when every target is reached, 1 otherwise, 2 for bad input "
        "(docs/formats.md §6).\n\n"
        "A calibration with drift effects compensates for the thermal state each target "
        "gives (joint_temp1..N, t_s, temp_c columns), else for its warm state (the end of its "
        "capture); the output says which.\n\n"
        "A target whose joints (or thermal state) lie beyond the ranges the calibration "
        "measured (its envelope) is named in the outside_range column and --json, and "
        "counted on stderr; --strict-range refuses it (exit 3).",
    )
    p.add_argument("targets", metavar="TARGETS.csv", nargs="?",
                   help="target points (omit to only export)")
    p.add_argument("--params", required=True, metavar="params.json",
                   help="the calibration (`cellcal calibrate --out`)")
    p.add_argument("--effect-file", action="append", default=[], metavar="FILE.py",
                   help="load user-defined effects from a Python file (needed when the "
                   "calibration used one; repeatable)")
    p.add_argument("--out", metavar="compensated.csv",
                   help="write the compensated targets (default: print them)")
    p.add_argument("--start", metavar="Q1,..,QN",
                   help="start configuration (deg) for targets without nominal joints")
    p.add_argument("--joints-tolerance-mm", type=float, default=JOINTS_TOLERANCE_MM,
                   metavar="MM", help="refuse targets whose joints q1..qN put the tool "
                   f"farther than this from their x, y, z on the nominal model (default "
                   f"{JOINTS_TOLERANCE_MM:g} mm)")
    p.add_argument("--position-only", action="store_true",
                   help="minimum-norm position correction; do not hold the nominal "
                   "orientation")
    p.add_argument("--export-model", metavar="FILE.yaml",
                   help="write the calibrated kinematics as a model YAML")
    p.add_argument("--export-ur", metavar="calibration.conf",
                   help="write UR calibration.conf deltas (standard-DH models)")
    p.add_argument("--export-urdf", metavar="FILE.urdf",
                   help="write the calibrated kinematics as a URDF ending in a link 'tcp' at "
                   "the measured point (checked by loading it with yourdfpy)")
    p.add_argument("--export-ur-yaml", metavar="FILE.yaml",
                   help="write the UR ROS driver's kinematics YAML (ur_description "
                   "kinematics_params_file, with its hash)")
    p.add_argument("--export-dh", metavar="FILE.csv",
                   help="write the calibrated DH/MDH table as CSV (units in the header)")
    p.add_argument("--strict-range", action="store_true",
                   help="refuse targets beyond the calibrated envelope (the joint ranges, "
                   "and temperatures or times where the model uses them, that the "
                   "calibration data covered; params.json `envelope`): exit 3, nothing "
                   "written. Without it they are compensated, flagged in the CSV's "
                   "outside_range column and counted on stderr")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    add_program_flags(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if uses_program(args):
        return run_program(args)
    from presentation.compensation_text import (
        compensation_summary,
        compensation_text,
        export_lines,
        outside_warning,
    )
    from presentation.thermal_text import state_line

    from ..usecases.compensate import CompensateRequest, compensate_targets

    request = CompensateRequest.from_args(args)
    done = compensate_targets(request)
    exports = done.exports
    rc = 0 if done.result is None or done.result.success.all() else 1
    warning = outside_warning(done.outside, where="the outside_range column"
                              + (" and --json" if args.json else ""))
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        summary = compensation_summary(
            params_file=request.params, model=done.model, capture=done.capture,
            notes=done.notes, exports=exports.files if exports else None,
            not_exported=exports.not_exported if exports else None, t=done.targets,
            c=done.result, out_file=request.out, outside=done.outside)
        if done.thermal is not None:
            summary["thermal_state"] = done.thermal
        print_json(summary)
        return rc
    if done.targets is not None:
        print(compensation_text(done.model, done.capture, request.targets, done.targets,
                                done.result, done.notes, done.outside))
        if done.thermal is not None:
            print(f"thermal   {state_line(done.thermal)}")
        if request.out:
            print(f"written   {request.out}")
        else:
            print(done.csv_text, end="")
    # beside compensated targets on stdout, the export report goes to stderr
    stream = sys.stderr if request.targets and not request.out else sys.stdout
    for line in export_lines(exports.files, exports.not_exported) if exports else ():
        print(line, file=stream)
    return rc
