"""``cellcal runs``: list the runs in a run store (or show one with its context and
interruptions). The list counts each run's interruptions, its beam breaks and the points
skipped because the beam stayed broken (see :mod:`daq.executor`)."""

from __future__ import annotations

import datetime as dt

from ..cli import UsageError


def register(sub) -> None:
    from .common import DB_HELP

    p = sub.add_parser("runs", help="list the runs in a run store")
    p.add_argument("run_id", nargs="?", type=int, default=None, metavar="RUN",
                   help="show this run in detail, with its interruptions")
    p.add_argument("--db", required=True, metavar="cell.db|URL", help=DB_HELP)
    p.add_argument("--robot-id", metavar="NAME", default=None, help="only this robot's runs")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def _time(t):
    return "-" if t is None else dt.datetime.fromtimestamp(t).strftime("%Y-%m-%d %H:%M:%S")


def _run_dict(store, r) -> dict:
    return {"run": r.id, "routine": r.routine, "status": r.status, "reason": r.reason,
            "points": r.n_points, "samples": store.n_samples(r.id), "model": r.model,
            "robot_id": r.robot_id,
            "robot": r.robot_url, "tracker": r.tracker_url, "robot_desc": r.robot_desc,
            "tracker_desc": r.tracker_desc, "software": r.software, "seed": r.seed,
            "started": r.started, "stopped": r.stopped, "plan_hash": r.plan_hash,
            "frame": r.frame, "summary": r.summary}


def run(args) -> int:
    from ..store import StoreError
    from .common import open_store, print_json, table

    store = open_store(args.db)
    try:
        if args.run_id is not None:
            try:
                r = store.run(args.run_id)
            except StoreError as e:
                raise UsageError(str(e)) from None
            d = _run_dict(store, r)
            d.update(robot_identity=r.robot_identity, tracker_identity=r.tracker_identity,
                     source_run=r.source_run)
            d["context"] = r.context.model_dump(mode="json")
            d["interruptions"] = [
                {"point": p, "t": t, "kind": k, "message": m}
                for p, t, k, m in store.interruptions(r.id)
            ]
            if args.json:
                print_json(d)
                return 0
            for k, v in d.items():
                if k not in ("interruptions", "frame", "context"):
                    print(f"{k:13s} {v}")
            print(f"{'context':13s} {r.context.to_json()}")
            if r.frame:
                print(f"{'frame':13s} tracker_T_base {r.frame['tracker_T_base'][:3]}")
            print(f"interruptions ({len(d['interruptions'])}):")
            for i in d["interruptions"]:
                print(f"  {_time(i['t'])}  point {i['point']}  {i['kind']}: {i['message']}")
            return 0
        runs = store.runs(args.robot_id)
        if args.json:
            print_json([_run_dict(store, r) for r in runs])
            return 0
        rows = []
        for r in runs:
            kinds = [k for _, _, k, _ in store.interruptions(r.id)]
            rows.append([str(r.id), r.routine, r.status, f"{store.n_samples(r.id)}/{r.n_points}",
                         r.model or "-", r.robot_id or "-", _time(r.started), len(kinds),
                         kinds.count("beam"), kinds.count("skipped"), (r.reason or "")[:60]])
        print(table(rows, ["run", "routine", "status", "points", "model", "robot", "started",
                           "interruptions", "beam breaks", "skipped", "reason"]))
        return 0
    finally:
        store.close()
