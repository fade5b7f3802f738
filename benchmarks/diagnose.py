"""Diagnosis speed: time to screen and rank every candidate effect, and to confirm the best.

UR10e with a hidden compliance:3, default model geometric,base,tool, 300 / 1 000 / 3 000
calibration poses (+ 500 validation poses). Prints the number of candidates screened
(every family on every joint, harmonic orders 1-60), the median time to screen and rank
them, and the time to confirm the best three (refits + held-out check).

    python benchmarks/diagnose.py
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis import diagnose
from calibration.simulate import random_joints, realistic_truth, simulate


def main() -> None:
    m = load_model("ur10e")
    print(f"{'poses':>6} {'candidates':>11} {'rank ms (median)':>17} {'confirm ms':>11} "
          f"{'total ms':>9}  best")
    for n in (300, 1000, 3000):
        em = ErrorModel(m, "geometric,base,tool,compliance:3")
        rng = np.random.default_rng(n)
        x = realistic_truth(em, rng)
        total = n + 500
        data = simulate(em, x, random_joints(m, total, rng), 0.015, rng,
                        is_valid=np.arange(total) >= n)
        fit = identify(ErrorModel(m), data)
        screens, confirms, totals = [], [], []
        for _ in range(5):
            t = time.perf_counter()
            d = diagnose(fit, data)
            totals.append(time.perf_counter() - t)
            screens.append(d.screen_s)
            confirms.append(d.confirm_s)
        print(f"{n:>6} {d.n_screened:>11} {statistics.median(screens) * 1000:>17.0f} "
              f"{statistics.median(confirms) * 1000:>11.0f} "
              f"{statistics.median(totals) * 1000:>9.0f}  {d.best.effect if d.best else '-'}")


if __name__ == "__main__":
    main()
