"""``cellcal runs``: list the runs in a run store (or show one with its context,
interruptions and the readings it did not accept).

The list counts each run's interruptions, its beam breaks, the points skipped because
the beam stayed broken (see :mod:`daq.executor`) and ``remeasured``: the points whose
reading was out of line with the running model and re-measured (:mod:`daq.remeasure`);
``--json`` gives every re-measure count under ``remeasure``.
"""

from __future__ import annotations

import datetime as dt
import math

from ..cli import UsageError, command_parser
from .common import positive_int


def register(sub) -> None:
    from .common import DB_HELP

    p = command_parser(
        sub, "runs", help="list the runs in a run store, or show one",
        description="List the runs of a run store (id, routine, status, points stored, "
        "model, robot id, start time, interruptions, beam breaks, points skipped, points "
        "re-measured, why it stopped; --robot-id: only that robot's); "
        "with RUN, show that run: its devices, context (tool, SMR, measurement frame, "
        "tracker checks, executor settings), summary and interruptions.")
    p.add_argument("run_id", nargs="?", type=positive_int, default=None, metavar="RUN",
                   help="show this run in detail, with its interruptions")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--robot-id", metavar="NAME", default=None, help="only this robot's runs")
    p.add_argument("--json", action="store_true",
                   help="print JSON (a list of runs, or one run with its context)")
    p.set_defaults(func=run)


def _time(t) -> str:
    """Local time, ISO 8601 (``2026-11-22 04:25:46``); ``-`` when unknown."""
    if t is None:
        return "-"
    return dt.datetime.fromtimestamp(t).isoformat(sep=" ", timespec="seconds")


def _run_dict(store, r) -> dict:
    return {"run": r.id, "routine": r.routine, "status": r.status, "reason": r.reason,
            "points": r.n_points, "samples": store.n_samples(r.id), "model": r.model,
            "robot_id": r.robot_id,
            "robot": r.robot_url, "tracker": r.tracker_url, "robot_desc": r.robot_desc,
            "tracker_desc": r.tracker_desc, "software": r.software, "seed": r.seed,
            "started": r.started, "stopped": r.stopped, "plan_hash": r.plan_hash,
            "frame": r.frame, "summary": None if r.summary is None else r.summary.to_json(),
            "remeasure": store.remeasure_counts(r.id)}


def _value(v) -> str:
    """A summary value for people: numbers to 4 decimals, lists comma-separated, a matrix
    row by row (``;``)."""
    if isinstance(v, bool) or v is None:
        return "-" if v is None else ("yes" if v else "no")
    if isinstance(v, float):
        return f"{v:.4f}".rstrip("0").rstrip(".") if math.isfinite(v) else str(v)
    if isinstance(v, (list, tuple)):
        sep = "; " if v and isinstance(v[0], (list, tuple)) else ", "
        return sep.join(_value(x) for x in v)
    return str(v)


def _flatten(d: dict, prefix: str = "") -> list[tuple[str, str]]:
    """Nested summary entries as (dotted key, value text) rows."""
    rows = []
    for k, v in d.items():
        if isinstance(v, dict):
            rows += _flatten(v, f"{prefix}{k}.")
        else:
            rows.append((f"{prefix}{k}", _value(v)))
    return rows


def _executor_text(context) -> str:
    """The executor settings that differ from the defaults (or ``defaults``)."""
    from daq.run_context import ExecutorOptions

    given = context.executor.model_dump()
    default = ExecutorOptions().model_dump()
    diff = [f"{k} {_value(v)}" for k, v in given.items() if v != default[k]]
    return ", ".join(diff) if diff else "defaults"


def print_run(store, r, interruptions) -> None:
    """One run for people: what, where, when, with what context; summary and interruptions
    as tables."""
    from .common import table

    c = r.context
    print(f"run {r.id} ({r.routine}): {r.status}, {store.n_samples(r.id)}/{r.n_points} points "
          f"stored" + (f"; {r.reason}" if r.reason else ""))
    tool = "" if c.tool_mm is None else ", tool " + ", ".join(f"{v:g}" for v in c.tool_mm) + " mm"
    print(f"{'model':10s} {r.model or '-'}{tool}")
    if c.smr_radius_mm is not None or c.reflector:
        print(f"{'SMR':10s} " + ", ".join(x for x in (
            c.reflector, None if c.smr_radius_mm is None else f"radius {c.smr_radius_mm:g} mm")
            if x))
    print(f"{'robot':10s} {r.robot_url or '-'}" + (f"  ({r.robot_desc})" if r.robot_desc else ""))
    if r.robot_id:
        print(f"{'robot id':10s} {r.robot_id}")
    print(f"{'tracker':10s} {r.tracker_url or '-'}"
          + (f"  ({r.tracker_desc})" if r.tracker_desc else ""))
    elapsed = (f" ({r.stopped - r.started:.1f} s)" if r.started and r.stopped else "")
    if r.source_run is not None:
        print(f"{'source':10s} the plan of run {r.source_run} (resumed in another cell)")
    print(f"{'started':10s} {_time(r.started)}, stopped {_time(r.stopped)}{elapsed}")
    print(f"{'plan':10s} {r.plan_hash[:16]}, {r.n_points} points"
          + ("" if r.seed is None else f", seed {r.seed}"))
    print(f"{'software':10s} {r.software or '-'}")
    if c.frame_run is not None:
        print(f"{'frame':10s} from run {c.frame_run}: tracker_T_base (robot base in the "
              "tracker frame, mm)")
        for row in c.tracker_T_base[:3]:
            print(" " * 11 + "  ".join(f"{v:12.6f}" for v in row))
    if c.tracker_check is not None:
        from .capture import check_line

        print(f"{'checks':10s} tracker: {check_line(c.tracker_check.model_dump(mode='json'))}")
    print(f"{'executor':10s} {_executor_text(c)}")
    if c.acquire:
        print(f"{'acquire':10s} " + ", ".join(f"{k} {_value(v)}" for k, v in c.acquire.items()))
    summary = {} if r.summary is None else r.summary.to_json()
    if r.frame:
        summary = {**{k: v for k, v in r.frame.items() if k != "tracker_T_base"}, **summary}
    if summary:
        print()
        print(table([list(kv) for kv in _flatten(summary)], ["summary", "value"], left=(0, 1)))
    print()
    if not interruptions:
        print("interruptions: none")
        return
    print(table([[_time(i["t"]), "-" if i["point"] is None else str(i["point"]), i["kind"],
                  i["message"]] for i in interruptions],
                ["interruption", "point", "kind", "message"], left=(0, 2, 3)))


def run(args) -> int:
    from daq.store import InterruptionKind, StoreError

    from .common import open_store, print_json, store_errors, table

    store = open_store(args.db, read_only=True)
    with store, store_errors(args.db):
        if args.run_id is not None:
            try:
                r = store.run(args.run_id)
            except StoreError as e:
                raise UsageError(str(e)) from None
            interruptions = [{"point": i.point_index, "t": i.t, "kind": i.kind,
                              "message": i.message} for i in store.interruptions(r.id)]
            rejected = [
                {"point": x.sample.point_index, "pose_id": x.sample.pose_id, "t": x.sample.t,
                 "xyz": [float(v) for v in x.sample.tracker_p_smr], "reason": x.reason}
                for x in store.readings(r.id)
            ]
            if args.json:
                d = _run_dict(store, r)
                d.update(robot_identity=r.robot_identity, tracker_identity=r.tracker_identity,
                         source_run=r.source_run)
                d["context"] = r.context.model_dump(mode="json")
                d["interruptions"] = interruptions
                d["rejected_readings"] = rejected
                print_json(d)
                return 0
            print_run(store, r, interruptions)
            if rejected:
                print(f"rejected readings ({len(rejected)}):")
                for x in rejected:
                    print(f"  {_time(x['t'])}  point {x['point']} ({x['pose_id']}): "
                          f"{x['reason']}")
            return 0
        runs = store.runs(args.robot_id)
        if args.json:
            print_json([_run_dict(store, r) for r in runs])
            return 0
        rows = []
        for r in runs:
            kinds = [i.kind for i in store.interruptions(r.id)]
            rows.append([str(r.id), r.routine, r.status, f"{store.n_samples(r.id)}/{r.n_points}",
                         r.model or "-", r.robot_id or "-", _time(r.started), len(kinds),
                         kinds.count(InterruptionKind.BEAM),
                         kinds.count(InterruptionKind.SKIPPED),
                         store.remeasure_counts(r.id)["suspects"], (r.reason or "")[:60]])
        print(table(rows, ["run", "routine", "status", "points", "model", "robot", "started",
                           "interruptions", "beam breaks", "skipped", "remeasured", "reason"],
                    left=(0, 1, 2, 4, 5, 6, 11)))
        return 0
