"""Ten weekly recalibrations of one simulated UR10e whose joint-2 zero creeps, then jumps.

Writes ``cal01.csv`` ... ``cal10.csv`` (measurement CSVs, docs/formats.md §1) into the
directory given: 300 random poses each, measured with 0.015 mm tracker noise on Mondays
06:00 UTC one week apart (the ``t_s`` column holds the epoch times). The robot's hidden
errors (geometric, base, tool: :func:`calibration.fit.simulate.realistic_truth`) stay the
same, except the zero of joint 2, which creeps by +0.0002 deg a week and slips by
+0.010 deg between the 6th and the 7th calibration (a collision). Calibrate each with
``--db ... --robot-id ...`` and ``cellcal history`` shows both (docs/history.md).

    python examples/zero_drift.py DIR [--seed 3]
"""

from __future__ import annotations

import argparse
import datetime as dt
from pathlib import Path

import numpy as np

from calibration import DEFAULT_EFFECTS, ErrorModel, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate

#: the hidden joint-2 zero error added at each calibration (deg): a creep and a slip
CREEP_DEG_PER_WEEK = 0.0002
SLIP_DEG, SLIP_BEFORE = 0.010, 6  # added from the 7th calibration (index 6) on
START = dt.datetime(2025, 1, 6, 6, 0, tzinfo=dt.UTC)
WEEK_S = 7 * 24 * 3600.0


def joint2_shift_deg(k: int) -> float:
    """The change of the joint-2 zero at calibration ``k`` (0-based) since the first."""
    return CREEP_DEG_PER_WEEK * k + (SLIP_DEG if k >= SLIP_BEFORE else 0.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--poses", type=int, default=300)
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    model = load_model("ur10e")
    em = ErrorModel(model, DEFAULT_EFFECTS)
    truth = realistic_truth(em, np.random.default_rng(args.seed))
    j2 = em.index("geometric.j2.theta")
    for k in range(10):
        rng = np.random.default_rng([args.seed, k])
        x = truth.copy()
        x[j2] += np.radians(joint2_shift_deg(k))
        q = random_joints(model, args.poses, rng)
        t0 = START.timestamp() + k * WEEK_S
        data = simulate(em, x, q, 0.015, rng, t_s=t0 + np.linspace(0.0, 3600.0, args.poses))
        data.meta = {"source": f"examples/zero_drift.py --seed {args.seed}: week {k + 1}, "
                     f"joint-2 zero {joint2_shift_deg(k):+.4f} deg", **data.meta}
        data.to_csv(args.dir / f"cal{k + 1:02d}.csv")
    print(f"wrote {args.dir}/cal01.csv ... cal10.csv: {args.poses} poses a week of a simulated "
          f"UR10e; joint-2 zero +{CREEP_DEG_PER_WEEK} deg/week, +{SLIP_DEG} deg before the "
          f"{SLIP_BEFORE + 1}th")


if __name__ == "__main__":
    main()
