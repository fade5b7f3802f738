"""Blunders re-measured at the cell: what the re-measure policy catches, and what its running
model costs.

Table 1 (``captures``): ``cellcal capture poses`` (400 poses, 25 % validation, UR10e with
hidden geometric errors, ``--remeasure 2``) over loopback sockets against the simulated
cell with ``blunder=RATE`` (readings displaced 0.5-5 mm); the cell's ``blunder_log`` is
the truth. Per seed: readings taken, blunders injected, re-measured at once, revisited
after the warm-up, points left unresolved (out of the export), missed (blunders in the
exported readings), clean readings rejected, validation RMS of the export's
calibration over the noise floor, the running model's refits and their time.

Table 2 (``refit``): one warm-started refit of the running model (``identify``,
geometric,base,tool of the UR10e, the robust solver) by calibration rows, as thread CPU
time with BLAS on one thread (the machine is shared: wall time varies), the judgement
of one reading (prediction and its covariance) and the cost per point: the judgement
plus the refit amortised over its interval (every max(10, n/10) rows).

    python benchmarks/remeasure.py [--seeds 1,2,3] [--rate 0.05] [--sizes 50,100,200,400,800]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from calibration import Dataset, ErrorModel, identify, load_csv, load_model  # noqa: E402
from cellcal.cli import main  # noqa: E402
from daq.remeasure import RunningModel  # noqa: E402
from daq.routines import make_plan  # noqa: E402
from daq.store import RunStore, Sample  # noqa: E402
from sim_drivers.model_truth import ModelTruth, model_truth_factory  # noqa: E402
from sim_drivers.serve import ServeConfig, SimStack  # noqa: E402

PORTS = {"modbus": 0, "line_robot": 0, "tracker": 0, "emscon": 0}


def capture(seed: int, rate: float, count: int = 400) -> list:
    cfg = ServeConfig(seed=seed, faults=f"blunder={rate}", ports=dict(PORTS), pty=False)
    with tempfile.TemporaryDirectory() as d, SimStack(cfg, truth_factory=model_truth_factory
                                                      ) as stack:
        db, csv = Path(d) / "c.db", Path(d) / "c.csv"
        args = ["capture", "poses", "--count", str(count), "--seed", str(seed),
                "--valid-fraction", "0.25", "--model", "ur10e", "--tool-mm", "0,0,60",
                "--no-floor", "--tracker-at", "2500,0,500",  # where the simulator has it
                "--robot", stack.urls[1], "--tracker", stack.urls[2],
                "--db", str(db), "--measure-s", "0.01", "--json"]
        with contextlib.redirect_stdout(io.StringIO()) as out:
            assert main(args) == 0
            assert main(["export", "--db", str(db), "--out", str(csv)]) == 0
        rm = json.loads(out.getvalue().splitlines()[0])["summary"]["remeasure"]
        log, n_readings = list(stack.cell.blunder_log), stack.cell.n_measurements
        with RunStore(db) as st:
            rej = st.readings(1)
        model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
        data = load_csv(csv, model)
        fit = identify(ErrorModel(model, "geometric,base,tool"), data)
    rej_xyz = np.array([r.sample.tracker_p_smr for r in rej]).reshape(-1, 3)
    seen = np.array([b.true_xyz + b.offset_mm for b in log]).reshape(-1, 3)
    missed = sum(np.linalg.norm(data.tracker_p_smr - p, axis=1).min() < 0.2 for p in seen)
    caught = [i for i in range(len(rej)) if len(seen) and
              np.linalg.norm(seen - rej_xyz[i], axis=1).min() < 0.2]
    revisited = sum(rej[i].reason.startswith("warm-up") for i in caught)
    return [seed, n_readings, len(log), len(caught) - revisited, revisited,
            rm["unresolved"], int(missed), len(rej) - len(caught),
            fit.valid["rms_mm"] / data.noise_floor_mm(),
            rm["refits"], rm["largest_refit_rows"], rm["refit_s"]]


def refit_cost(sizes: list[int], repeats: int = 3) -> list[list]:
    from threadpoolctl import threadpool_limits

    model = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
    n_max = max(sizes)
    plan = make_plan("poses", model, count=n_max, seed=1)
    truth = ModelTruth.from_spec("ur10e", None, 1)
    Q = np.array([t.q for t in plan.targets])
    P = truth.error_model.evaluate(truth.x_true, truth.error_model.bind(
        Dataset(q=Q, tracker_p_smr=np.zeros((n_max, 3)))), False)[0]
    P += np.random.default_rng(0).normal(0, 0.017, P.shape)
    rows = []
    with threadpool_limits(1):
        for n in sizes:
            running = RunningModel(model, plan)
            for i in range(n):
                running.samples[i] = Sample(i, Q[i], P[i], np.full(3, 0.017), 10, float(i))
            running.refit()  # the cold first fit
            cpu, wall = [], []
            for _ in range(repeats):
                c0, w0 = time.thread_time(), time.perf_counter()
                running.refit()
                cpu.append(time.thread_time() - c0)
                wall.append(time.perf_counter() - w0)
            interval = max(running.refit_every, n // 10)
            probe = running.samples[n - 1]
            c0 = time.thread_time()
            for _ in range(20):
                running.judge(probe)
            judge = (time.thread_time() - c0) / 20
            rows.append([n, 1e3 * min(cpu), 1e3 * min(wall), interval,
                         1e3 * judge, 1e3 * (min(cpu) / interval + judge)])
    return rows


def table(rows, header, fmt):
    print(" | ".join(header))
    print(" | ".join("---" for _ in header))
    for r in rows:
        print(" | ".join(f.format(v) for f, v in zip(fmt, r, strict=True)))
    print()


def main_() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", default="1,2,3")
    p.add_argument("--rate", type=float, default=0.05)
    p.add_argument("--sizes", default="50,100,200,400,800")
    a = p.parse_args()
    rows = [capture(int(s), a.rate) for s in a.seeds.split(",")]
    table(rows, ["seed", "readings", "blunders", "re-measured", "revisited", "unresolved",
                 "missed", "clean rejected", "valid rms / floor", "refits", "largest refit",
                 "refit s"],
          ["{}", "{}", "{}", "{}", "{}", "{}", "{}", "{}", "{:.3f}", "{}", "{}", "{:.2f}"])
    table(refit_cost([int(s) for s in a.sizes.split(",")]),
          ["calib rows", "refit CPU ms", "refit wall ms", "refit every", "judge CPU ms",
           "CPU ms / point"],
          ["{}", "{:.0f}", "{:.0f}", "{}", "{:.2f}", "{:.1f}"])


if __name__ == "__main__":
    main_()
