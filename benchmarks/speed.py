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
  model it ends with;
- the command, end to end: ``cellcal calibrate`` of 150 poses (a CSV from ``cellcal
  simulate``; a fresh process, its start included) against the same process's fit alone
  by the textbook LM, and ``cellcal --help`` against ``python -c "import numpy"``
  (median wall time of fresh processes).

BLAS runs on one thread (as identify runs a small problem). Each figure is wall time;
with ``--cpu`` the in-process rows give the process's CPU time instead (on a shared
machine what a lone user would wait, whatever the neighbours do).

    python benchmarks/speed.py                   # the table (minutes)
    python benchmarks/speed.py --only identify   # some rows: identify, auto, command
    python benchmarks/speed.py --quick           # tiny sizes, one run: that it works
    PYTHONPATH=DIR python benchmarks/speed.py    # another checkout's code (before/after)
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from diagnose import auto_problem
from identify import problem
from reference_lm import textbook_lm
from threadpoolctl import threadpool_limits

import calibration
from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.auto_diagnosis import auto_diagnose
from calibration.fit.identify import structural_identifiability
from calibration.numerics.heap import keep_freed_memory

#: the checkout measured: the one ``calibration`` is imported from (PYTHONPATH)
ROOT = Path(calibration.__file__).resolve().parents[1]
#: the clock of the in-process rows (``--cpu``: the process's CPU time)
CLOCK = time.perf_counter


def median_s(fn, runs: int) -> float:
    """Median time of ``fn()`` over ``runs`` calls (:data:`CLOCK`)."""
    times = []
    for _ in range(runs):
        t = CLOCK()
        fn()
        times.append(CLOCK() - t)
    return statistics.median(times)


def solve_s(fit, runs: int) -> float:
    """Median ``Fit.solve_s`` of ``fit()`` over ``runs`` calls (``--cpu``: the CPU time of
    the whole call)."""
    if CLOCK is time.process_time:
        return median_s(fit, runs)
    return statistics.median(fit().solve_s for _ in range(runs))


def timed(fn) -> tuple[object, float]:
    """``fn()`` and its time (:data:`CLOCK`)."""
    t = CLOCK()
    out = fn()
    return out, CLOCK() - t


def row(what: str, value_s: float, ref_s: float, unit: str = "ms") -> None:
    f, d = (1000.0, 1) if unit == "ms" else (1.0, 2)
    print(f"| {what:<46} | {value_s * f:>9.{d}f} {unit:<2} | {ref_s * f:>9.{d}f} {unit:<2} "
          f"| {value_s / ref_s:>6.2f} |")


def identification(n: int, runs: int) -> None:
    data = problem(n)
    em = ErrorModel(load_model("ur10e"))
    calib = em.prepare(data).calib()
    fit = identify(em, data)  # warm-up; its free parameters for the reference
    ref = median_s(lambda: textbook_lm(em, calib, fit.free), runs)
    screened = solve_s(lambda: identify(em, data), runs)
    kept = solve_s(lambda: identify(em, data, outliers="keep"), runs)
    struct = median_s(lambda: structural_identifiability(em, calib), runs)
    row(f"identify {n} poses, blunder test (default)", screened, ref)
    row(f"identify {n} poses, --outliers keep", kept, ref)
    row(f"structural identifiability, {n} poses", struct, ref)


def auto(n: int, max_steps: int) -> None:
    data = auto_problem(n)
    fit = identify(ErrorModel(load_model("ur10e")), data)
    res, took = timed(lambda: auto_diagnose(fit, data, max_steps=max_steps))
    ref = timed(lambda: textbook_lm(res.fit.error_model, data.calib(), res.fit.free))[1]
    row(f"diagnose --auto {n} poses ({len(res.steps)} steps)", took, ref, "s")
    print(f"|   steps: {', '.join(s.effect for s in res.steps)}")


def process_s(args: list[str], runs: int) -> float:
    """Median wall time of a fresh ``python args...`` process (start included), run in the
    checkout measured (``python -m`` puts the working directory before PYTHONPATH)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        subprocess.run([sys.executable, *args], env=env, check=True, cwd=ROOT,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def command(n: int, runs: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        csv = str(Path(tmp) / "poses.csv")
        subprocess.run([sys.executable, "-m", "cellcal", "simulate", "--model", "ur10e",
                        "--poses", str(n), "--valid", "0", "--out", csv], check=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, cwd=ROOT,
                       stdout=subprocess.DEVNULL)
        calib = process_s(["-m", "cellcal", "calibrate", "--model", "ur10e", csv], runs)
        from calibration import load_csv

        model = load_model("ur10e")
        data = load_csv(csv, model)
        em = ErrorModel(model)
        with threadpool_limits(limits=1, user_api="blas"):
            free = identify(em, data).free
            ref = median_s(lambda: textbook_lm(em, em.prepare(data), free), runs)
    row(f"cellcal calibrate {n} poses (process)", calib, ref, "s")
    numpy = process_s(["-c", "import numpy"], runs)
    row("cellcal --help (process) vs import numpy", process_s(["-m", "cellcal", "--help"],
                                                                runs), numpy, "s")


def main(quick: bool, only: set[str]) -> None:
    keep_freed_memory()  # as identify does: the reference runs first
    clock = "CPU" if CLOCK is time.process_time else "wall"
    print(f"one BLAS thread; {clock} time; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores; reference: a textbook numpy LM on the same problem\n")
    print(f"| {'':<46} | {'time':>12} | {'reference':>12} | {'ratio':>6} |")
    print(f"|{'-' * 48}|{'-' * 14}|{'-' * 14}|{'-' * 8}|")
    if "auto" in only:  # the diagnosis loads scipy, and with it a BLAS of its own: load it
        import scipy.linalg  # noqa: F401 - before the limit below, which pins only the
        import scipy.special  # noqa: F401 - libraries loaded when it is entered
    with threadpool_limits(limits=1, user_api="blas"):
        if "identify" in only:
            identification(60 if quick else 1000, 1 if quick else 15)
        if "auto" in only:
            for n in (60,) if quick else (500, 2000):
                auto(n, 1 if quick else 12)
    if "command" in only:
        command(30 if quick else 150, 1 if quick else 7)
    print(f"\nload average afterwards {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    import argparse

    ROWS = ("identify", "auto", "command")
    ap = argparse.ArgumentParser(description="The speed table of docs/speed.md.")
    ap.add_argument("--quick", action="store_true", help="tiny sizes (the tests' smoke run)")
    ap.add_argument("--cpu", action="store_true",
                    help="CPU time of the in-process rows instead of wall time")
    ap.add_argument("--only", default=",".join(ROWS), metavar="ROWS",
                    help=f"comma-separated rows of {', '.join(ROWS)} (default all)")
    a = ap.parse_args()
    rows = set(a.only.split(","))
    if rows - set(ROWS):
        ap.error(f"--only: unknown rows {', '.join(sorted(rows - set(ROWS)))}")
    if a.cpu:
        CLOCK = time.process_time
    main(a.quick, rows)
