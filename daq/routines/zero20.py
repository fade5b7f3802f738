"""``zero20``: the 20-posture, 4-plane zero-point routine.

20 different postures, 5 on each of 4 vertical planes through a fixed target
point, each bringing the tool tip to the target
(:func:`calibration.zero_point.zero20_postures` on the nominal model). Each
point is a ``zero`` target: the executor moves to the posture, then, with a
tracker, closes the loop with damped-least-squares joint corrections until the
measured tip is on the target within ``zero_tol_mm`` (the target in the
tracker frame is fixed by the first posture), and records the joints.

Needs an arm that can orient its tool (6 joints or more): a smaller arm reaches
a point in too few postures.

Replay (``--replay RUN``, :func:`replay_plan`): the same 20 postures again, from
the joints recorded in run RUN's samples (not re-solved): for the seed method's
second, fine pass after a manual adjustment of the joint zeros. The executor
moves to each recorded posture and closes the loop again from there.
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ._common import floats


def make_plan(model, *, target_xyz=None, seed_deg=None, seed: int = 0,
              replay: dict | None = None) -> Plan:
    """The zero20 plan.

    Parameters
    ----------
    model : RobotModel
    target_xyz : sequence of 3 float
        The fixed target point (mm, base frame).
    seed_deg : sequence of float, optional
        Preferred configuration (deg).
    seed : int
        Seed of the IK's extra random starts.
    replay : dict, optional
        Replay recorded postures instead (see :func:`replay_plan`): keys ``run``
        (source run id), ``q`` ((20, N) joints read, rad), ``plane`` ((20,)), ``label``
        (20 str), ``target_xyz_mm`` (the source plan's target, mm).
    """
    from calibration.zero_point import zero20_postures

    if replay is not None:
        return replay_plan(model, **replay)

    if model.n_joints < 6:
        raise ValueError(f"zero20: model {model.name} has {model.n_joints} joints; 20 distinct "
                         "postures on one point need an arm that orients its tool (6+ joints)")
    if model.prismatic_mask() is not None:
        raise ValueError(f"zero20: model {model.name} has a prismatic joint: the zero-point "
                         "routine handles revolute joints only")
    if target_xyz is None:
        raise ValueError("zero20: the target point is required (--target-xyz X,Y,Z)")
    target = np.asarray(target_xyz, float)
    q_seed = np.radians(seed_deg) if seed_deg is not None else None
    q, plane, ok = zero20_postures(model.convention, model.dh_table(), model.tool_mm(), target,
                                   q_seed=q_seed, limits=model.limits_rad(),
                                   rng=np.random.default_rng(seed))
    if not ok.all():
        bad = (np.flatnonzero(~ok) + 1).tolist()
        raise ValueError(f"zero20: postures {bad} cannot reach the target {target.tolist()} mm")
    per = {}
    targets = []
    for i in range(len(q)):
        k = int(plane[i])
        per[k] = per.get(k, 0) + 1
        targets.append(Target(i, "zero", q=q[i], xyz=target, label=f"p{k}.{per[k]}",
                              info={"plane": k}))
    params = {"target_xyz_mm": target.tolist(),
              "seed_deg": None if q_seed is None else np.degrees(q_seed).tolist(), "seed": seed}
    return Plan("zero20", params, tuple(targets), model=model.name)


def replay_plan(model, *, run: int, q, plane, label, target_xyz_mm) -> Plan:
    """A zero20 plan that replays the postures recorded in run ``run``.

    Parameters
    ----------
    model : RobotModel
    run : int
        The source run (recorded in the plan's parameters).
    q : (n, N) array
        Joints read at each recorded posture, rad (the new targets, not re-solved).
    plane : (n,) int
        Plane 1..4 of each posture.
    label : sequence of str
        The postures' labels (kept).
    target_xyz_mm : sequence of 3 float
        The source plan's nominal target point (mm, base frame).
    """
    q = np.atleast_2d(np.asarray(q, float))
    if q.shape[1] != model.n_joints:
        raise ValueError(f"zero20 --replay {run}: the run has {q.shape[1]} joints, model "
                         f"{model.name} has {model.n_joints}")
    target = np.asarray(target_xyz_mm, float)
    targets = tuple(Target(i, "zero", q=q[i], xyz=target, label=str(label[i]),
                           info={"plane": int(plane[i])}) for i in range(len(q)))
    params = {"target_xyz_mm": target.tolist(), "replay_run": int(run)}
    return Plan("zero20", params, targets, model=model.name)


def replay_source(db: str, run_id: int) -> dict:
    """The ``replay`` argument of :func:`make_plan` from run ``run_id`` of the store ``db``.

    The run must be a completed ``zero20`` run; ValueError otherwise.
    """
    from pathlib import Path

    from ..plans import Plan
    from ..store import RunStore, StoreError

    if not Path(db).exists():
        raise ValueError(f"--replay {run_id}: {db}: no such run store")
    with RunStore(db) as store:
        try:
            r = store.run(run_id)
        except StoreError as e:
            raise ValueError(f"--replay {run_id}: {e}") from None
        if r.routine != "zero20" or r.status != "completed":
            raise ValueError(f"--replay {run_id}: run {run_id} is a {r.status} {r.routine} run, "
                             "not a completed zero20 run")
        s = store.samples(r.id)
    src = Plan.from_json(r.plan_json)
    return {"run": r.id, "q": s["q"], "label": s["pose_id"],
            "plane": [int(t["info"]["plane"]) for t in s["target"]],
            "target_xyz_mm": src.params["target_xyz_mm"]}


def finalize(plan: Plan, samples: dict, run) -> dict:
    """Spread of the measured tips (they should all be on the target)."""
    xyz = samples["xyz"]
    spread = np.linalg.norm(xyz - xyz.mean(axis=0), axis=1)
    return {"summary": {**(run.summary or {}), "tip_spread_max_mm": float(spread.max()),
                        "tip_spread_rms_mm": float(np.sqrt(np.mean(spread**2)))}}


def add_args(p) -> None:
    p.add_argument("--target-xyz", metavar="X,Y,Z", help="fixed target point, mm (base frame)")
    p.add_argument("--seed-deg", metavar="Q1,..,QN", help="preferred configuration, deg")
    p.add_argument("--replay", type=int, metavar="RUN", default=None,
                   help="replay the 20 postures recorded in run RUN of --db (their joints, "
                   "not re-solved), closing the loop again: the fine pass after a manual "
                   "adjustment of the joint zeros")


def params_from_args(args) -> dict:
    if getattr(args, "replay", None) is not None:
        if args.target_xyz is not None or args.seed_deg is not None:
            raise ValueError("zero20: --replay takes the postures (and target) from the run; "
                             "drop --target-xyz/--seed-deg")
        return {"replay": replay_source(args.db, args.replay)}
    return {"target_xyz": floats(args.target_xyz, 3, "--target-xyz"),
            "seed_deg": floats(args.seed_deg, None, "--seed-deg"), "seed": args.seed or 0}

