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
    ("--zero-tol-mm", "zero_tol_mm", float, "zero20: tip-on-target tolerance, mm (default 0.01; "
     "the loop also stops within 1.5x the measurement's 3-D std)"),
    ("--zero-average", "zero_average", int,
     "zero20: tracker measurements averaged per step of the closed loop (default 1)"),
]


def add_common(p, *, resume: bool = False) -> None:
    p.add_argument("--db", required=True, metavar="cell.db", help="run store (SQLite)")
    p.add_argument("--robot", required=not resume, metavar="URL", help="robot driver URL")
    p.add_argument("--tracker", required=not resume, metavar="URL", help="tracker driver URL")
    p.add_argument("--yes", action="store_true",
                   help="do not ask before moving a robot that is not a simulator")
    p.add_argument("--json", action="store_true", help="print one JSON object, no progress")
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
        "SQLite run store at once. Resume an interrupted run with `cellcal resume`.",
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
        for flag, _, typ, hlp in EXEC_FLAGS:
            r.add_argument(flag, type=typ, default=None, help=hlp)
        mod.add_args(r)
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
def _flag_dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def options_from_args(args, stored: dict | None = None):
    from dataclasses import asdict

    from ..executor import ExecutorOptions

    base = dict(stored or {})
    known = set(asdict(ExecutorOptions()))
    base = {k: v for k, v in base.items() if k in known}
    o = ExecutorOptions(**base)
    for flag, attr, _, _ in EXEC_FLAGS:
        v = getattr(args, _flag_dest(flag), None)
        if v is not None:
            setattr(o, attr, v)
    return o


def open_drivers(robot_url: str, tracker_url: str, timeout: float = 5.0):
    """Connected (robot, tracker); closes what was opened when the other fails."""
    import sim_drivers.inprocess  # noqa: F401  (registers sim://)
    from drivers.errors import DriverError
    from drivers.urls import open_robot, open_tracker

    try:
        robot = open_robot(robot_url)
        tracker = open_tracker(tracker_url)
    except ValueError as e:
        raise UsageError(str(e)) from None
    try:
        robot.connect(timeout=timeout)
        tracker.connect(timeout=timeout)
    except DriverError as e:
        robot.close()
        tracker.close()
        raise ConnectFailed(str(e)) from e
    return robot, tracker


class ConnectFailed(Exception):
    """The devices could not be reached."""


def run_executor(store, run_id, plan, robot, tracker, options, model, args) -> tuple[str, dict]:
    """Run the executor with progress; returns (status, JSON-ready summary)."""
    import time

    from ..executor import Executor
    from ..progress import Progress
    from ..routines import get

    progress = Progress(enabled=not args.json)
    ex = Executor(store, run_id, plan, robot, tracker, options, model=model, progress=progress,
                  finalize=getattr(get(plan.routine), "finalize", None))
    t0 = time.monotonic()
    try:
        status = ex.run()
    finally:
        progress.close()
    run = store.run(run_id)
    out = {"run": run_id, "routine": plan.routine, "status": status, "reason": run.reason,
           "points": len(plan), "samples": store.n_samples(run_id), "faults": ex.n_faults,
           "elapsed_s": time.monotonic() - t0, "plan_hash": plan.hash, "db": str(store.path)}
    if run.frame is not None:
        out["frame"] = run.frame
    if run.summary:
        out["summary"] = run.summary
    return status, out


def report(out: dict, args) -> int:
    from .common import print_json

    if args.json:
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


def run(args) -> int:
    from calibration import ModelError, load_model

    from ..check import check_plan
    from ..routines import get
    from ..routines._common import floats
    from ..store import RunStore, StoreError

    mod = get(args.routine)
    try:
        model = load_model(args.model)
        tool = floats(args.tool_mm, 3, "--tool-mm")
        if tool is not None:
            model = model.with_changes(tool=tuple(tool))
        params = mod.params_from_args(args)
        plan = mod.make_plan(model, **params)
    except (ModelError, ValueError) as e:
        raise UsageError(str(e)) from None
    res = check_plan(plan, model, floor_z_mm=None if args.no_floor else args.floor_z_mm,
                     max_reach_mm=getattr(args, "max_reach_mm", None))
    if not res.ok:
        raise UsageError(res.report())
    options = options_from_args(args)
    if args.dry_run:
        if args.json:
            from .common import print_json

            print_json({"routine": plan.routine, "points": len(plan), "plan_hash": plan.hash,
                        "check": "ok", "params": plan.params})
        else:
            print(f"{plan.routine}: {len(plan)} points, plan {plan.hash[:16]}")
            print(res.report())
        return 0
    confirm_motion([args.robot, args.tracker], args.yes)
    try:
        store = RunStore(args.db, synchronous=args.synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None
    try:
        extra = {"tool_mm": model.tool_mm().tolist()}
        frame_run = _frame_run(store, args.frame_run)
        if frame_run is not None:
            extra |= {"frame_run": frame_run.id,
                     "tracker_T_base": frame_run.frame["tracker_T_base"],
                     "tracker_R_base": [r[:3] for r in frame_run.frame["tracker_T_base"][:3]]}
        try:
            robot, tracker = open_drivers(args.robot, args.tracker)
        except ConnectFailed as e:
            print(f"cellcal capture: cannot connect: {e}", file=sys.stderr)
            return 1
        try:
            from dataclasses import asdict

            from ..executor import describe

            run_id = store.create_run(
                plan, robot_url=args.robot, tracker_url=args.tracker,
                robot_desc=describe(robot), tracker_desc=describe(tracker), seed=args.seed,
                model=args.model, options={**asdict(options), **extra},
            )
            if not args.json:
                print(f"run {run_id}: {plan.routine}, {len(plan)} points, plan "
                      f"{plan.hash[:16]}", file=sys.stderr)
            status, out = run_executor(store, run_id, plan, robot, tracker, options, model, args)
        finally:
            robot.close()
            tracker.close()
        return report(out, args)
    finally:
        store.close()


def _frame_run(store, run_id):
    if run_id is not None:
        from ..store import StoreError

        try:
            r = store.run(run_id)
        except StoreError as e:
            raise UsageError(str(e)) from None
        if r.frame is None:
            raise UsageError(f"run {run_id} has no measurement frame (not a completed frame run)")
        return r
    for r in reversed(store.runs()):
        if r.routine == "frame" and r.status == "completed" and r.frame is not None:
            return r
    return None
