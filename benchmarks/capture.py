"""Software overhead of the capture executor per point, against the simulator at zero motion time.

Two set-ups, each a ``poses`` plan on the toy arm with time_scale 0 (moves and
measurements take no wall time): the in-process ``sim://`` drivers (the toy arm's
calibration-backed truth; executor + SQLite only) and the real drivers over loopback
sockets to ``SimStack`` (ToyArm truth; line robot + TCP tracker). The plan is made for the
simulated tracker's line of sight (the SMR 60 mm off the flange, the tracker where the
simulated cell puts it), so every point is measured: the run must end ``completed``.
Every point includes the executor's read-back of the joints after the move and after the
measurement.
Prints points, total seconds, ms per point and the SQLite commit's share (WAL,
synchronous=FULL).

    .venv/bin/python benchmarks/capture.py [--points 1000]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import sim_drivers.inprocess as inproc  # noqa: E402
from calibration import load_model  # noqa: E402
from calibration.cell.cell import CellSpec  # noqa: E402
from daq.executor import Executor  # noqa: E402
from daq.routines import make_plan  # noqa: E402
from daq.run_context import ExecutorOptions  # noqa: E402
from daq.store import RunStore  # noqa: E402
from drivers.urls import open_robot, open_tracker  # noqa: E402
from sim_drivers.model_truth import DEFAULT_TOOL_MM, DEFAULT_TRACKER_AT_MM  # noqa: E402
from sim_drivers.serve import ServeConfig, SimStack  # noqa: E402

TOY = ROOT / "tests" / "daq" / "data" / "toyarm.yaml"


def bench(label, plan, robot_url, tracker_url, synchronous="FULL"):
    robot, tracker = open_robot(robot_url), open_tracker(tracker_url)
    robot.connect()
    tracker.connect()
    with tempfile.TemporaryDirectory() as d, RunStore(Path(d) / "b.db", synchronous) as st:
        rid = st.create_run(plan)
        ex = Executor(st, rid, plan, robot, tracker, ExecutorOptions(measure_s=0.001))
        t0 = time.perf_counter()
        status = ex.run()
        total = time.perf_counter() - t0
        assert status == "completed" and st.n_samples(rid) == plan.n_planned, status
    robot.close()
    tracker.close()
    n = plan.n_planned
    return [label, synchronous, n, total, 1000 * total / n, 1000 * ex.commit_s / n]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=1000)
    args = ap.parse_args()
    cell = CellSpec().with_tracker(DEFAULT_TRACKER_AT_MM, "the simulated cell")
    plan = make_plan("poses", load_model(TOY).with_changes(tool=DEFAULT_TOOL_MM),
                     count=args.points, seed=0, cell=cell)
    inproc.register()  # sim:// (the application registers it when it starts)
    rows = []
    for sync in ("FULL", "NORMAL"):
        inproc.reset_cells()
        tool = ",".join(f"{v:g}" for v in DEFAULT_TOOL_MM)
        rows.append(bench("in-process sim://", plan,
                          f"sim://robot?model={TOY}&tool={tool}&name=bench",
                          "sim://tracker?name=bench", sync))
    cfg = ServeConfig(ports={"modbus": 0, "line_robot": 0, "tracker": 0}, pty=False)
    with SimStack(cfg) as stack:
        rows.append(bench("sockets (line robot + TCP tracker)", plan, stack.urls[1],
                          stack.urls[2]))
    with SimStack(cfg) as stack:
        rows.append(bench("sockets (Modbus robot + TCP tracker)", plan, stack.urls[0],
                          stack.urls[2]))
    head = f"{'drivers':38s} {'sync':6s} {'points':>6s} {'total s':>8s} {'ms/point':>9s} " \
           f"{'of which commit ms':>19s}"
    print(head)
    print("-" * len(head))
    for label, sync, n, total, ms, commit in rows:
        print(f"{label:38s} {sync:6s} {n:6d} {total:8.2f} {ms:9.2f} {commit:19.2f}")


if __name__ == "__main__":
    main()
