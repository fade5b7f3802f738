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
"""

from __future__ import annotations

import numpy as np

from ..plans import Plan, Target
from ._common import floats


def make_plan(model, *, target_xyz=None, seed_deg=None, seed: int = 0) -> Plan:
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
    """
    from calibration.zero_point import zero20_postures

    if model.n_joints < 6:
        raise ValueError(f"zero20: model {model.name} has {model.n_joints} joints; 20 distinct "
                         "postures on one point need an arm that orients its tool (6+ joints)")
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


def finalize(plan: Plan, samples: dict, run) -> dict:
    """Spread of the measured tips (they should all be on the target)."""
    xyz = samples["xyz"]
    spread = np.linalg.norm(xyz - xyz.mean(axis=0), axis=1)
    return {"summary": {**(run.summary or {}), "tip_spread_max_mm": float(spread.max()),
                        "tip_spread_rms_mm": float(np.sqrt(np.mean(spread**2)))}}


def add_args(p) -> None:
    p.add_argument("--target-xyz", metavar="X,Y,Z", help="fixed target point, mm (base frame)")
    p.add_argument("--seed-deg", metavar="Q1,..,QN", help="preferred configuration, deg")


def params_from_args(args) -> dict:
    return {"target_xyz": floats(args.target_xyz, 3, "--target-xyz"),
            "seed_deg": floats(args.seed_deg, None, "--seed-deg"), "seed": args.seed or 0}

