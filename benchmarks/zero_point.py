"""Zero-point recalibration: the published seed method against the rigorous one.

A simulated UR10e whose joint zeros moved (hidden offsets 0.05-0.5 deg on every joint)
and whose tool is unknown; 20 postures (5 on each of 4 planes) taught on one point with
0.02 mm tip scatter (3-D RMS). For each scenario and method, over several trials: the
worst error of the determined offsets (joints 2-5), iterations, time, flagged outliers.

Scenarios: ``nominal``; ``bad start`` (joint 2 off by 1 deg more); ``wrong posture``
(one posture taught 2 mm off the target).

Run: ``.venv/bin/python benchmarks/zero_point.py [--trials 10]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from calibration import load_model
from calibration.model.inverse import ChainFK
from calibration.zero_point import rigorous_method, seed_method, simulate_postures

TOOL = np.array([12.0, -8.0, 135.0])
TARGET = np.array([700.0, 150.0, 250.0])


def scenario(name: str, rng: np.random.Generator):
    m = load_model("ur10e")
    hidden = rng.uniform(0.05, 0.5, 6) * rng.choice([-1, 1], 6)
    if name == "bad start":
        hidden[1] += 1.0
    post, _ = simulate_postures("dh", m.dh_table(), np.radians(hidden), TOOL, TARGET,
                                scatter_mm=0.02 / np.sqrt(3), limits=m.limits_rad(), rng=rng)
    wrong = None
    if name == "wrong posture":
        fk = ChainFK.from_model(m)
        k = int(rng.integers(post.n))
        _, _, Jp, _ = fk(post.q[k:k + 1])
        post.q[k] += np.linalg.pinv(Jp[0]) @ np.array([0.0, 2.0, 0.0])
        wrong = post.pose_id[k]
    return m, post, np.radians(hidden), wrong


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=10)
    args = ap.parse_args()
    rows = []
    for name in ("nominal", "bad start", "wrong posture"):
        stats = {"seed": [], "rigorous": []}
        for trial in range(args.trials):
            rng = np.random.default_rng(1000 + trial)
            m, post, hidden, wrong = scenario(name, rng)
            fk = ChainFK.from_model(m)
            for method in stats:
                t0 = time.perf_counter()
                if method == "seed":
                    r = seed_method(fk, post, rng=np.random.default_rng(trial))
                else:
                    r = rigorous_method(fk, post)
                dt = time.perf_counter() - t0
                err = np.degrees(np.abs(r.offsets - hidden))[r.determined].max()
                flagged = wrong is not None and r.outliers == [wrong]
                stats[method].append((err, r.iterations, dt, r.converged, flagged))
        for method, s in stats.items():
            a = np.array(s, float)
            rows.append([name, method, f"{np.sqrt(np.mean(a[:, 0] ** 2)):.4f}",
                         f"{a[:, 0].max():.4f}", f"{int((a[:, 0] < 0.005).sum())}/{len(a)}",
                         f"{a[:, 1].mean():.0f}", f"{a[:, 2].mean() * 1000:.0f}",
                         f"{int(a[:, 3].sum())}/{len(a)}",
                         f"{int(a[:, 4].sum())}/{len(a)}" if name == "wrong posture" else "-"])
    head = ["scenario", "method", "rms err deg", "max err deg", "< 0.005 deg", "iterations",
            "ms", "converged", "outlier flagged"]
    widths = [max(len(str(r[i])) for r in [head, *rows]) for i in range(len(head))]
    print(f"UR10e, hidden zero offsets 0.05-0.5 deg, unknown tool, 20 postures on one point, "
          f"0.02 mm tip scatter; {args.trials} trials per scenario; errors over joints 2-5 "
          "(joints 1 and 6 are undetermined by a single point)")
    print("  ".join(h.ljust(w) for h, w in zip(head, widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for r in rows:
        print("  ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)))


if __name__ == "__main__":
    main()
