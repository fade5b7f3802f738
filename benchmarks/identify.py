"""Identification speed and accuracy: default model (geometric,base,tool), UR10e; idle and
with another process saturating a core.

For 100, 1 000 and 10 000 calibration poses (plus 2 000 validation poses), prints the
median identification time (``Fit.solve_s``: binding, the identifiability QR, the solve,
the validation) over several runs, idle and while a busy-loop process holds a core,
with BLAS pinned to one thread for small problems (the default,
:mod:`calibration.numerics.blas`) and with BLAS's default threads; then the peak memory the
identification allocates (tracemalloc) and the validation RMS divided by the noise floor
sqrt(3)*sigma. The claim: pinned, the loaded time stays within 1.5x of the idle one.

    python benchmarks/identify.py            # all sizes
    python benchmarks/identify.py 1000       # one size
    python benchmarks/identify.py --quick    # a tiny problem, one run: that it works
"""

from __future__ import annotations

import contextlib
import multiprocessing
import statistics
import sys
import time
import tracemalloc

import numpy as np

import calibration.numerics.blas
from calibration import ErrorModel, identify, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate

SIGMA = 0.015


def _spin(stop) -> None:  # pragma: no cover - runs in the load process
    while not stop.is_set():
        for _ in range(100_000):
            pass


@contextlib.contextmanager
def load(busy: bool):
    """Another process saturating one core while the block runs (when ``busy``)."""
    if not busy:
        yield
        return
    stop = multiprocessing.Event()
    p = multiprocessing.Process(target=_spin, args=(stop,), daemon=True)
    p.start()
    time.sleep(0.3)
    try:
        yield
    finally:
        stop.set()
        p.join(5)
        if p.is_alive():
            p.kill()
            p.join()


def median_solve_s(em, data, runs: int, pinned: bool) -> tuple[float, object]:
    small = calibration.numerics.blas.SMALL_ELEMENTS
    calibration.numerics.blas.SMALL_ELEMENTS = small if pinned else -1
    try:
        fits = [identify(em, data) for _ in range(runs)]
    finally:
        calibration.numerics.blas.SMALL_ELEMENTS = small
    return statistics.median(f.solve_s for f in fits), fits[-1]


def problem(n: int, n_valid: int = 2000):
    """The benchmark's data: UR10e, default model, ``n`` calibration + ``n_valid``
    validation poses, sigma :data:`SIGMA` (seeded by ``n``)."""
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(n)
    x = realistic_truth(em, rng)
    q = random_joints(m, n + n_valid, rng)
    return simulate(em, x, q, SIGMA, rng, is_valid=np.arange(n + n_valid) >= n)


def main(sizes=(100, 1000, 10000), runs: int | None = None) -> None:
    m = load_model("ur10e")
    em = ErrorModel(m)
    print(f"model ur10e, effects {','.join(em.labels)}, {em.n_params} parameters, "
          f"sigma {SIGMA} mm per axis; median solve_s in ms; 'loaded': another process "
          "saturates a core")
    head = (f"{'poses':>6} {'BLAS':>8} {'idle ms':>8} {'loaded ms':>10} {'loaded/idle':>12} "
            f"{'runs':>5} {'iters':>6} {'peak MB':>8} {'valid RMS/floor':>16}")
    print(head)
    print("-" * len(head))
    for n in sizes:
        data = problem(n)
        n_runs = runs or (15 if n <= 1000 else 5)
        identify(em, data)  # warm-up (imports, the BLAS controller)
        tracemalloc.start()
        fit = identify(em, data)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        ratio = fit.valid["rms_mm"] / data.noise_floor_mm()
        for pinned in (True, False):
            idle, _ = median_solve_s(em, data, n_runs, pinned)
            with load(True):
                loaded, _ = median_solve_s(em, data, n_runs, pinned)
            small = calibration.numerics.blas.SMALL_ELEMENTS
            label = ("1 thread" if 3 * (n + 2000) * em.n_params
                     <= small else "default") if pinned else "default"
            print(f"{n:>6} {label:>8} {idle * 1000:>8.1f} {loaded * 1000:>10.1f} "
                  f"{loaded / idle:>12.2f} {n_runs:>5} {fit.iterations:>6} {peak:>8.1f} "
                  f"{ratio:>16.3f}")


if __name__ == "__main__":
    if "--quick" in sys.argv[1:]:  # that the script works: a tiny problem, one run each
        main((30,), runs=1)
    else:
        main(tuple(int(a) for a in sys.argv[1:]) or (100, 1000, 10000))
