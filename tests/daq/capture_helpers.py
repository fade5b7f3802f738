"""Helpers for the capture tests: a served simulated cell, drivers, a run in a store."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from calibration import ErrorModel, load_model
from calibration.cell.cell import CellSpec
from daq.run_context import ExecutorOptions, RunContext
from daq.service import execute
from daq.store import RunStore
from drivers.ur_rtde import UrRtdeRobot
from drivers.urls import open_robot, open_tracker
from sim_drivers.fake_rtde_control import FakeRTDEControl
from sim_drivers.model_truth import DEFAULT_TRACKER_AT_MM, ModelTruth
from sim_drivers.rtde_server import RtdeSimServer
from sim_drivers.serve import ServeConfig, SimStack
from tests.sim_drivers.rtde_helpers import loopback_host

DATA = Path(__file__).parent / "data"
TOY = str(DATA / "toyarm.yaml")
ROOT = Path(__file__).resolve().parents[2]
FREE_PORTS = {"modbus": 0, "line_robot": 0, "tracker": 0, "emscon": 0}


def toy_sim(kind: str, seed: int, name: str = "default", **extra) -> str:
    """An in-process ``sim://`` URL of the toy arm (tests/daq/data/toyarm.yaml; the SMR at
    the wrist: no tool) for cell ``name``. The 3-joint toy cannot turn its SMR towards the
    tracker, so it carries a 360-degree reflector (the beam still breaks on occlusions)."""
    from urllib.parse import urlencode

    query = {"model": TOY, "tool": "0,0,0", "seed": seed, "name": name, "reflector": "360",
             **extra}
    return f"sim://{kind}?{urlencode(query)}"


def ur10e_controller_model():
    """The nominal UR10e as the simulated controller knows it (SMR on a 60 mm holder)."""
    return load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))


def base_only_truth(seed: int, hidden=None, tracker_at=DEFAULT_TRACKER_AT_MM) -> ModelTruth:
    """A UR10e whose only hidden error is its pose in the tracker frame (and the tool), the
    tracker at ``tracker_at`` (mm, base frame)."""
    nominal = ur10e_controller_model()
    em = ErrorModel(nominal, "base,tool")
    rng = np.random.default_rng(seed)
    from calibration.fit.simulate import realistic_truth

    x = realistic_truth(em, rng)
    x[em.index("tool.x"):em.index("tool.x") + 3] = nominal.tool_mm()
    return ModelTruth(nominal, em, x, tracker_at=tracker_at)


def rough_cell(tracker_at=DEFAULT_TRACKER_AT_MM, error_mm=(60.0, -40.0, 30.0)) -> CellSpec:
    """The cell as a user describes it: the tracker ``error_mm`` off its true place."""
    return CellSpec().with_tracker(np.add(tracker_at, error_mm), "--tracker-at")


@contextlib.contextmanager
def served_cell(truth_factory, *, faults=None, seed=0, time_scale=0.0, cell=None, abb=False,
                **cell_kw):
    """A SimStack on free loopback ports (no pty): yields the stack (what ``cellcal sim
    serve`` runs, in this process so a test can read the simulator's truth). ``cell``: the
    cell (fixtures, SMR); ``abb``: the robot served as an ABB IRC5 too (its URL the last);
    ``cell_kw``: extra :class:`~sim_drivers.cell.SimCell` arguments (weather station,
    collimation...)."""
    cfg = ServeConfig(seed=seed, faults=faults, ports=dict(FREE_PORTS), pty=False,
                      time_scale=time_scale, abb=abb)
    with SimStack(cfg, truth_factory=truth_factory, cell=cell, **cell_kw) as stack:
        yield stack


@contextlib.contextmanager
def connected(robot_url: str, tracker_url: str):
    robot = open_robot(robot_url)
    try:
        robot.connect(2.0)
        with connected_tracker(tracker_url) as tracker:
            yield robot, tracker
    finally:
        robot.close()


@contextlib.contextmanager
def connected_tracker(tracker_url: str):
    """The tracker at ``tracker_url``, connected; closed on exit."""
    tracker = open_tracker(tracker_url)
    try:
        tracker.connect(2.0)
        yield tracker
    finally:
        tracker.close()


@contextlib.contextmanager
def stack_robot(stack, protocol: str):
    """A connected robot driver of ``stack``'s cell over ``protocol``: "modbus" or "line"
    (the stack's servers), or "rtde": the cell served over RTDE too (a fresh loopback
    address on port 30004), read by the real ur-rtde receive client and moved through
    :class:`~sim_drivers.fake_rtde_control.FakeRTDEControl` on the same cell (the
    simulator has no UR script server)."""
    cell, server = stack.cell, None
    if protocol == "rtde":
        server = RtdeSimServer(cell, host=loopback_host()).start()
        robot = UrRtdeRobot.from_url(
            server.url, control_factory=lambda h: FakeRTDEControl(cell, h, server=server))
    else:
        scheme = {"modbus": "modbus", "line": "socket"}[protocol]
        robot = open_robot(next(u for u in stack.urls if u.startswith(scheme)))
    try:
        robot.connect(5.0)
        yield robot
    finally:
        robot.close()
        if server is not None:
            server.stop()


def run_plan(store: RunStore, plan, robot, tracker, model=None, options=None, run_id=None,
             urls=("", "")) -> tuple[int, str]:
    """Create (or continue) a run and execute it (:func:`daq.service.execute`) with the
    executor ``options``; returns (run id, status)."""
    options = options or ExecutorOptions()
    if run_id is None:
        run_id = store.create_run(plan, RunContext(routine=plan.routine, robot_url=urls[0],
                                                   tracker_url=urls[1], executor=options))
    context = store.run(run_id).context.model_copy(update={"executor": options})
    return run_id, execute(store, run_id, plan, robot, tracker, model=model,
                           context=context).status


def read_lines(proc, n, timeout):
    """The first ``n`` non-empty lines ``proc`` prints on stdout (within ``timeout`` s)."""
    lines, buf = [], b""
    deadline = time.monotonic() + timeout
    fd = proc.stdout.fileno()
    while len(lines) < n:
        left = deadline - time.monotonic()
        assert left > 0, f"only got {lines}"
        if select.select([fd], [], [], left)[0]:
            chunk = os.read(fd, 4096)
            assert chunk, "cellcal sim serve exited early: " + (
                proc.stderr.read().decode() if proc.stderr else "(stderr not captured)")
            buf += chunk
            *done, buf = buf.split(b"\n")
            lines += [d.decode().strip() for d in done if d.strip()]
    return lines


def count_samples(address) -> int:
    """Samples stored in the run store at ``address`` (a file or a PostgreSQL URL), read
    on a connection of its own; 0 while there is no store yet or the server is away."""
    from daq.store.dialect import StoreError, connect

    try:
        db = connect(address, read_only=True, timeout_s=2.0)
    except StoreError:
        return 0
    try:
        return int(db.execute("SELECT count(*) FROM samples").fetchone()[0])
    except (StoreError, sqlite3.OperationalError):
        return 0
    finally:
        db.close()


@contextlib.contextmanager
def sim_serve(*args: str):
    """``cellcal sim serve ARGS`` as a subprocess (stdout piped; on free ports unless ARGS
    give ports); SIGTERM on exit."""
    if not any(a.startswith("--") and a.endswith(("-port", "-port-base", "--any-port"))
               for a in args):
        args = (*args, "--port-base", "0")
    serve = subprocess.Popen([sys.executable, "-m", "cellcal", "sim", "serve", *args], cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        yield serve
    finally:
        serve.send_signal(signal.SIGTERM)
        try:
            serve.wait(timeout=10)
        except subprocess.TimeoutExpired:
            serve.kill()
            serve.wait()
        serve.stdout.close()

