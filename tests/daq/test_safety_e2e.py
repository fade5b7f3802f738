"""Safe motion at the cell, end to end over real sockets (issue 12).

Each scenario the issue reported, against the simulated cell that ``cellcal sim serve``
runs (a :class:`~sim_drivers.serve.SimStack`, here in the test's process so the test can
read the simulator's truth), driven by the ``cellcal`` command line: a second process on
a live run, a resume in another cell, a tracker that jumps or repeats itself (a TCP
proxy in front of the simulated tracker), a frame of the wrong orientation, a multi-turn
frame circle, a bridge to a controller that does not say it is a simulator, and stops by
signal in real time. Faults fire by state (samples stored, moves made), never by a count
of lines; nothing asserts on wall-clock time.
"""

from __future__ import annotations

import io
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from calibration.cell.cell import CellSpec, Smr
from calibration.model.transforms import make_T, rotvec_to_matrix
from cellcal.cli import main
from daq.plans import Plan
from daq.routines import make_plan
from daq.store import RunStore
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import ROOT, count_samples, served_cell, ur10e_controller_model
from .line_proxy import LineProxy
from .test_zero_e2e import TARGET, zero_truth

CLI = [sys.executable, "-m", "cellcal"]
#: the simulated cell's tracker stands at (2500, 0, 500) mm in the base frame
UR = ["--model", "ur10e", "--tool-mm", "0,0,60", "--tracker-at", "2500,0,500"]
#: plans made without line of sight (compared with make_plan's), on a cell whose 360-degree
#: reflector the tracker sees from anywhere (links still break the beam)
UR0 = ["--model", "ur10e", "--tool-mm", "0,0,60", "--no-visibility"]
SEE_ALL = CellSpec(smr=Smr(reflector="360"))




def _host_port(url: str) -> tuple[str, int]:
    host, port = url.split("://", 1)[1].split("?")[0].rsplit(":", 1)
    return host, int(port)


def _json(capsys) -> dict:
    return json.loads(capsys.readouterr().out)


def _off_plan(store: RunStore, run_id: int) -> float:
    """The largest joint difference (rad) of a stored sample from its planned posture."""
    plan = Plan.from_json(store.run(run_id).plan_json)
    s = store.samples(run_id)
    q = np.array([plan.targets[i].q for i in s.point_index])
    return float(np.abs(s.q - q).max())


# -------------------------------------------------- one owner per run and robot
@pytest.mark.slow
def test_a_live_run_and_a_busy_robot_have_one_owner(tmp_path):
    db = tmp_path / "live.db"
    hold = threading.Event()

    def held(line: str) -> list[str]:  # the tracker answers once the test lets it
        if line.startswith("OK MEAS") and count_samples(db) >= 3:
            hold.wait(120)
        return [line]

    with served_cell(model_truth_factory, seed=5) as stack, \
            LineProxy(_host_port(stack.urls[2]), held) as proxy:
        robot = stack.urls[1]
        capture = [*CLI, "capture", "poses", "--count", "12", "--seed", "2", *UR, "--no-floor",
                   "--robot", robot, "--tracker", proxy.url("tracker+tcp"), "--db", str(db),
                   "--json", "--measure-s", "0.05"]
        first = subprocess.Popen(capture, cwd=ROOT, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE)
        deadline = time.monotonic() + 60
        while count_samples(db) < 3:
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.01)
        try:
            resume = subprocess.run([*CLI, "resume", "--db", str(db), "--json"], cwd=ROOT,
                                    capture_output=True, timeout=60)
            again = subprocess.run(capture, cwd=ROOT, capture_output=True, timeout=60)
            still_running = first.poll() is None
        finally:
            hold.set()
        out, err = first.communicate(timeout=120)
    assert still_running
    assert resume.returncode == 2, resume.stderr.decode()
    assert f"run 1 is in use by pid {first.pid}" in resume.stderr.decode()
    assert again.returncode == 2, again.stderr.decode()
    assert f"robot {robot} is in use by pid {first.pid}" in again.stderr.decode()
    assert first.returncode == 0, err.decode()
    assert json.loads(out)["status"] == "completed"
    with RunStore(db) as st:
        assert [r.id for r in st.runs()] == [1]  # the second capture stored nothing
        kinds = [k for _, _, k, _ in st.interruptions(1)]
        assert _off_plan(st, 1) < 0.002  # every sample where its posture was planned
    assert "killed" not in kinds


# ----------------------------------------------------------- the same cell
def test_a_resume_in_another_cell_is_refused_or_starts_a_new_run(tmp_path, capsys):
    db = str(tmp_path / "cell.db")
    with served_cell(model_truth_factory, seed=5) as a, \
            served_cell(model_truth_factory, seed=6) as b:
        a_robot = a.urls[1]
        a.faults.arm("pstop")  # the first move: a protective stop pauses the run
        assert main(["capture", "poses", "--count", "6", "--seed", "1", *UR, "--no-floor",
                     "--robot", a.urls[1], "--tracker", a.urls[2], "--db", db, "--json",
                     "--measure-s", "0.05"]) == 1
        assert _json(capsys)["status"] == "paused"
        a.cell.clear_protective_stop()
        rc = main(["resume", "--db", db, "--robot", b.urls[1], "--tracker", b.urls[2],
                   "--json"])
        err = capsys.readouterr().err
        assert rc == 2 and "run 1 was measured in another cell" in err and "--other-cell" in err
        assert b.cell.n_moves == 0
        with RunStore(db) as st:
            r = st.run(1)
            assert (r.robot_url, r.tracker_url) == (a.urls[1], a.urls[2])  # not overwritten
            assert st.n_samples(1) == 0
        rc = main(["resume", "--db", db, "--robot", b.urls[1], "--tracker", b.urls[2],
                   "--other-cell", "--json"])
        new = _json(capsys)
        assert rc == 0 and new["run"] == 2 and new["samples"] == 6
        assert main(["resume", "1", "--db", db, "--json"]) == 0  # in its own cell
        old = _json(capsys)
    assert old["run"] == 1 and old["samples"] == 6 and old["status"] == "completed"
    with RunStore(db) as st:
        r1, r2 = st.run(1), st.run(2)
        assert r2.source_run == 1 and r1.source_run is None
        assert r1.robot_identity["serial"] == "SIM-ur10e-5"
        assert r2.robot_identity["serial"] == "SIM-ur10e-6"
        assert r1.plan_hash == r2.plan_hash and r1.robot_url == a_robot
        assert _off_plan(st, 1) < 0.002 and _off_plan(st, 2) < 0.002


# ---------------------------------------------------- the zero-point loop
def _jump_proxy(stack, db, dz_mm: float):
    """A tracker proxy whose readings jump by ``dz_mm`` once the robot stands at the third
    zero posture and has made one correction there (a bumped tracker mid-loop)."""
    state = {"moves": None}

    def transform(line: str) -> list[str]:
        if not line.startswith("OK MEAS"):
            return [line]
        if state["moves"] is None:
            if count_samples(db) >= 2:  # the first measurement at the third posture
                state["moves"] = stack.cell.n_moves
            return [line]
        if stack.cell.n_moves > state["moves"]:  # a correction has moved the robot
            z = float(re.search(r" z=(\S+)", line).group(1))
            return [re.sub(r" z=\S+", f" z={z + dz_mm:.5f}", line)]
        return [line]

    return LineProxy(_host_port(stack.urls[2]), transform)


def test_a_tracker_that_jumps_mid_loop_pauses_the_zero_run(tmp_path, capsys):
    db = tmp_path / "zero.db"
    with served_cell(zero_truth, seed=3, cell=SEE_ALL) as stack, \
            _jump_proxy(stack, db, 900.0) as proxy:
        plan = make_plan("zero20", ur10e_controller_model(),
                         target_xyz=[float(v) for v in TARGET.split(",")])
        rc = main(["capture", "zero20", *UR0, "--floor-z-mm", "-150", "--robot", stack.urls[1],
                   "--tracker", proxy.url("tracker+tcp"), "--db", str(db), "--json",
                   "--target-xyz", TARGET])
        out = _json(capsys)
        state = stack.cell.robot_state()
    assert rc == 1 and out["status"] == "paused" and out["samples"] == 2
    assert "zero_diverged at point 2" in out["reason"] and "jumped" in out["reason"]
    # the robot stayed by the third posture: one bounded correction, above the floor
    assert np.abs(state.q - plan.targets[2].q).max() < 0.06
    assert np.linalg.norm(state.tcp - plan.targets[2].base_p_tcp) < 6.0
    assert state.tcp[2] > 0.0


def test_a_frame_of_the_wrong_orientation_pauses_the_zero_run(tmp_path, capsys):
    db = str(tmp_path / "zero.db")
    with served_cell(zero_truth, seed=4, cell=SEE_ALL) as stack:
        truth_T = stack.cell.truth.tracker_T_base
        # a frame run measured in this cell, whose frame is turned 120 deg about z
        assert main(["capture", "frame", *UR0, "--start-deg", "20,-100,100,-90,-90,0",
                     "--circle-points", "4", "--line-points", "3", "--robot", stack.urls[1],
                     "--tracker", stack.urls[2], "--db", db, "--json"]) == 0
        capsys.readouterr()
        with RunStore(db) as st:
            wrong = truth_T @ make_T(rotvec_to_matrix([0.0, 0.0, np.radians(120.0)]),
                                     np.zeros(3))
            st.update_run(1, frame={**st.run(1).frame, "tracker_T_base": wrong.tolist()})
        plan = make_plan("zero20", ur10e_controller_model(),
                         target_xyz=[float(v) for v in TARGET.split(",")])
        rc = main(["capture", "zero20", *UR0, "--floor-z-mm", "-150", "--robot", stack.urls[1],
                   "--tracker", stack.urls[2], "--db", db, "--json", "--target-xyz", TARGET])
        out = _json(capsys)
        q = stack.cell.robot_state().q
    assert rc == 1 and out["status"] == "paused" and out["samples"] == 1
    assert "zero_diverged at point 1" in out["reason"]
    assert "measurement frame is not this cell's" in out["reason"]
    assert np.abs(q - plan.targets[1].q).max() < 0.06  # joint 4 nowhere near -344 deg


# ------------------------------------------------------ repeated replies
def test_a_tracker_repeating_its_reply_is_not_stored_twice(tmp_path, capsys):
    db = tmp_path / "rep.db"
    state = {"last": None, "done": False}

    def transform(line: str) -> list[str]:
        if not line.startswith("OK MEAS"):
            return [line]
        if not state["done"] and state["last"] is not None and count_samples(db) >= 3:
            state["done"] = True
            return [state["last"]]  # the previous point's reply, word for word
        state["last"] = line
        return [line]

    with served_cell(model_truth_factory, seed=2) as stack, \
            LineProxy(_host_port(stack.urls[2]), transform) as proxy:
        rc = main(["capture", "poses", "--count", "6", "--seed", "3", *UR, "--no-floor",
                   "--robot", stack.urls[1], "--tracker", proxy.url("tracker+tcp"),
                   "--db", str(db), "--json", "--measure-s", "0.05"])
        out = _json(capsys)
    assert rc == 0 and out["samples"] == 6 and state["done"]
    with RunStore(db) as st:
        s = st.samples(1)
        faults = [(k, m) for _, _, k, m in st.interruptions(1) if k not in ("resume",)]
    assert np.all(np.diff(s.t_s) > 0) and len({tuple(p) for p in s.tracker_p_smr}) == 6
    assert len(faults) == 1 and faults[0][0] == "protocol" and "stale measurement" in faults[0][1]


# ------------------------------------------------------------ multi-turn
def test_a_720_deg_frame_circle_completes(tmp_path, capsys):
    db = str(tmp_path / "frame.db")
    with served_cell(model_truth_factory, seed=4, cell=SEE_ALL) as stack:
        rc = main(["capture", "frame", *UR0, "--start-deg", "0,-100,100,-90,-90,0",
                   "--circle-span-deg", "720", "--circle-points", "17", "--line-points", "5",
                   "--robot", stack.urls[1], "--tracker", stack.urls[2], "--db", db,
                   "--json"])
        out = _json(capsys)
    assert rc == 0 and out["status"] == "completed" and out["samples"] == 22
    with RunStore(db) as st:
        s = st.samples(1)
        assert st.interruptions(1) == []  # the controller refused nothing
        assert _off_plan(st, 1) < 0.06
    j1 = np.degrees(s.q[:17, 0])
    assert j1.min() == pytest.approx(-360.0, abs=0.01) and j1.max() == pytest.approx(360, abs=0.01)
    assert abs(np.degrees(s.q[17, 0])) < 10.0  # back for the line
    # turned from 20 deg, the same circle leaves the joint range: refused before motion
    rc = main(["capture", "frame", *UR0, "--start-deg", "20,-100,100,-90,-90,0",
               "--circle-span-deg", "720", "--robot", "socket://127.0.0.1:9", "--tracker",
               "tracker+tcp://127.0.0.1:9", "--db", db, "--dry-run"])
    assert rc == 2 and "beyond its max limit 360 deg" in capsys.readouterr().err


# --------------------------------------------------- only simulators go unasked
def test_a_bridge_to_an_unidentified_controller_asks_first(tmp_path, capsys, monkeypatch):
    db = str(tmp_path / "bridge.db")

    def real(line: str) -> list[str]:  # what a real controller says: no sim=1
        return [re.sub(r" sim=1 kinematics=\S+", "", line) if line.startswith("OK HELLO")
                else line]

    with served_cell(model_truth_factory, seed=8) as stack, \
            LineProxy(_host_port(stack.urls[1]), real) as bridge:
        def args(robot: str) -> list[str]:
            return ["capture", "poses", "--count", "3", *UR, "--no-floor", "--robot", robot,
                    "--tracker", stack.urls[2], "--db", db, "--json", "--measure-s", "0.05"]

        monkeypatch.setattr("sys.stdin", io.StringIO(""))
        assert main(args(bridge.url("socket"))) == 2
        err = capsys.readouterr().err
        assert "did not identify as a simulator" in err and "--yes" in err
        assert stack.cell.n_moves == 0
        with RunStore(db) as st:
            assert st.runs() == []
        assert main([*args(bridge.url("socket")), "--yes"]) == 0
        assert _json(capsys)["samples"] == 3
        # the simulator itself (it says so) goes unasked
        assert main(args(stack.urls[1])) == 0


# ------------------------------------------------------- stops that stop
@pytest.mark.slow
@pytest.mark.parametrize("signals, code, name", [
    ((signal.SIGINT, signal.SIGINT), 130, "a second Ctrl-C"),
    ((signal.SIGTERM,), 143, "SIGTERM"),
    ((signal.SIGHUP,), 129, "SIGHUP"),
])
def test_a_signal_stops_the_joint_in_real_time(tmp_path, signals, code, name):
    db = tmp_path / "sig.db"
    with served_cell(model_truth_factory, seed=4, time_scale=1.0) as stack:
        cell = stack.cell
        p = subprocess.Popen([*CLI, "capture", "poses", "--count", "3", "--seed", "1", *UR,
                              "--no-floor", "--speed", "0.1", "--robot", stack.urls[1],
                              "--tracker", stack.urls[2], "--db", str(db), "--json"],
                             cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        deadline = time.monotonic() + 60
        while not cell.robot_state().moving:
            assert p.poll() is None and time.monotonic() < deadline
            time.sleep(0.01)
        sent_to = cell._q_to.copy()
        for s in signals:
            os.kill(p.pid, s)
            time.sleep(0.2)
        out, err = p.communicate(timeout=60)
        s1 = cell.robot_state()
        time.sleep(0.5)
        s2 = cell.robot_state()
    assert p.returncode == code, err.decode()
    assert not s1.moving and np.array_equal(s1.q, s2.q)  # stopped, and it stays
    assert np.abs(s1.q - sent_to).max() > 0.05  # short of where it was sent
    doc = json.loads(out)
    assert doc["status"] == "paused" and doc["signal"] == signal.Signals(signals[-1]).name
    with RunStore(db) as st:
        r = st.run(1)
    assert r.status == "paused" and f"stopped at once by {name}" in r.reason
    assert "the controller's stop was sent" in r.reason
