"""The command-line options of each capture routine (``cellcal capture ROUTINE ...``).

:data:`ROUTINE_ARGS` maps a routine (:mod:`daq.routines`) to its :class:`RoutineArgs`:
``add(parser)`` declares the flags, ``params(args)`` turns the parsed arguments into the
routine's ``make_plan`` keyword arguments (a pure conversion: no I/O; a run a flag refers
to, like zero20's ``--replay RUN``, stays a reference the service resolves), and
``acquire_flags`` are the flags of the routine's acquisition options ``(flag, option,
type, help)``, given to ``capture`` and ``resume``. Common flags (``--seed``,
``--floor-z-mm``, ``--max-reach-mm``...) come from :mod:`cellcal.commands.capture`; the
executor's and the devices' from :mod:`cellcal.flags.capture_flags`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from .values import floats


@dataclass(frozen=True)
class RoutineArgs:
    """A routine's flags (``add``), their conversion (``params``), its acquisition flags,
    and what ``cellcal capture ROUTINE --help`` says about it: ``summary`` (one line, the
    routine module's docstring says the same) and ``description`` (plain text)."""

    add: Callable
    params: Callable
    summary: str
    description: str
    acquire_flags: list = field(default_factory=list)
    #: the command that runs the routine when it is not ``cellcal capture ROUTINE`` (its
    #: plan needs inputs a capture does not take: ``validate``, a calibration and a program)
    command: str | None = None


# ------------------------------------------------------------------ frame
_FRAME = ("Joint 1 alone turns through --circle-span-deg in --circle-points steps (the "
          "target traces a circle about the base Z axis), then the TCP moves along the base x "
          "axis alone, --line-points points over --line-length-mm centred on the start. The "
          "circle and the line give the robot base in the tracker frame (tracker_T_base), "
          "stored with the run: later runs of the store use it (zero20's closed loop, "
          "iso9283's accuracy, the export's `# tracker_T_base:` line).")


def _frame_add(p) -> None:
    p.add_argument("--start-deg", metavar="Q1,..,QN",
                   help="start posture, deg (default: a comfortable posture of the model)")
    p.add_argument("--circle-span-deg", type=float, default=90.0, metavar="DEG",
                   help="joint-1 turn, deg (default 90, at least 30: a narrower arc gives "
                   "the frame fit a poor circle)")
    p.add_argument("--circle-points", type=int, default=12, metavar="N",
                   help="points on the circle (default 12)")
    p.add_argument("--line-length-mm", type=float, default=300.0, metavar="MM",
                   help="length of the x line, mm (default 300)")
    p.add_argument("--line-points", type=int, default=11, metavar="N",
                   help="points on the line (default 11)")


def _frame_params(args) -> dict:
    from daq.routines.frame import MIN_CIRCLE_SPAN_DEG  # numpy: not at the parser's start-up

    if not args.circle_span_deg >= MIN_CIRCLE_SPAN_DEG:  # NaN too
        raise ValueError(f"--circle-span-deg: {args.circle_span_deg:g} is below the minimum "
                         f"{MIN_CIRCLE_SPAN_DEG:g} deg (a narrower arc gives the frame fit a "
                         "poor circle)")
    return {"start_deg": floats(args.start_deg, None, "--start-deg"),
            "circle_span_deg": args.circle_span_deg, "circle_points": args.circle_points,
            "line_length_mm": args.line_length_mm, "line_points": args.line_points}


# ------------------------------------------------------------------ steps
_STEPS = ("From the start point the TCP steps along x, then y, then z (linear moves): "
          "--count steps of --step-mm per axis, back at the start before each axis. Each "
          "sample records the controller's nominal TCP (cmd_x/y/z, what the teach pendant "
          "shows) next to the tracker's measurement: with the measurement frame their "
          "difference is the absolute positioning error.")


def _steps_add(p) -> None:
    p.add_argument("--start-xyz", metavar="X,Y,Z", help="start point, mm (base frame)")
    p.add_argument("--start-deg", metavar="Q1,..,QN", help="start posture / IK seed, deg")
    p.add_argument("--step-mm", type=float, default=20.0, metavar="MM",
                   help="step length, mm (default 20)")
    p.add_argument("--count", type=int, default=10, metavar="N",
                   help="steps per axis (default 10)")
    p.add_argument("--axes", default="xyz", metavar="AXES",
                   help="the axes to step along, in order (default xyz)")


def _steps_params(args) -> dict:
    return {"start_xyz": floats(args.start_xyz, 3, "--start-xyz"),
            "start_deg": floats(args.start_deg, None, "--start-deg"),
            "step_mm": args.step_mm, "count": args.count, "axes": args.axes}


# ----------------------------------------------------------------- zero20
_ZERO20 = ("20 postures, 5 on each of 4 vertical planes through the fixed point "
           "--target-xyz, each bringing the tool tip onto it: at each posture a closed loop "
           "corrects the joints until the tracker sees the tip on the target (fixed by the "
           "first posture) within --zero-tol-mm. Each correction approaches its joints from "
           "the same side (a small overshoot first), so backlash does not make the loop "
           "oscillate. `cellcal zero --db` then computes the joints' zero offsets; `--replay "
           "RUN` repeats the postures of run RUN for the fine second pass.")


def _zero20_add(p) -> None:
    p.add_argument("--target-xyz", metavar="X,Y,Z",
                   help="the fixed target point, mm (base frame); required unless --replay")
    p.add_argument("--seed-deg", metavar="Q1,..,QN",
                   help="preferred configuration, deg (default: the best-conditioned one)")
    p.add_argument("--replay", type=int, metavar="RUN", default=None,
                   help="replay the 20 postures recorded in run RUN of --db (their joints, "
                   "not re-solved), closing the loop again: the fine pass after a manual "
                   "adjustment of the joint zeros")


def _zero20_params(args) -> dict:
    if getattr(args, "replay", None) is not None:
        if args.target_xyz is not None or args.seed_deg is not None:
            raise ValueError("zero20: --replay takes the postures (and target) from the run; "
                             "drop --target-xyz/--seed-deg")
        return {"replay_run": args.replay}
    return {"target_xyz": floats(args.target_xyz, 3, "--target-xyz"),
            "seed_deg": floats(args.seed_deg, None, "--seed-deg"), "seed": args.seed or 0}


_ZERO20_ACQUIRE = [
    ("--zero-tol-mm", "tol_mm", float, "zero20: tip-on-target tolerance, mm (default 0.01; "
     "the loop also stops within 1.5x the measurement's 3-D std)"),
    ("--zero-average", "average", int,
     "zero20: tracker measurements averaged per step of the closed loop (default 1)"),
    ("--zero-approach-rad", "approach_rad", float,
     "zero20: each correction first moves every joint this far below its new position, so "
     "it approaches from the same side (backlash), rad (default 0.002; 0: straight)"),
]


def _max_reach(p) -> None:
    p.add_argument("--max-reach-mm", type=float, default=None, metavar="MM",
                   help="keep the tool point within this distance of the base, mm")


# ------------------------------------------------------------------ poses
_POSES = ("Random poses within the joint limits, above the floor and within "
          "--max-reach-mm; --method optimal picks them greedily from a candidate pool, each "
          "time the one that most increases the observability of --effects (D-optimal "
          "design). A fraction --valid-fraction of the poses (random) is marked set=valid: "
          "`cellcal calibrate` reports the error on them separately.")


def _poses_add(p) -> None:
    p.add_argument("--count", type=int, default=100, metavar="N",
                   help="number of poses (default 100)")
    p.add_argument("--method", choices=("random", "optimal"), default="random",
                   help="random (default) or optimal (D-optimal from a candidate pool)")
    p.add_argument("--valid-fraction", type=float, default=0.0, metavar="F",
                   help="fraction of the poses marked set=valid, 0..1 (default 0)")
    p.add_argument("--effects", default="geometric,base,tool", metavar="LIST",
                   help="with --method optimal: the error model whose observability is "
                   "maximised (default geometric,base,tool)")
    p.add_argument("--pool", type=int, default=None, metavar="N",
                   help="with --method optimal: candidate pool size (default 5 x the "
                   "calibration poses, 50 to 3000)")
    _max_reach(p)


def _poses_params(args) -> dict:
    return {"count": args.count, "seed": args.seed or 0, "method": args.method,
            "valid_fraction": args.valid_fraction, "effects": args.effects, "pool": args.pool,
            "floor_z_mm": args.floor_z_mm, "max_reach_mm": args.max_reach_mm}


# ---------------------------------------------------------------- iso9283
_ISO9283 = ("The 5 ISO 9283 cube points (P1 the centre of a cube of side --side-mm at "
            "--centre-xyz, P2-P5 on the diagonals of a diagonal plane), --cycles times, each "
            "approached from the same side (a pre-position --approach-mm away). The run "
            "summary gets the positional repeatability RP per point and, when the store has "
            "a measurement frame, the positional accuracy AP.")


def _iso9283_add(p) -> None:
    p.add_argument("--centre-xyz", metavar="X,Y,Z", help="cube centre, mm (base frame)")
    p.add_argument("--start-deg", metavar="Q1,..,QN", help="IK seed posture, deg")
    p.add_argument("--side-mm", type=float, default=200.0, metavar="MM",
                   help="cube side, mm (default 200)")
    p.add_argument("--cycles", type=int, default=30, metavar="N",
                   help="cycles over the 5 points (default 30)")
    p.add_argument("--approach-mm", type=float, default=20.0, metavar="MM",
                   help="distance of the pre-position, mm (default 20)")


def _iso9283_params(args) -> dict:
    return {"centre_xyz": floats(args.centre_xyz, 3, "--centre-xyz"),
            "start_deg": floats(args.start_deg, None, "--start-deg"), "side_mm": args.side_mm,
            "cycles": args.cycles, "approach_mm": args.approach_mm}


# ----------------------------------------------------------------- warmup
_WARMUP = ("Repeats a cycle of work in the working space (--count random poses the tracker "
           "sees, --seed, at the capture's speed) and measures a reference pose before every "
           "cycle, until the reference's drift over the last --window-min minutes is below "
           "--threshold-mm (default 3x the tracker's sigma) or --max-min minutes have "
           "passed. Prints the drift curve and stores it with the run; `capture "
           "--require-warm N` then refuses to start unless this warm-up ended less than N "
           "minutes ago and the joints have not cooled since.")


def _warmup_add(p) -> None:
    p.add_argument("--count", type=int, default=6, metavar="N",
                   help="working poses per cycle (default 6)")
    p.add_argument("--window-min", type=float, default=15.0, metavar="MIN",
                   help="the window the drift is judged over, minutes (default 15)")
    p.add_argument("--threshold-mm", type=float, default=None, metavar="MM",
                   help="settled when the drift over the window is below this, mm (default "
                   "3x the tracker's sigma, at least 0.02)")
    p.add_argument("--max-min", type=float, default=60.0, metavar="MIN",
                   help="the time bound, minutes (default 60)")
    p.add_argument("--cycles", type=int, default=None, metavar="N",
                   help="cycles planned (default: enough for --max-min at 0.5 rad/s)")
    _max_reach(p)


def _warmup_params(args) -> dict:
    return {"count": args.count, "seed": args.seed or 0, "window_min": args.window_min,
            "threshold_mm": args.threshold_mm, "max_min": args.max_min, "cycles": args.cycles,
            "floor_z_mm": args.floor_z_mm, "max_reach_mm": args.max_reach_mm}


# ------------------------------------------------------------------ validate
#: the variants ``cellcal validate`` can run (calibration.compensation.controller_joints.VARIANTS)
VALIDATE_VARIANTS = ("uncompensated", "compensated", "geometric")


def _validate_add(p) -> None:
    p.add_argument("--cycles", type=int, default=1, metavar="N",
                   help="run the waypoints N times per variant (N >= 2: ISO 9283 RP too; "
                   "default 1)")
    p.add_argument("--variants", default=",".join(VALIDATE_VARIANTS), metavar="V,..",
                   help="which programs run, in order: uncompensated (as written), "
                   "compensated, geometric (the calibrated DH table alone, what "
                   "calibration.conf holds); default all three")


def _validate_params(args) -> dict:
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    bad = [v for v in variants if v not in VALIDATE_VARIANTS]
    if bad or not variants or len(set(variants)) != len(variants):
        raise ValueError(f"--variants {args.variants!r}: give some of "
                         f"{', '.join(VALIDATE_VARIANTS)}, each once")
    if args.cycles < 1:
        raise ValueError(f"--cycles {args.cycles}: give 1 or more")
    return {"cycles": args.cycles, "variants": variants}


_VALIDATE = ("Run by `cellcal validate`: a program's waypoints (or a targets CSV), as "
             "written, compensated by the calibration and with the calibrated DH table "
             "alone, moved to by joint moves and measured by the tracker; the run's summary "
             "gets each variant's error and ISO 9283 AP (RP with --cycles 2 or more).")

#: routine name -> its command-line options (every routine of :data:`daq.routines.ROUTINES`)
ROUTINE_ARGS = {
    "frame": RoutineArgs(_frame_add, _frame_params, "measurement-frame setup — the joint-1 "
                         "circle and the x line.", _FRAME),
    "steps": RoutineArgs(_steps_add, _steps_params, "axis-wise step moves from a start point "
                         "(absolute positioning error).", _STEPS),
    "zero20": RoutineArgs(_zero20_add, _zero20_params, "the 20-posture, 4-plane zero-point "
                          "routine.", _ZERO20, _ZERO20_ACQUIRE),
    "poses": RoutineArgs(_poses_add, _poses_params, "calibration and validation pose sets, "
                         "random or chosen for observability.", _POSES),
    "iso9283": RoutineArgs(_iso9283_add, _iso9283_params, "pose accuracy and repeatability "
                           "cycles (ISO 9283 cube points).", _ISO9283),
    "warmup": RoutineArgs(_warmup_add, _warmup_params, "work the robot until a reference pose "
                          "stops drifting (a warm-up before a capture).", _WARMUP),
    "validate": RoutineArgs(_validate_add, _validate_params, "a program's waypoints, as "
                            "written and compensated, measured by the tracker.", _VALIDATE,
                            command="validate"),
}

#: every routine's acquisition flags (given to ``resume``, they apply to a run of that routine)
ACQUIRE_FLAGS = [f for spec in ROUTINE_ARGS.values() for f in spec.acquire_flags]
