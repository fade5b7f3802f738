"""Diagnosis speed.

1. Ranking: time to screen and rank every candidate effect, and to confirm the best
   (``diagnose``): UR10e with a hidden compliance:3, default model geometric,base,tool,
   300 / 1 000 / 3 000 calibration poses (+ 500 validation poses).
2. The automatic loop (``diagnose --auto``): UR10e with fifteen hidden effects (harmonics
   of orders 1, 2, 3, 8, 12 and 20 on six joints, compliance of joints 2 and 3, backlash
   of joints 3 and 5, scale of joints 2 and 4, coupling,
   and two local bumps 3-4 degrees wide), 500 and 2 000 calibration poses
   (+ 40 % validation poses), up to 12 steps. Prints every step: the effect added, its
   parameters, calibration and held-out RMS, the time to screen, the longest refit and the
   whole step; then the total and the machine's load average (the machine is shared:
   read the times with the load).

    python benchmarks/diagnose.py            # both parts
    python benchmarks/diagnose.py auto       # only the automatic loop
    python benchmarks/diagnose.py --quick    # a tiny loop of one step: that it works
"""

from __future__ import annotations

import os
import statistics
import sys
import time

import numpy as np
from reference_lm import textbook_lm  # beside this script

from calibration import ErrorModel, identify, load_model
from calibration.diagnosis.auto_diagnosis import auto_diagnose
from calibration.diagnosis.diagnosis import diagnose
from calibration.effects import parse_effects
from calibration.fit.simulate import Bump, random_joints, realistic_truth, simulate

HIDDEN = ("harmonic20:2,harmonic2:3,harmonic:1,harmonic8:5,harmonic3:4,compliance:2,"
          "compliance:3,backlash:3,scale:2,coupling:5,harmonic12:6,scale:4,backlash:5")


def ranking() -> None:
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


def auto_problem(n: int):
    """The automatic loop's data: UR10e with the fifteen hidden effects, ``n`` calibration
    + 40 % validation poses (seeded)."""
    m = load_model("ur10e")
    effects = parse_effects("geometric,base,tool," + HIDDEN, m)
    effects += [Bump(m, 2, 30.0, 4.0), Bump(m, 4, -60.0, 3.0)]
    em = ErrorModel(m, effects)
    rng = np.random.default_rng(11)
    x = realistic_truth(em, rng)
    nv = int(0.4 * n)
    total = n + nv
    q = random_joints(m, total, rng)
    dirs = np.zeros((total, 6), int)
    dirs[1:] = np.sign(np.diff(q, axis=0))
    is_valid = np.zeros(total, bool)
    is_valid[rng.choice(total, nv, replace=False)] = True
    return simulate(em, x, q, 0.015, rng, is_valid=is_valid, dirs=dirs)


def auto_loop(n: int, max_steps: int = 12) -> None:
    m = load_model("ur10e")
    data = auto_problem(n)
    nv = int(data.is_valid.sum())
    load0 = os.getloadavg()[0]
    fit = identify(ErrorModel(m), data)
    print(f"\n--auto, {n} calibration + {nv} validation poses, 15 hidden effects "
          f"(noise floor {data.noise_floor_mm():.4f} mm), load average {load0:.1f} on "
          f"{os.cpu_count()} cores")
    print(f"{'step':>4}  {'effect':<14} {'params':>6} {'calib mm':>9} {'held-out mm':>11} "
          f"{'screen s':>8} {'max refit s':>11} {'step s':>7}")
    print(f"{0:>4}  {'(start)':<14} {'':>6} {fit.calib['rms_mm']:>9.4f} "
          f"{fit.valid['rms_mm']:>11.4f}")

    def show(s) -> None:
        show.i += 1
        print(f"{show.i:>4}  {s.effect:<14} {s.n_params:>6} {s.calib_rms_mm:>9.4f} "
              f"{s.heldout_rms_mm:>11.4f} {s.screen_s:>8.2f} {max(s.refit_s):>11.2f} "
              f"{s.seconds:>7.2f}", flush=True)

    show.i = 0
    res = auto_diagnose(fit, data, max_steps=max_steps, progress=show)
    final = res.steps[-1].heldout_rms_mm if res.steps else res.start_heldout_rms_mm
    _, it, ref_s = textbook_lm(res.fit.error_model, data.calib(), res.fit.free)
    print(f"total {res.total_s:.1f} s for {len(res.steps)} steps; held-out "
          f"{final / data.noise_floor_mm():.2f} x the noise floor; load average "
          f"{os.getloadavg()[0]:.1f}")
    print(f"reference: one textbook numpy LM fit of the final model ({it} iterations) "
          f"{ref_s:.2f} s; the loop takes {res.total_s / ref_s:.0f} x that")
    print(f"stopped: {res.stop_reason}")


def main() -> None:
    if "--quick" in sys.argv[1:]:  # that the script works: a tiny loop, one step
        auto_loop(60, max_steps=1)
        return
    if "auto" not in sys.argv[1:]:
        ranking()
    for n in (500, 2000):
        auto_loop(n)


if __name__ == "__main__":
    main()
