"""The command-line options of each capture routine (``cellcal capture ROUTINE ...``).

:data:`ROUTINE_ARGS` maps a routine (:mod:`daq.routines`) to its :class:`RoutineArgs`:
``add(parser)`` declares the flags, ``params(args)`` turns the parsed arguments into the
routine's ``make_plan`` keyword arguments (a pure conversion: no I/O; a run a flag refers
to, like zero20's ``--replay RUN``, stays a reference the service resolves), and
``acquire_flags`` are the flags of the routine's acquisition options ``(flag, option,
type, help)``, given to ``capture`` and ``resume``. Common flags (``--seed``,
``--floor-z-mm``, ``--max-reach-mm``...) come from :mod:`daq.commands.capture`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field


def floats(text: str | None, n: int | None, what: str) -> list[float] | None:
    """Parse ``"1,2,3"`` into floats (exactly ``n`` when given); ValueError naming ``what``."""
    if text is None:
        return None
    try:
        v = [float(s) for s in str(text).replace(" ", "").split(",") if s]
    except ValueError:
        raise ValueError(f"{what}: expected comma-separated numbers, got {text!r}") from None
    if n is not None and len(v) != n:
        raise ValueError(f"{what}: expected {n} numbers, got {len(v)}")
    return v


@dataclass(frozen=True)
class RoutineArgs:
    """A routine's flags (``add``), their conversion (``params``), its acquisition flags."""

    add: Callable
    params: Callable
    acquire_flags: list = field(default_factory=list)


# ------------------------------------------------------------------ frame
def _frame_add(p) -> None:
    p.add_argument("--start-deg", metavar="Q1,..,QN", help="start posture, deg")
    p.add_argument("--circle-span-deg", type=float, default=90.0, help="joint-1 turn (deg)")
    p.add_argument("--circle-points", type=int, default=12)
    p.add_argument("--line-length-mm", type=float, default=300.0)
    p.add_argument("--line-points", type=int, default=11)


def _frame_params(args) -> dict:
    return {"start_deg": floats(args.start_deg, None, "--start-deg"),
            "circle_span_deg": args.circle_span_deg, "circle_points": args.circle_points,
            "line_length_mm": args.line_length_mm, "line_points": args.line_points}


# ------------------------------------------------------------------ steps
def _steps_add(p) -> None:
    p.add_argument("--start-xyz", metavar="X,Y,Z", help="start point, mm (base frame)")
    p.add_argument("--start-deg", metavar="Q1,..,QN", help="start posture / IK seed, deg")
    p.add_argument("--step-mm", type=float, default=20.0)
    p.add_argument("--count", type=int, default=10, help="steps per axis")
    p.add_argument("--axes", default="xyz")


def _steps_params(args) -> dict:
    return {"start_xyz": floats(args.start_xyz, 3, "--start-xyz"),
            "start_deg": floats(args.start_deg, None, "--start-deg"),
            "step_mm": args.step_mm, "count": args.count, "axes": args.axes}


# ----------------------------------------------------------------- zero20
def _zero20_add(p) -> None:
    p.add_argument("--target-xyz", metavar="X,Y,Z", help="fixed target point, mm (base frame)")
    p.add_argument("--seed-deg", metavar="Q1,..,QN", help="preferred configuration, deg")
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
]


# ------------------------------------------------------------------ poses
def _poses_add(p) -> None:
    p.add_argument("--count", type=int, default=100, help="number of poses")
    p.add_argument("--method", choices=("random", "optimal"), default="random")
    p.add_argument("--valid-fraction", type=float, default=0.0,
                   help="fraction of the poses marked set=valid (random)")
    p.add_argument("--effects", default="geometric,base,tool",
                   help="error model whose observability 'optimal' maximises")
    p.add_argument("--pool", type=int, default=None, help="candidate pool size for 'optimal'")
    p.add_argument("--max-reach-mm", type=float, default=None)


def _poses_params(args) -> dict:
    return {"count": args.count, "seed": args.seed or 0, "method": args.method,
            "valid_fraction": args.valid_fraction, "effects": args.effects, "pool": args.pool,
            "floor_z_mm": args.floor_z_mm, "max_reach_mm": args.max_reach_mm}


# ---------------------------------------------------------------- iso9283
def _iso9283_add(p) -> None:
    p.add_argument("--centre-xyz", metavar="X,Y,Z", help="cube centre, mm (base frame)")
    p.add_argument("--start-deg", metavar="Q1,..,QN", help="IK seed posture, deg")
    p.add_argument("--side-mm", type=float, default=200.0)
    p.add_argument("--cycles", type=int, default=30)
    p.add_argument("--approach-mm", type=float, default=20.0)


def _iso9283_params(args) -> dict:
    return {"centre_xyz": floats(args.centre_xyz, 3, "--centre-xyz"),
            "start_deg": floats(args.start_deg, None, "--start-deg"), "side_mm": args.side_mm,
            "cycles": args.cycles, "approach_mm": args.approach_mm}


#: routine name -> its command-line options (every routine of :data:`daq.routines.ROUTINES`)
ROUTINE_ARGS = {
    "frame": RoutineArgs(_frame_add, _frame_params),
    "steps": RoutineArgs(_steps_add, _steps_params),
    "zero20": RoutineArgs(_zero20_add, _zero20_params, _ZERO20_ACQUIRE),
    "poses": RoutineArgs(_poses_add, _poses_params),
    "iso9283": RoutineArgs(_iso9283_add, _iso9283_params),
}
