"""The tracker's line of sight: what plans that see cost and gain, on the honest simulator.

For two tracker placements (beside and behind a UR10e with the SMR 60 mm out on the
flange axis, a 1.5" SMR, +-30 deg):

1. the share of uniformly drawn joint poses (within +-180 deg, above the floor) whose SMR
   faces the tracker within the acceptance, and the share that is visible (facing and the
   beam clear of every link);
2. a capture on the simulated cell (real drivers over loopback, zero motion time) of
   ``--count`` random poses planned as before (no line of sight, a random order) and
   planned for the line of sight (the tracker's place known roughly, 100 mm off) in the
   shortest order, and of as many D-optimal poses: planned, measured, beam breaks, points
   skipped, and the estimated capture time (0.5 rad/s, 0.5 s settling, 0.5 s measuring);
3. what identification accuracy costs: geometric, base and tool identified from 300
   simulated measurements (the truth's hidden errors, noise 0.5·(15 µm + 6 µm/m)) on poses
   drawn without the constraint, on visible random and on visible D-optimal poses; the
   validation RMS over 150 visible poses (what a tracker can check) and over 150 poses of
   the whole working space (what the robot is used in), in units of the noise floor.

    .venv/bin/python benchmarks/visibility.py [--count 200] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calibration import Dataset, ErrorModel, identify, load_model  # noqa: E402
from calibration.cell.cell import CellSpec  # noqa: E402
from calibration.cell.visibility import assess, sample_visible, workspace_ok  # noqa: E402
from daq.plans import Plan, Target, estimate_capture_s  # noqa: E402
from daq.routines import make_plan  # noqa: E402
from daq.run_context import ExecutorOptions, RunContext  # noqa: E402
from daq.service import execute  # noqa: E402
from daq.store import RunStore  # noqa: E402
from drivers.urls import open_robot, open_tracker  # noqa: E402
from sim_drivers.model_truth import ModelTruth  # noqa: E402
from sim_drivers.serve import ServeConfig, SimStack  # noqa: E402

PLACEMENTS = {"beside": (0.0, 2600.0, 400.0), "behind": (-2400.0, 300.0, 700.0)}
SPEED, SETTLE, MEASURE = 0.5, 0.5, 0.5
FAST = ExecutorOptions(measure_s=0.01, backoff_s=0.0005, backoff_max_s=0.001)


def model():
    return load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))


def shares(m, cell, rng, n=20000):
    lim = np.clip(m.limits_rad(), -np.pi, np.pi)
    q = rng.uniform(lim[:, 0], lim[:, 1], (n, 6))
    q = q[workspace_ok(m, q)]
    s = assess(m, q, cell, margins=False)
    return float(s.facing_ok.mean()), float(s.visible.mean())


def shuffled(plan, rng):
    """The plan's targets in a random order (the order plans had before)."""
    ts = [plan.targets[i] for i in rng.permutation(len(plan))]
    return Plan(plan.routine, plan.params, tuple(
        Target(k, t.move, q=t.q, set=t.set, label=t.label, info=t.info)
        for k, t in enumerate(ts)), plan.model)


def capture(plan, tracker_at, seed):
    cfg = ServeConfig(seed=seed, pty=False, ports={"modbus": 0, "line_robot": 0, "tracker": 0,
                                                   "emscon": 0})
    with SimStack(cfg, truth_factory=lambda s, h: ModelTruth.from_spec(
            "ur10e", None, s, tracker_at=tracker_at)) as stack, \
            tempfile.TemporaryDirectory() as d, RunStore(Path(d) / "v.db") as store:
        robot, tracker = open_robot(stack.urls[1]), open_tracker(stack.urls[2])
        robot.connect()
        tracker.connect()
        try:
            rid = store.create_run(plan, RunContext(routine=plan.routine, executor=FAST))
            execute(store, rid, plan, robot, tracker, model=model(),
                    context=store.run(rid).context)
        finally:
            robot.close()
            tracker.close()
        s = store.run(rid).summary
        regular = {t.index for t in plan.targets if not t.spare}
        measured = len(regular & store.done_indices(rid))
        return [plan.n_planned, measured, s["beam_breaks"], len(s["skipped_points"]),
                s["spares_measured"]]


def est_min(plan):
    return estimate_capture_s(plan, SPEED, MEASURE, settle_s=SETTLE) / 60.0


def accuracy(truth, cell, seed):
    m = truth.model
    em = ErrorModel(m, "geometric,base,tool")
    rng = np.random.default_rng(seed)
    sigma = 0.5 * (0.015 + 0.006 * 2.6)

    def measure(q, is_valid=None):
        data = Dataset(q=q, tracker_p_smr=np.zeros((len(q), 3)), is_valid=is_valid)
        P = truth.error_model.evaluate(truth.x_true, truth.error_model.bind(data), False)[0]
        data.tracker_p_smr = P + rng.normal(0, sigma, P.shape)
        return data

    lim = np.clip(m.limits_rad(), -np.pi, np.pi)

    def uniform(n):
        q = rng.uniform(lim[:, 0], lim[:, 1], (8 * n, 6))
        return q[workspace_ok(m, q)][:n]

    valid_vis, valid_all = sample_visible(m, cell, 150, rng), uniform(150)
    optimal = make_plan("poses", m, count=300, seed=seed, method="optimal", cell=cell)
    sets = {"uniform (no line of sight)": uniform(300),
            "visible, random": sample_visible(m, cell, 300, rng),
            "visible, D-optimal": np.array([t.q for t in optimal.targets if not t.spare])}
    floor = np.sqrt(3) * sigma
    rows = []
    for label, q in sets.items():
        fit = identify(em, measure(q))
        out = []
        for qv in (valid_vis, valid_all):
            data = measure(qv)
            P = em.evaluate(fit.values, em.bind(em.prepare(data)), False)[0]
            out.append(float(np.sqrt(np.mean(np.sum((P - data.tracker_p_smr) ** 2, 1)))))
        # the identified model against the truth, noise-free, over the whole workspace
        data = Dataset(q=valid_all, tracker_p_smr=np.zeros((len(valid_all), 3)))
        P_true = truth.error_model.evaluate(truth.x_true, truth.error_model.bind(data), False)[0]
        P = em.evaluate(fit.values, em.bind(em.prepare(data)), False)[0]
        model_err = float(np.sqrt(np.mean(np.sum((P - P_true) ** 2, 1))))
        rows.append([label, out[0] / floor, out[1] / floor, 1000 * model_err])
    return rows, floor


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    m = model()
    for name, at in PLACEMENTS.items():
        truth_cell = CellSpec().with_tracker(at, "truth")
        rough = CellSpec().with_tracker(np.add(at, (60.0, -70.0, 40.0)), "--tracker-at")
        face, vis = shares(m, truth_cell, np.random.default_rng(a.seed))
        print(f"\n== tracker {name} at {at} mm: of uniformly drawn poses {100 * face:.1f} % face "
              f"it within 30 deg, {100 * vis:.1f} % are visible (facing and the beam clear)")
        rng = np.random.default_rng(a.seed)
        before = shuffled(make_plan("poses", m, count=a.count, seed=a.seed), rng)
        after = make_plan("poses", m, count=a.count, seed=a.seed, cell=rough)
        after_rnd = shuffled(Plan(after.routine, after.params, tuple(
            t for t in after.targets if not t.spare), after.model), rng)
        opt = make_plan("poses", m, count=a.count, seed=a.seed, method="optimal", cell=rough)
        print(f"{'plan':42s} {'planned':>7s} {'measured':>8s} {'beam breaks':>11s} "
              f"{'skipped':>7s} {'spares':>6s} {'est. min':>8s}")
        for label, plan in (("before: random, no line of sight, random order", before),
                            ("after: random, visible, shortest order", after),
                            ("after: D-optimal, visible, shortest order", opt)):
            row = capture(plan, at, a.seed)
            print(f"{label:42s} {row[0]:7d} {row[1]:8d} {row[2]:11d} {row[3]:7d} {row[4]:6d} "
                  f"{est_min(plan):8.1f}")
        print(f"{'  the visible random poses in a random order':42s} {'':7s} {'':8s} {'':11s} "
              f"{'':7s} {'':6s} {est_min(after_rnd):8.1f}")
        truth = ModelTruth.from_spec("ur10e", None, a.seed, tracker_at=at)
        rows, floor = accuracy(truth, rough, a.seed)
        print(f"identification (geometric,base,tool; 300 poses), validation RMS / noise floor "
              f"({floor:.4f} mm):")
        print(f"  {'calibration poses':28s} {'on visible poses':>17s} {'whole workspace':>16s}"
              f" {'model error µm (whole workspace, noise-free)':>45s}")
        for label, v, w, e in rows:
            print(f"  {label:28s} {v:17.2f} {w:16.2f} {e:45.1f}")


if __name__ == "__main__":
    main()
