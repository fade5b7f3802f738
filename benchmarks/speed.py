"""The speed table of docs/speed.md: each figure beside a plain reference measured in the
same run, and the ratio (the machine is shared: the ratio cancels most of its load).

The reference is a textbook numpy Levenberg-Marquardt on the same problem
(:mod:`reference_lm`: same model, analytic Jacobian, start and free parameters; nothing
else). Rows:

- ``identify``, 1 000 calibration + 2 000 validation poses, UR10e, geometric,base,tool:
  median ``Fit.solve_s`` with the blunder test (the default) and without it
  (``--outliers keep``), and the structural identifiability check alone;
- ``diagnose --auto`` on 500 and 2 000 poses with fifteen hidden effects (the loop of
  benchmarks/diagnose.py): the whole loop, its steps, against one textbook fit of the
  model it ends with.

BLAS runs on one thread (as identify runs a small problem).

    python benchmarks/speed.py            # the table (minutes)
    python benchmarks/speed.py --quick    # tiny sizes, one run: that the script works
"""

from __future__ import annotations

import os
import statistics
import sys
import time

from diagnose import auto_problem
from identify import problem
from reference_lm import textbook_lm
from threadpoolctl import threadpool_limits

from calibration import ErrorModel, identify, load_model
from calibration.auto_diagnosis import auto_diagnose
from calibration.heap import keep_freed_memory
from calibration.identify import structural_identifiability


def median_s(fn, runs: int) -> float:
    """Median wall time of ``fn()`` over ``runs`` calls."""
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def row(what: str, value_s: float, ref_s: float, unit: str = "ms") -> None:
    f = 1000.0 if unit == "ms" else 1.0
    print(f"| {what:<46} | {value_s * f:>9.1f} {unit:<2} | {ref_s * f:>9.1f} {unit:<2} "
          f"| {value_s / ref_s:>6.2f} |")


def identification(n: int, runs: int) -> None:
    data = problem(n)
    em = ErrorModel(load_model("ur10e"))
    calib = em.prepare(data).calib()
    fit = identify(em, data)  # warm-up; its free parameters for the reference
    ref = median_s(lambda: textbook_lm(em, calib, fit.free), runs)
    screened = statistics.median(identify(em, data).solve_s for _ in range(runs))
    kept = statistics.median(identify(em, data, outliers="keep").solve_s
                             for _ in range(runs))
    struct = median_s(lambda: structural_identifiability(em, calib), runs)
    row(f"identify {n} poses, blunder test (default)", screened, ref)
    row(f"identify {n} poses, --outliers keep", kept, ref)
    row(f"structural identifiability, {n} poses", struct, ref)


def auto(n: int, max_steps: int) -> None:
    data = auto_problem(n)
    fit = identify(ErrorModel(load_model("ur10e")), data)
    res = auto_diagnose(fit, data, max_steps=max_steps)
    ref = textbook_lm(res.fit.error_model, data.calib(), res.fit.free)[2]
    row(f"diagnose --auto {n} poses ({len(res.steps)} steps)", res.total_s, ref, "s")


def main(quick: bool) -> None:
    keep_freed_memory()  # as identify does: the reference runs first
    print(f"one BLAS thread; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} "
          "cores; reference: a textbook numpy LM on the same problem\n")
    print(f"| {'':<46} | {'time':>12} | {'reference':>12} | {'ratio':>6} |")
    print(f"|{'-' * 48}|{'-' * 14}|{'-' * 14}|{'-' * 8}|")
    with threadpool_limits(limits=1, user_api="blas"):
        identification(60 if quick else 1000, 1 if quick else 15)
        for n in (60,) if quick else (500, 2000):
            auto(n, 1 if quick else 12)
    print(f"\nload average afterwards {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main("--quick" in sys.argv[1:])
