"""Solvers on the same data: lm, ridge, besa, sa (and besa+lm), UR10e, default error model.

Three calibration sets of 300 poses from one hidden "true" robot (sigma 0.015 mm per
axis), each judged on the same clean validation set of 1000 poses over the whole
workspace:

(a) clean     poses uniform within the joint limits;
(b) outliers  the same poses, 5 % of them (15) moved by 1-3 mm in a random direction;
(c) ill-cond. poses within +-20 deg of one random posture on every joint (a tracker
              that sees only part of the workspace).

Prints one table: validation RMS and its ratio to the noise floor sqrt(3) sigma, the
calibration RMS, the wall time of identify() and the solver's iterations (annealing:
temperature levels and model evaluations). Ridge: the ridge parameter xi, the
condition class and the poses IGG3 rejected; every solver: whether the blunders it left out
(calibration.fit.outliers, the default) are the injected ones.

    python benchmarks/solvers.py [--seed N]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from calibration import Dataset, ErrorModel, identify, load_model
from calibration.fit.simulate import random_joints, realistic_truth, simulate

SIGMA = 0.015
N_CAL = 300
N_VAL = 1000
SOLVERS = ("lm", "ridge", "besa", "sa", "besa+lm")


def cases(seed: int) -> tuple[ErrorModel, Dataset, dict]:
    """(error model, validation set, {case: (calibration set, injected outlier ids)})."""
    m = load_model("ur10e")
    em = ErrorModel(m)
    rng = np.random.default_rng(seed)
    x_true = realistic_truth(em, rng)
    valid = simulate(em, x_true, random_joints(m, N_VAL, rng), SIGMA, rng)
    clean = simulate(em, x_true, random_joints(m, N_CAL, rng), SIGMA, rng)
    dirty = simulate(em, x_true, clean.q, SIGMA, rng)
    dirty.tracker_p_smr = clean.tracker_p_smr.copy()
    bad = np.sort(rng.choice(N_CAL, N_CAL // 20, replace=False))
    direction = rng.normal(size=(bad.size, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    dirty.tracker_p_smr[bad] += direction * rng.uniform(1.0, 3.0, (bad.size, 1))
    lim = m.limits_rad()
    centre = random_joints(m, 1, rng, max_abs_deg=150.0)
    q_small = np.clip(centre + rng.uniform(-1, 1, (N_CAL, m.n_joints)) * np.radians(20.0),
                      lim[:, 0], lim[:, 1])
    small = simulate(em, x_true, q_small, SIGMA, rng)
    return em, valid, {
        "(a) clean": (clean, []),
        "(b) 5% outliers 1-3 mm": (dirty, [dirty.pose_id[i] for i in bad]),
        "(c) ill-conditioned": (small, []),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2024)
    args = ap.parse_args()
    em, valid, sets = cases(args.seed)
    floor = valid.noise_floor_mm()
    print(f"model ur10e, effects {','.join(em.labels)}, {em.n_params} parameters; "
          f"{N_CAL} calibration poses, {N_VAL} clean validation poses over the workspace; "
          f"sigma {SIGMA} mm, noise floor {floor:.4f} mm; seed {args.seed}")
    header = (f"{'case':<24} {'solver':<8} {'valid RMS mm':>12} {'/floor':>7} "
              f"{'calib RMS mm':>12} {'time s':>7} {'iters':>6} {'evals':>6}  notes")
    print(header)
    print("-" * len(header))
    for case, (data, injected) in sets.items():
        for solver in SOLVERS:
            t = time.perf_counter()
            fit = identify(em, data, solver, valid=valid)
            dt = time.perf_counter() - t
            notes = [] if fit.converged else [f"NOT converged: {fit.reason}"]
            if solver == "ridge":
                rej = fit.info["rejected"]
                notes.append(f"xi {fit.info['xi']:.2g}, cond {fit.info['condition_number']:.2g}"
                             f" ({fit.info['condition_class']}), rejected {len(rej)}"
                             f", downweighted {len(fit.info['downweighted'])}")
            if injected and fit.outliers is not None:  # left out before any solver runs
                notes.append(f"blunders left out == injected: "
                             f"{sorted(fit.outliers.ids) == sorted(injected)}")
            if solver == "lm" and case.startswith("(c)"):
                notes.append(f"{fit.identifiability.n_identifiable} identifiable, "
                             f"cond {fit.identifiability.condition_number:.3g}")
            evals = fit.info.get("evaluations", "")
            print(f"{case:<24} {solver:<8} {fit.valid['rms_mm']:>12.4f} "
                  f"{fit.valid['rms_mm'] / floor:>7.2f} {fit.calib['rms_mm']:>12.4f} "
                  f"{dt:>7.2f} {fit.iterations:>6} {evals!s:>6}  {'; '.join(notes)}")


if __name__ == "__main__":
    main()
