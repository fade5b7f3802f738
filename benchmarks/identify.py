"""Identification speed and accuracy: default model (geometric,base,tool), UR10e.

For 100, 1 000 and 10 000 calibration poses (plus 2 000 validation poses), prints the
median identification time over several runs (including binding, the identifiability
QR and the solve), the peak memory the identification allocates (tracemalloc), and the
validation RMS divided by the noise floor sqrt(3)*sigma.

    python benchmarks/identify.py
"""

from __future__ import annotations

import statistics
import time
import tracemalloc

import numpy as np

from calibration import ErrorModel, identify, load_model
from calibration.simulate import random_joints, realistic_truth, simulate

SIGMA = 0.015


def main() -> None:
    m = load_model("ur10e")
    em = ErrorModel(m)
    print(f"model ur10e, effects {','.join(em.labels)}, {em.n_params} parameters, "
          f"sigma {SIGMA} mm per axis")
    print(f"{'poses':>7} {'median ms':>10} {'min ms':>8} {'runs':>5} {'iters':>6} "
          f"{'peak MB':>8} {'valid RMS/floor':>16}")
    for n in (100, 1000, 10000):
        rng = np.random.default_rng(n)
        x = realistic_truth(em, rng)
        q = random_joints(m, n + 2000, rng)
        data = simulate(em, x, q, SIGMA, rng, is_valid=np.arange(n + 2000) >= n)
        runs = 15 if n <= 1000 else 5
        times = []
        fit = None
        for _ in range(runs):
            t = time.perf_counter()
            fit = identify(em, data)
            times.append(time.perf_counter() - t)
        tracemalloc.start()
        identify(em, data)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        ratio = fit.valid["rms_mm"] / data.noise_floor_mm()
        print(f"{n:>7} {statistics.median(times) * 1000:>10.1f} {min(times) * 1000:>8.1f} "
              f"{runs:>5} {fit.iterations:>6} {peak:>8.1f} {ratio:>16.3f}")


if __name__ == "__main__":
    main()
