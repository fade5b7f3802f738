"""Time per point: emScon (Leica TPI, binary) vs the line protocol, against the simulator.

The simulated cell (``cellcal sim serve --model toy``, its own process, so server
and client do not share one interpreter lock) runs with time_scale 0: moves and
measurements take no wall time, and the figures are the protocols' and the
drivers' own cost over loopback:

- ``measure``: one ``tracker.measure()`` (emScon: one StartMeasurement, its
  answer and the result packet; line: ``MEAS`` and its reply), median and 95th
  percentile over ``--points`` calls;
- ``capture``: a whole ``poses`` capture through the capture service
  (:func:`daq.service.start_run`: line robot over TCP + the tracker, SQLite store),
  time per point of its execution: move, settle, joints, measure, and the sample with
  the tracker's metadata (std, covariance, air, reflector, face) committed;
- ``checks``: the tracker's checks before a run (:func:`daq.tracker_checks.check_tracker`:
  reflector, air, ready gate, two faces), once per run;
- ``connect``: opening the driver (emScon: units, coordinates, mode,
  reflectors, face, status; line: HELLO, STATUS?).

    python benchmarks/tracker_protocols.py [--points 500]
"""

from __future__ import annotations

import argparse
import os
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from daq.run_context import ExecutorOptions, TrackerSetup  # noqa: E402
from daq.service import CaptureRequest, plan_run, start_run  # noqa: E402
from daq.store import RunStore  # noqa: E402
from daq.tracker_checks import check_tracker  # noqa: E402
from drivers.urls import open_robot, open_tracker  # noqa: E402

TOY = ROOT / "tests" / "daq" / "data" / "toyarm.yaml"


def served_urls(proc, n: int, timeout: float = 30.0) -> list[str]:
    lines, buf, deadline = [], b"", time.monotonic() + timeout
    while len(lines) < n:
        assert time.monotonic() < deadline, f"cellcal sim serve printed only {lines}"
        if select.select([proc.stdout], [], [], 0.5)[0]:
            chunk = os.read(proc.stdout.fileno(), 4096)
            assert chunk, "cellcal sim serve exited"
            buf += chunk
            *done, buf = buf.split(b"\n")
            lines += [d.decode().strip() for d in done if d.strip()]
    return lines


def measure_times(url: str, n: int) -> tuple[float, np.ndarray]:
    trk = open_tracker(url)
    t0 = time.perf_counter()
    trk.connect(5.0)
    connect = time.perf_counter() - t0
    trk.measure(0.001, 5.0)  # first one sets the measuring time
    dt = np.empty(n)
    for k in range(n):
        t0 = time.perf_counter()
        trk.measure(0.001, 5.0)
        dt[k] = time.perf_counter() - t0
    trk.close()
    return connect, dt


def capture_time(planned, robot_url: str, tracker_url: str) -> tuple[float, float]:
    """(s per point of a capture's execution, s of the tracker's checks)."""
    robot, tracker = open_robot(robot_url), open_tracker(tracker_url)
    robot.connect(5.0)
    tracker.connect(5.0)
    options = planned.request.executor
    t0 = time.perf_counter()
    check_tracker(tracker, TrackerSetup(), options)
    checks = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as d, RunStore(Path(d) / "b.db", "NORMAL") as st:
        out = start_run(st, planned, robot_url=robot_url, tracker_url=tracker_url,
                        devices=(robot, tracker))
        assert out.status == "completed", out.reason
        s = st.samples(out.run_id)
        assert np.all(s.face > 0) and np.all(np.isfinite(s.pressure_hpa))  # the metadata
    robot.close()
    tracker.close()
    return out.elapsed_s / len(planned.plan), checks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=500)
    args = ap.parse_args()
    planned = plan_run(CaptureRequest(
        routine="poses", model=str(TOY), params={"count": args.points, "seed": 0},
        floor_z_mm=None, executor=ExecutorOptions(measure_s=0.001)))
    rows = []
    serve = subprocess.Popen(
        [sys.executable, "-m", "cellcal", "sim", "serve", "--model", "toy", "--no-pty",
         "--no-rtde"],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        urls = served_urls(serve, 4)
        robot_url = urls[1]
        for label, url in (("line protocol (tracker+tcp)", urls[2]),
                           ("emScon TPI (emscon://)", urls[3])):
            connect, dt = measure_times(url, args.points)
            per_point, checks = capture_time(planned, robot_url, url)
            rows.append((label, connect, np.median(dt), np.percentile(dt, 95), per_point,
                         checks))
    finally:
        serve.terminate()
        serve.wait(10)
        serve.stdout.close()
    head = (f"{'tracker protocol':30s} {'connect ms':>10s} {'measure ms (median)':>20s} "
            f"{'measure ms (p95)':>17s} {'capture ms/point':>17s} {'checks ms/run':>14s}")
    print(f"{args.points} points, simulated cell (own process) at time_scale 0, loopback TCP")
    print(head)
    print("-" * len(head))
    for label, connect, med, p95, per_point, checks in rows:
        print(f"{label:30s} {1e3 * connect:10.2f} {1e3 * med:20.3f} {1e3 * p95:17.3f} "
              f"{1e3 * per_point:17.2f} {1e3 * checks:14.2f}")


if __name__ == "__main__":
    main()
