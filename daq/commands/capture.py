"""``cellcal capture ROUTINE``: make a plan, dry-run it, and run it into the run store.

Exit codes: 0 the run completed; 1 it paused (protective stop, rejected
command, retries exhausted) or failed; 2 bad input or a plan refused by the
dry run (the offending points are named); 130 stopped with Ctrl-C (the run is
resumable with ``cellcal resume``).
"""

from __future__ import annotations

import ipaddress
import sys
from urllib.parse import urlsplit

from ..cli import UsageError
from .routine_args import ROUTINE_ARGS, floats

#: executor options settable on the command line: (flag, attribute, type, help)
EXEC_FLAGS = [
    ("--speed", "speed_rad_s", float, "joint speed, rad/s (default 0.5)"),
    ("--linear-speed", "speed_mm_s", float, "TCP speed of linear moves, mm/s (default 100)"),
    ("--dwell", "dwell_s", float, "extra wait after the robot settled, s (default 0)"),
    ("--measure-s", "measure_s", float, "tracker averaging time, s (default 0.5)"),
    ("--max-std-mm", "max_std_mm", float,
     "remeasure when the tracker's per-axis std exceeds this, mm (default 0.05)"),
    ("--max-retries", "max_retries", int, "retries per point after transient faults (default 8)"),
    ("--io-timeout", "io_timeout_s", float, "timeout of reads, s (default 1)"),
    ("--store-wait", "store_wait_s", float,
     "a lost run store connection (PostgreSQL): wait this long for it, holding the robot, "
     "before pausing the run, s (default 30)"),
]


def add_common(p, *, resume: bool = False) -> None:
    from .common import DB_HELP

    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--robot", required=not resume, metavar="URL", help="robot driver URL")
    p.add_argument("--tracker", required=not resume, metavar="URL", help="tracker driver URL")
    p.add_argument("--yes", action="store_true",
                   help="do not ask before moving a robot that is not a simulator")
    p.add_argument("--json", action="store_true", help="print one JSON object, no progress")
    p.add_argument("--robot-id", metavar="NAME", default=None,
                   help="who the robot is, recorded with the run (default: the controller's "
                   "MODEL/SERIAL when its protocol reports one)")
    p.add_argument("--synchronous", choices=("FULL", "NORMAL"), default="FULL",
                   help=argparse_hidden())


def argparse_hidden():
    import argparse

    return argparse.SUPPRESS


def register(sub) -> None:
    from ..routines import ROUTINES, get

    p = sub.add_parser(
        "capture",
        help="run a capture routine into the run store",
        description="Make a routine's plan, dry-run it against the model (joint limits, reach, "
        "floor), then move and measure point by point; every sample is committed to the "
        "run store (SQLite file or PostgreSQL) at once. Resume an interrupted run with "
        "`cellcal resume`.",
    )
    rsub = p.add_subparsers(dest="routine", metavar="ROUTINE")
    rsub.required = True
    for name in ROUTINES:
        mod = get(name)
        first = (mod.__doc__ or "").strip().splitlines()[0]
        r = rsub.add_parser(name, help=first.split(": ", 1)[-1])
        r.add_argument("--model", required=True, metavar="NAME|PATH", help="robot model")
        add_common(r)
        r.add_argument("--tool-mm", metavar="X,Y,Z", default=None,
                       help="the controller's TCP in the flange frame, mm (overrides the "
                       "model's tool; recorded with the run)")
        r.add_argument("--seed", type=int, default=None, help="random seed (recorded)")
        r.add_argument("--floor-z-mm", type=float, default=0.0,
                       help="dry run: lowest z of link origins and tool, mm (default 0)")
        r.add_argument("--no-floor", action="store_true", help="dry run: no floor check")
        r.add_argument("--frame-run", type=int, default=None, metavar="RUN",
                       help="measurement frame from this frame run (default: the latest "
                       "completed one in the store, if any)")
        r.add_argument("--dry-run", action="store_true",
                       help="check and print the plan, do not move")
        for flag, _, typ, hlp in EXEC_FLAGS + ROUTINE_ARGS[name].acquire_flags:
            r.add_argument(flag, type=typ, default=None, help=hlp)
        ROUTINE_ARGS[name].add(r)
        r.set_defaults(func=run)


# ------------------------------------------------------------------ safety
def is_local(url: str) -> bool:
    """True for simulator URLs: ``sim://``, loopback hosts, pseudo-terminals (/dev/pts/N)."""
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    if scheme == "sim":
        return True
    if scheme in ("serial", "tracker+serial"):
        return parts.path.startswith("/dev/pts/")
    host = parts.hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def confirm_motion(urls: list[str], yes: bool, stdin=None, stderr=None) -> None:
    """Ask before moving anything that is not a simulator; UsageError when refused."""
    remote = [u for u in urls if u and not is_local(u)]
    if not remote or yes:
        return
    stdin = stdin or sys.stdin
    stderr = stderr or sys.stderr
    try:
        tty = stdin.isatty()
    except (AttributeError, ValueError):
        tty = False
    if not tty:
        raise UsageError(f"{', '.join(remote)} is not a simulator: refusing to move without "
                         "confirmation (no terminal); pass --yes to confirm")
    stderr.write(f"About to move real hardware: {', '.join(remote)}.\n"
                 "Is the cell clear and the robot's speed limited? Type 'yes' to start: ")
    stderr.flush()
    if stdin.readline().strip().lower() not in ("y", "yes"):
        raise UsageError("not confirmed: nothing moved")


# --------------------------------------------------------------- plumbing
def flag_values(args, flags) -> dict:
    """``{attribute: value}`` of the flags given on the command line (others left out)."""
    out = {}
    for flag, attr, _, _ in flags:
        v = getattr(args, flag.lstrip("-").replace("-", "_"), None)
        if v is not None:
            out[attr] = v
    return out


def report(out: dict, as_json: bool) -> int:
    """Print a run outcome (``RunOutcome.to_json()``); the exit code."""
    from .common import print_json

    if as_json:
        print_json(out)
    else:
        print(f"run {out['run']} ({out['routine']}): {out['status']}, "
              f"{out['samples']}/{out['points']} points stored, {out['faults']} faults, "
              f"{out['elapsed_s']:.1f} s  [{out['db']}]")
        if out.get("reason"):
            print(f"  reason: {out['reason']}")
        if "frame" in out:
            f = out["frame"]
            print(f"  frame: circle rms {f['circle']['rms_mm']:.4f} mm, line rms "
                  f"{f['line']['rms_mm']:.4f} mm, non-orthogonality "
                  f"{f['orthogonality_deg']:.4f} deg")
            for row in f["tracker_T_base"][:3]:
                print("   " + "  ".join(f"{v:12.6f}" for v in row))
        if out["status"] in ("paused", "stopped"):
            print(f"  resume with: cellcal resume {out['run']} --db {out['db']}")
    return {"completed": 0, "stopped": 130}.get(out["status"], 1)


def run_and_report(command: str, as_json: bool, go) -> int:
    """``go(progress)`` (a service call returning a ``RunOutcome``) with a progress line;
    prints the outcome and returns the exit code (1 when the devices or the run store cannot
    be reached)."""
    from ..errors import ConnectFailed
    from ..progress import Progress
    from ..store import StoreUnavailable

    progress = Progress(enabled=not as_json)
    try:
        outcome = go(progress)
    except ConnectFailed as e:
        print(f"cellcal {command}: cannot connect: {e}", file=sys.stderr)
        return 1
    except StoreUnavailable as e:
        print(f"cellcal {command}: run store unreachable: {e}; `cellcal resume` once it is "
              "back", file=sys.stderr)
        return 1
    finally:
        progress.close()
    return report(outcome.to_json(), as_json)


def request_from_args(args):
    """The typed capture request of the parsed arguments (ValueError for bad values)."""
    from ..run_context import ExecutorOptions
    from ..service import CaptureRequest

    spec = ROUTINE_ARGS[args.routine]
    tool = floats(args.tool_mm, 3, "--tool-mm")
    return CaptureRequest(
        routine=args.routine, model=args.model, params=spec.params(args),
        tool_mm=None if tool is None else tuple(tool), seed=args.seed,
        floor_z_mm=None if args.no_floor else args.floor_z_mm,
        max_reach_mm=getattr(args, "max_reach_mm", None), frame_run=args.frame_run,
        executor=ExecutorOptions(**flag_values(args, EXEC_FLAGS)),
        acquire=flag_values(args, spec.acquire_flags), robot_id=args.robot_id)


def run(args) -> int:
    from ..service import plan_run, start_run
    from ..store import RunStore, StoreError

    try:
        request = request_from_args(args)
    except ValueError as e:
        raise UsageError(str(e)) from None
    planned = plan_run(request, db=args.db)
    plan = planned.plan
    if args.dry_run:
        if args.json:
            from .common import print_json

            print_json({"routine": plan.routine, "points": len(plan), "plan_hash": plan.hash,
                        "check": "ok", "params": plan.params})
        else:
            print(f"{plan.routine}: {len(plan)} points, plan {plan.hash[:16]}")
            print(planned.check.report())
        return 0
    confirm_motion([args.robot, args.tracker], args.yes)
    try:
        store = RunStore(args.db, synchronous=args.synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None

    def started(run_id: int, _done: int) -> None:
        if not args.json:
            print(f"run {run_id}: {plan.routine}, {len(plan)} points, plan "
                  f"{plan.hash[:16]}", file=sys.stderr)

    try:
        return run_and_report("capture", args.json, lambda progress: start_run(
            store, planned, robot_url=args.robot, tracker_url=args.tracker, progress=progress,
            on_started=started))
    finally:
        store.close()
