"""``cellcal capture ROUTINE``: make a plan, dry-run it, and run it into the run store.

Before the run is stored the tracker is set up and checked (:mod:`daq.tracker_checks`):
``--reflector``, ``--meteo``, the ready gate and the two-face check.

Before anything moves: the options are checked (exit 2), the plan is dry-run, the robot's
lease is taken (another live process using the robot: exit 2, naming it), the devices
are connected and say who they are, the robot's joint count (and a simulator's robot
model) must be the model's (exit 2), and unless both devices declared themselves
simulators the motion must be confirmed (``--yes``, or typing ``yes`` at a terminal).

Exit codes (docs/formats.md §6): 0 the run completed; 1 it paused (protective stop,
rejected command, retries exhausted, a move refused or not done, the run store
unreachable) or failed, or the devices cannot be reached; 2 bad input, a plan refused by
the dry run (the offending points are named), a busy robot or run, the wrong robot, the
motion not confirmed, a tracker that fails its checks (the check and what to do are
named; nothing is stored); 3 a plan the tracker would not see enough of; 130 stopped
with Ctrl-C (the run is resumable with ``cellcal resume``); 128 + N stopped at once by
signal N (a second Ctrl-C 130, SIGTERM 143, SIGHUP 129: the controller's stop was sent
and the run is ``paused``).
"""

from __future__ import annotations

import argparse
import sys

from ..cli import UsageError, add_subcommands, command_parser
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
    ("--remeasure", "remeasure", int,
     "re-measure a reading out of line with the model fitted so far up to N times, moving "
     "away and back (default 2; 0: no model check)"),
    ("--store-wait", "store_wait_s", float,
     "a lost run store connection (PostgreSQL): wait this long for it, holding the robot, "
     "before pausing the run, s (default 30)"),
]


def metavar(typ) -> str:
    """``N`` for a count, ``X`` for a quantity (the help says its unit)."""
    return "N" if typ is int else "X"


def add_common(p, *, resume: bool = False) -> None:
    from .common import DB_HELP

    p.add_argument("--db", required=True, metavar="cell.db|URL",
                   help=DB_HELP + ("; a file is created when missing" if not resume else ""))
    p.add_argument("--robot", required=not resume, metavar="URL",
                   help="robot driver URL, e.g. modbus+tcp://127.0.0.1:15020?unit=1 (README: "
                   "At the cell)" + (" (default: the run's)" if resume else ""))
    p.add_argument("--tracker", required=not resume, metavar="URL",
                   help="tracker driver URL, e.g. tracker+tcp://127.0.0.1:15700"
                   + (" (default: the run's)" if resume else ""))
    p.add_argument("--yes", action="store_true",
                   help="do not ask before moving devices that did not identify themselves "
                   "as simulators (any real controller, whatever its address)")
    p.add_argument("--json", action="store_true", help="print one JSON object, no progress")
    p.add_argument("--robot-id", metavar="NAME", default=None,
                   help="who the robot is, recorded with the run (default: the controller's "
                   "MODEL/SERIAL when its protocol reports one)")
    p.add_argument("--synchronous", choices=("FULL", "NORMAL"), default="FULL",
                   help=argparse.SUPPRESS)


def add_tracker_flags(p, *, resume: bool = False) -> None:
    """The tracker's setup and checks (:class:`~daq.run_context.TrackerSetup`)."""
    p.add_argument("--meteo", metavar="T,P,H", default=None,
                   help="the air at the cell (°C, hPa, %%RH) for a tracker without a weather "
                   "station (refused when one reports); recorded with every point"
                   + ("; replaces the run's for this session" if resume else ""))
    if resume:
        return
    p.add_argument("--reflector", metavar="NAME", default=None,
                   help="select the tracker's reflector by name (case-insensitive; an unknown "
                   "name lists the known ones); recorded with every point")
    p.add_argument("--two-face-tol-mm", type=float, default=None, metavar="MM",
                   help="two-face check before the run: the largest difference between the "
                   "faces beyond the measurements' noise, mm (default 0.05)")
    p.add_argument("--no-two-face-check", action="store_true",
                   help="skip the two-face check before the run")


def tracker_setup(args, stored: dict | None = None) -> dict:
    """The tracker setup fields the flags give (``stored``: the run's, for a resume), as
    :class:`~daq.run_context.TrackerSetup` checks them; ValueError naming the flag."""
    from pydantic import ValidationError

    from daq.run_context import TrackerSetup

    given: dict = {}
    meteo = floats(getattr(args, "meteo", None), 3, "--meteo")
    if meteo is not None:
        given["meteo"] = tuple(meteo)
    if getattr(args, "reflector", None) is not None:
        given["reflector"] = args.reflector
    if getattr(args, "no_two_face_check", False):
        given["two_face_check"] = False
    if getattr(args, "two_face_tol_mm", None) is not None:
        given["two_face_tol_mm"] = args.two_face_tol_mm
    try:
        TrackerSetup(**{**(stored or {}), **given})
    except ValidationError as e:
        msg = "; ".join(err["msg"].removeprefix("Value error, ") for err in e.errors())
        raise ValueError(msg.replace("two_face_tol_mm", "--two-face-tol-mm")) from None
    return given


def register(sub) -> None:
    p = command_parser(
        sub, "capture",
        help="run a capture routine into the run store",
        description="Make a routine's plan, dry-run it against the model (joint limits, "
        "reach, floor), then move and measure point by point; every sample is committed to "
        "the run store (a SQLite file or PostgreSQL) at once. Resume an interrupted run with "
        "`cellcal resume`. `cellcal capture ROUTINE --help` describes a routine and its "
        "options.\n\n"
        "Exit codes: 0 completed; 1 paused (protective stop, rejected command, retries "
        "exhausted, run store unreachable) or failed, or the devices cannot be reached; 2 "
        "bad input, a plan refused by the dry run (the offending points are named) or "
        "anything else refused before the run is stored; 3 a plan the tracker would not "
        "see enough of; 130 stopped with Ctrl-C (resumable); 128 + N stopped at once by "
        "signal N (docs/formats.md §6).",
    )
    rsub = add_subcommands(p, "routine", "ROUTINE")
    for name, spec in ROUTINE_ARGS.items():
        r = command_parser(rsub, name, help=spec.summary,
                           description=spec.summary[0].upper() + spec.summary[1:] + "\n\n"
                           + spec.description)
        r.add_argument("--model", required=True, metavar="NAME|PATH",
                       help="the robot model: a built-in name (see `cellcal models`) or a "
                       "model YAML file (recorded with the run)")
        add_common(r)
        r.add_argument("--tool-mm", metavar="X,Y,Z", default=None,
                       help="the controller's TCP in the flange frame, mm (overrides the "
                       "model's tool; recorded with the run, exported as `# tool_mm:` and "
                       "the nominal tool of every later fit)")
        r.add_argument("--smr-radius-mm", type=float, default=None, metavar="MM",
                       help="radius of the SMR (recorded; default: the reflector's, when the "
                       "tracker reports it)")
        r.add_argument("--seed", type=int, default=None,
                       help="random seed of the plan (recorded; default 0)")
        r.add_argument("--floor-z-mm", type=float, default=0.0, metavar="MM",
                       help="dry run: lowest z of link origins and tool, mm (default 0)")
        r.add_argument("--no-floor", action="store_true", help="dry run: no floor check")
        r.add_argument("--keepout-mm", action="append", default=[],
                       metavar="X0,Y0,Z0,X1,Y1,Z1",
                       help="a box (base frame, mm) no link origin or tool point may enter, "
                       "checked by the dry run and before every move (repeatable)")
        r.add_argument("--check-paths", action="store_true",
                       help="also check the floor, keep-out boxes and reach along every joint "
                       "move, not only where it ends")
        r.add_argument("--frame-run", type=int, default=None, metavar="RUN",
                       help="measurement frame from this frame run (default: the latest "
                       "completed one in the store, if any)")
        r.add_argument("--dry-run", action="store_true",
                       help="check and print the plan (the points the tracker would not see, "
                       "the estimated capture time), do not move")
        r.add_argument("--tracker-at", metavar="X,Y,Z", default=None,
                       help="where the tracker head stands, robot base frame, mm (rough is "
                       "fine; default: from the latest frame run in --db, else --cell)")
        r.add_argument("--cell", metavar="cell.yaml", default=None,
                       help="the cell: tracker position, SMR axis and reflector, margins, "
                       "fixtures (docs/formats.md section 7)")
        r.add_argument("--no-visibility", action="store_true",
                       help="plan without the tracker's line of sight (the dry run still "
                       "lists the points it would not see)")
        r.add_argument("--plot", metavar="PNG", default=None,
                       help="draw the plan: robot, SMR positions, tracker and beams")
        for flag, _, typ, hlp in EXEC_FLAGS + ROUTINE_ARGS[name].acquire_flags:
            r.add_argument(flag, type=typ, default=None, help=hlp, metavar=metavar(typ))
        add_tracker_flags(r)
        spec.add(r)
        r.set_defaults(func=run)


# ------------------------------------------------------------------ safety
def confirm_motion(cell, urls: list[str], yes: bool, stdin=None, stderr=None) -> None:
    """Ask before moving devices that did not identify themselves as simulators.

    ``cell`` is what they said (:class:`daq.devices.CellIdentity`); only a robot and a
    tracker that both declared themselves simulators go without asking. Any other
    endpoint — a loopback address or a pty included (an SSH tunnel or a serial bridge
    may lead to a real controller) — needs ``yes`` or a ``yes`` typed at a terminal;
    UsageError when refused (nothing moved).
    """
    if cell.simulated or yes:
        return
    what = ", ".join(f"{u} ({d})" for u, d in zip(urls, (cell.robot, cell.tracker),
                                                     strict=True) if not d.simulator)
    stdin = stdin or sys.stdin
    stderr = stderr or sys.stderr
    try:
        tty = stdin.isatty()
    except (AttributeError, ValueError):
        tty = False
    if not tty:
        raise UsageError(f"{what} did not identify as a simulator: refusing to move without "
                         "confirmation (no terminal); pass --yes to confirm")
    stderr.write(f"About to move real hardware: {what}.\n"
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
        rm = (out.get("summary") or {}).get("remeasure")
        if rm and (rm["suspects"] or rm["rejected"] or rm["unresolved"]):
            print(f"  re-measured {rm['suspects']} points ({rm['remeasurements']} "
                  f"re-measurements, {rm['rejected']} readings rejected, "
                  f"{rm['model_disagrees']} where the model disagrees, {rm['unresolved']} "
                  f"unresolved); the first {rm['warmup']} points before the model")
        if "frame" in out:
            f = out["frame"]
            print(f"  frame: circle rms {f['circle']['rms_mm']:.4f} mm, line rms "
                  f"{f['line']['rms_mm']:.4f} mm, non-orthogonality "
                  f"{f['orthogonality_deg']:.4f} deg")
            print("  tracker_T_base (robot base in the tracker frame, mm; rows of [R | t]):")
            for row in f["tracker_T_base"][:3]:
                print("   " + "  ".join(f"{v:12.6f}" for v in row))
        if out.get("tracker_check"):
            print(f"  tracker: {check_line(out['tracker_check'])}")
        summary = out.get("summary") or {}
        if summary.get("beam_breaks") or summary.get("skipped_points"):
            skipped = summary.get("skipped_points", [])
            print(f"  line of sight: {summary.get('beam_breaks', 0)} beam breaks, "
                  f"{len(skipped)} points skipped {skipped[:10]}, "
                  f"{summary.get('spares_measured', 0)} spares measured in their place")
        if out["status"] in ("paused", "stopped"):
            print(f"  resume with: cellcal resume {out['run']} --db {out['db']}")
    signum = out.get("signal")
    if signum:
        import signal

        return 128 + int(getattr(signal, signum, 0) or 1)
    return {"completed": 0, "stopped": 130}.get(out["status"], 1)


def check_line(c: dict) -> str:
    """One line of what the tracker's checks found (a ``TrackerCheck``, JSON)."""
    parts = []
    if c.get("ready") is not None:
        parts.append("ready")
    if c.get("temp_c") is not None:
        parts.append(f"air {c['temp_c']:.1f} °C {c['pressure_hpa']:.1f} hPa "
                     f"{c['humidity_pct']:.0f} %RH ({c['air_source']})")
    if c.get("reflector"):
        parts.append(f"reflector {c['reflector']}")
    if c.get("face"):
        parts.append(f"face {c['face']}")
    f = c.get("two_face")
    if f:
        parts.append(f"two faces {f['diff_mm']:.3f} mm apart (allowed {f['tol_mm']:.3f} + "
                     f"{f['noise_mm']:.3f} noise)")
    return ", ".join(parts) or "no checks offered"


def run_and_report(command: str, as_json: bool, go) -> int:
    """``go(progress)`` (a service call returning a ``RunOutcome``) with a progress line;
    prints the outcome and returns the exit code (1 when the devices or the run store cannot
    be reached)."""
    from daq.errors import ConnectFailed
    from daq.store import StoreUnavailable

    from ..progress import Progress

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


def executor_options(values: dict, base=None):
    """ExecutorOptions from flag values (over ``base``'s); UsageError naming the flag."""
    from pydantic import ValidationError

    from daq.run_context import ExecutorOptions

    try:
        return ExecutorOptions(**{**(base.model_dump() if base is not None else {}), **values})
    except ValidationError as e:
        flag_of = {attr: flag for flag, attr, _, _ in EXEC_FLAGS}
        raise UsageError("; ".join(
            f"{flag_of.get(str(err['loc'][0]), err['loc'][0])}: {err['msg']}"
            for err in e.errors())) from None


def motion_limits(args):
    """The run's motion limits from the arguments; UsageError for bad values."""
    from daq.errors import one_line
    from daq.motion_guard import MotionLimits

    try:
        boxes = tuple(tuple(floats(b, 6, "--keepout-mm")) for b in args.keepout_mm)
        return MotionLimits(floor_z_mm=None if args.no_floor else args.floor_z_mm,
                            max_reach_mm=getattr(args, "max_reach_mm", None),
                            keepout_mm=boxes, check_paths=args.check_paths)
    except ValueError as e:
        msg = one_line(e).replace("floor_z_mm", "--floor-z-mm").replace(
            "max_reach_mm", "--max-reach-mm").replace("keepout_mm", "--keepout-mm")
        raise UsageError(msg) from None


def request_from_args(args):
    """The typed capture request of the parsed arguments (UsageError/ValueError for bad
    values: every option is checked here, before a store or a run exists)."""
    import math

    from calibration.cell import load_cell
    from daq.run_context import TrackerSetup
    from daq.service import CaptureRequest

    spec = ROUTINE_ARGS[args.routine]
    tool = floats(args.tool_mm, 3, "--tool-mm")
    if tool is not None and not all(math.isfinite(v) for v in tool):
        raise UsageError(f"--tool-mm: expected 3 finite numbers, got {args.tool_mm!r}")
    limits = motion_limits(args)
    tracker_at = floats(args.tracker_at, 3, "--tracker-at")
    radius = args.smr_radius_mm
    if radius is not None and not 0 < radius < 1000:
        raise ValueError(f"--smr-radius-mm: {radius:g} is not a radius in mm (0 < r < 1000)")
    return CaptureRequest(
        cell=None if args.cell is None else load_cell(args.cell),
        tracker_at=None if tracker_at is None else tuple(tracker_at),
        visibility=not args.no_visibility,
        routine=args.routine, model=args.model, params=spec.params(args),
        tool_mm=None if tool is None else tuple(tool), smr_radius_mm=radius, seed=args.seed,
        floor_z_mm=limits.floor_z_mm, max_reach_mm=limits.max_reach_mm,
        frame_run=args.frame_run, executor=executor_options(flag_values(args, EXEC_FLAGS)),
        acquire=flag_values(args, spec.acquire_flags), motion=limits,
        tracker=TrackerSetup(**tracker_setup(args)), robot_id=args.robot_id)


def check_urls(robot: str | None, tracker: str | None) -> None:
    """Refuse a malformed robot or tracker URL before anything is opened or created."""
    from drivers.urls import check_url

    try:
        for url, kind in ((robot, "robot"), (tracker, "tracker")):
            if url is not None:
                check_url(url, kind)
    except ValueError as e:
        raise UsageError(str(e)) from None


def run(args) -> int:
    from daq.service import plan_run, start_run
    from daq.store import RunStore, StoreError

    check_urls(args.robot, args.tracker)
    try:
        request = request_from_args(args)
    except ValueError as e:
        raise UsageError(str(e)) from None
    from daq.sight import estimate_time, format_time

    planned = plan_run(request, db=args.db)
    plan = planned.plan
    estimate = estimate_time(plan, request.executor)
    if args.plot:
        from presentation.plan_figure import plan_figure

        plan_figure(planned.model, plan, planned.sight.cell).savefig(args.plot, dpi=110)
        if not args.json:
            print(f"wrote {args.plot}", file=sys.stderr)
    if args.dry_run:
        if args.json:
            from .common import print_json

            print_json({"routine": plan.routine, "points": plan.n_planned,
                        "spares": len(plan) - plan.n_planned, "plan_hash": plan.hash,
                        "check": "ok", "params": plan.params,
                        "sight": planned.sight.to_json(), **estimate})
        else:
            spares = len(plan) - plan.n_planned
            print(f"{plan.routine}: {plan.n_planned} points"
                  f"{f' (+ {spares} spares)' if spares else ''}, plan {plan.hash[:16]}")
            print(planned.check.report())
            print(planned.sight.report())
            print(format_time(estimate))
        return 0
    if not args.json and (planned.sight.hidden or not planned.sight.checked):
        print(f"cellcal capture: note: {planned.sight.report(limit=5)}", file=sys.stderr)
    try:
        store = RunStore(args.db, synchronous=args.synchronous)
    except (StoreError, OSError) as e:
        raise UsageError(str(e)) from None

    def started(run_id: int, _done: int) -> None:
        if not args.json:
            print(f"run {run_id}: {plan.routine}, {plan.n_planned} points, plan "
                  f"{plan.hash[:16]}", file=sys.stderr)

    try:
        return run_and_report("capture", args.json, lambda progress: start_run(
            store, planned, robot_url=args.robot, tracker_url=args.tracker, progress=progress,
            on_started=started, confirm=lambda cell, robot, tracker: confirm_motion(
                cell, [robot, tracker], args.yes)))
    finally:
        store.close()
