"""Safe motion, unit by unit: the motion guard, leases, the schema-4 upgrade, read-back,
stale measurements, stops on signals (in process), options checked before a run exists."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import threading
import time

import numpy as np
import pytest

import sim_drivers.inprocess as inproc
from calibration import load_model
from cellcal.cli import main
from daq.check import check_plan
from daq.executor import Executor, StaleMeasurement
from daq.motion_guard import MotionGuard, MotionLimits
from daq.plans import Plan, Target
from daq.remeasure import Judgement, Remeasure
from daq.routines import make_plan
from daq.run_context import ExecutorOptions, RunContext
from daq.store import RunStore
from daq.store.leases import Leases, robot_key, run_key
from daq.store.schema import SCHEMA_V1, SCHEMA_VERSION, UPGRADES
from drivers.urls import open_robot, open_tracker

from .capture_helpers import TOY, run_plan, toy_sim

TOYM = load_model(TOY)
UR = load_model("ur10e").with_changes(tool=(0.0, 0.0, 60.0))
START = np.radians([20.0, -100.0, 100.0, -90.0, -90.0, 0.0])


@pytest.fixture(autouse=True)
def fresh_cells():
    inproc.reset_cells()
    yield
    inproc.reset_cells()


# ----------------------------------------------------------- motion guard
def test_guard_refuses_limits_floor_keepout_reach_and_deviation():
    g = MotionGuard(UR, MotionLimits(floor_z_mm=0.0, max_reach_mm=1500.0,
                                     keepout_mm=((-2000, -2000, -100, 2000, -500, 3000),)))
    assert g.check_joint_move(START, START) == []
    over = START.copy()
    over[3] = np.radians(-344.5 - 30)
    assert "joint 4 = -374.500 deg beyond its min limit -360 deg" in g.check_joint_move(
        START, over)[0]
    down = START.copy()
    down[1] = np.radians(-10.0)  # the upper arm points down: wrist and tool below the floor
    assert any("below the floor 0 mm" in m for m in g.check_joint_move(START, down))
    side = START.copy()
    side[0] = np.radians(100.0)
    assert any("keep-out box 1" in m for m in g.check_joint_move(START, side))
    # an adaptive move may not wander from the planned posture
    nudged = START + np.radians([0.0, 0.0, 0.0, 5.0, 0.0, 0.0])
    probs = g.check_joint_move(START, nudged, planned=START, adaptive=True)
    assert any("joint 4 5.000 deg from the planned posture" in m for m in probs)
    assert g.check_joint_move(START, nudged, planned=START, adaptive=False) == []
    # a linear move cannot land a full turn away from where joint 1 stands
    turned = START.copy()
    turned[0] += 2 * np.pi
    tip = g.tool_points(START[None])[0]
    assert any("turns it the short way" in m for m in g.check_linear_move(turned, tip,
                                                                            planned=START))
    assert g.check_linear_move(START, tip + [10.0, 0, 0], planned=START) == []
    assert any("below the floor" in m for m in g.check_linear_move(START, tip - [0, 0, 2000.0]))
    # read back: the robot must be where it was sent
    assert g.check_arrival(START + 1e-4, q_cmd=START) == []
    assert "joint 2 reads" in g.check_arrival(START + [0, 0.01, 0, 0, 0, 0], q_cmd=START)[0]


def test_dry_run_checks_keepout_and_multi_turn_linear_moves():
    q0 = START.copy()
    q1 = START.copy()
    q1[0] += 2 * np.pi  # the same place, a turn further
    p = make_plan("frame", UR, start_deg=np.degrees(START), circle_points=3)
    tip = MotionGuard(UR).tool_points(q0[None])[0]
    plan = Plan("t", {}, (Target(0, "joints", q=q1), Target(1, "linear", q=q0,
                                                               base_p_tcp=tip + [5, 0, 0])))
    res = check_plan(plan, UR, floor_z_mm=None)
    assert not res.ok and "would turn joint 1 by 360.0 deg" in res.report()
    box = ((-5000, -5000, -5000, 5000, 5000, 5000),)
    res = check_plan(p, UR, limits=MotionLimits(keepout_mm=box))
    assert res.bad_indices == list(range(len(p))) and "keep-out box 1" in res.report()
    with pytest.raises(ValueError, match="keep-out box"):
        MotionLimits(keepout_mm=((0, 0, 0, -1, 1, 1),))


def test_a_multi_turn_frame_circle_comes_back_by_a_joint_move():
    p = make_plan("frame", UR, start_deg=[0, -100, 100, -90, -90, 0], circle_span_deg=720,
                  circle_points=9)
    assert check_plan(p, UR).ok
    line1 = next(t for t in p.targets if t.label == "line1")
    assert line1.move == "joints" and line1.via is not None
    assert np.degrees(p.targets[8].q[0]) == pytest.approx(360.0)
    assert abs(np.degrees(line1.q[0])) < 10.0
    p = make_plan("frame", UR, start_deg=[20, -100, 100, -90, -90, 0], circle_span_deg=720)
    assert "beyond its max limit 360 deg" in check_plan(p, UR).report()


# ----------------------------------------------------------------- leases
# one owner, stale owners taken over, racing takers: tests/daq/test_leases_backends.py (on
# a SQLite file and on PostgreSQL)


def test_robot_keys_normalise_the_address():
    assert robot_key("socket://LOCALHOST:15021") == robot_key("socket://127.0.0.1:15021")
    assert robot_key("modbus+tcp://10.0.0.2") == robot_key("modbus+tcp://10.0.0.2:502?unit=1")
    assert robot_key("sim://robot?seed=1&model=ur10e&time_scale=2") == robot_key(
        "sim://robot?model=ur10e&seed=1")
    assert robot_key("sim://robot?seed=1&model=ur10e") != robot_key("sim://robot?seed=2&model=ur10e")


# ---------------------------------------------------------- schema 3 -> 4
def test_upgrade_from_a_schema_3_store(tmp_path):
    path = tmp_path / "v3.db"
    con = sqlite3.connect(path, isolation_level=None)
    con.executescript(SCHEMA_V1)
    UPGRADES[1](con)
    UPGRADES[2](con)
    ctx = RunContext(routine="poses", model="toyarm", robot_url="socket://127.0.0.1:1")
    con.execute("INSERT INTO runs (routine, plan_json, plan_hash, n_points, status, model, "
                "context_json) VALUES ('poses', '{}', 'abc', 2, 'paused', 'toyarm', ?)",
                (ctx.model_dump_json(exclude={"motion"}),))
    con.execute("PRAGMA user_version=3")
    con.close()
    with RunStore(path) as st:
        assert st.version == SCHEMA_VERSION
        r = st.run(1)
        assert r.robot_identity is None and r.tracker_identity is None and r.source_run is None
        # the limits it ran under: no floor (none was recorded), the rest the defaults
        assert r.context.motion == MotionLimits(floor_z_mm=None)
        st.update_run(1, robot_identity={"kind": "robot", "serial": "S"})
        assert st.run(1).robot_identity["serial"] == "S"
    with Leases(path) as ls:
        assert ls.acquire(run_key(1), "run 1") is None


# ------------------------------------------------- executor: read-back etc.
class _Repeating:
    """A tracker that hands back its previous measurement once ``repeat`` is set."""

    def __init__(self, tracker):
        self.t, self.url, self.repeat, self.last = tracker, tracker.url, False, None
        self.fired = False

    def connect(self, timeout=5.0):
        self.t.connect(timeout)

    def close(self):
        self.t.close()

    def measure(self, duration_s=0.5, timeout=10.0):
        if self.repeat and not self.fired and self.last is not None:
            self.fired = True
            return self.last
        self.last = self.t.measure(duration_s, timeout)
        return self.last


class _Meddling:
    """A tracker whose measurement lets another process nudge the robot (joint 2)."""

    def __init__(self, tracker, cell):
        self.t, self.cell, self.url, self.armed = tracker, cell, tracker.url, False

    def connect(self, timeout=5.0):
        self.t.connect(timeout)

    def close(self):
        self.t.close()

    def measure(self, duration_s=0.5, timeout=10.0):
        m = self.t.measure(duration_s, timeout)
        if self.armed:
            q = self.cell.robot_state().q + [0.0, 0.05, 0.0]
            self.cell.command_move_joints(q, 1.0)
        return m


def _toy(name, seed=1):
    robot, tracker = open_robot(toy_sim("robot", seed, name)), open_tracker(
        toy_sim("tracker", seed, name))
    robot.connect()
    tracker.connect()
    return robot, tracker


def test_a_repeated_measurement_is_never_stored(tmp_path):
    robot, inner = _toy("repeat")
    tracker = _Repeating(inner)
    plan = make_plan("poses", TOYM, count=4, seed=1)
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.0)
    with RunStore(tmp_path / "c.db") as st:
        rid = st.create_run(plan, RunContext(routine="poses", executor=opts))

        def progress(done, total, err):
            tracker.repeat = tracker.repeat or done == 2  # at the third point, once

        ex = Executor(st, rid, plan, robot, tracker, opts, progress=progress,
                      guard=MotionGuard(TOYM))
        assert ex.run() == "completed"
        s = st.samples(rid)
        kinds = [k for _, _, k, _ in st.interruptions(rid)]
    assert kinds == ["stale_measurement"]
    assert np.all(np.diff(s.t_s) > 0) and len({tuple(x) for x in s.tracker_p_smr}) == 4
    assert issubclass(StaleMeasurement, Exception) and StaleMeasurement.transient


def test_a_robot_moved_during_the_measurement_pauses_the_run(tmp_path):
    robot, inner = _toy("meddle")
    tracker = _Meddling(inner, robot.cell)
    plan = make_plan("poses", TOYM, count=4, seed=2)
    with RunStore(tmp_path / "c.db") as st:
        tracker.armed = False
        rid, status = run_plan(st, plan, robot, tracker, model=TOYM,
                               options=ExecutorOptions(measure_s=0.01))
        assert status == "completed"
        plan2 = make_plan("poses", TOYM, count=4, seed=3)
        tracker.armed = True
        rid2, status = run_plan(st, plan2, robot, tracker, model=TOYM,
                                options=ExecutorOptions(measure_s=0.01))
        assert status == "paused" and st.n_samples(rid2) == 0
        reason = st.run(rid2).reason
    assert "motion_mismatch at point 0" in reason and "moved during the measurement" in reason


def test_adaptive_moves_are_bounded_by_the_guard(tmp_path):
    """A zero20-style acquisition that asks for a wild correction is refused before motion."""
    robot, tracker = _toy("wild")

    class Wild:
        def acquire(self, t, ctx):
            ctx.move_joints(np.asarray(t.q) + [0.0, 0.0, 1.0])  # 57 deg off the posture
            raise AssertionError("never reached")

    plan = Plan("poses", {}, (Target(0, "joints", q=[0.1, 0.5, -0.8]),), model="toyarm")
    with RunStore(tmp_path / "c.db") as st:
        rid = st.create_run(plan, RunContext(routine="poses"))
        moves = robot.cell.n_moves
        ex = Executor(st, rid, plan, robot, tracker, ExecutorOptions(measure_s=0.01),
                      acquisition=Wild(), guard=MotionGuard(TOYM))
        assert ex.run() == "paused"
        reason = st.run(rid).reason
    assert robot.cell.n_moves == moves + 1  # the planned move only
    assert "move_refused at point 0" in reason and "joint 3 57.296 deg from the planned" in reason


# ------------------------------------------- re-measurements: the same checks
class _Suspicious:
    """A running model that finds every reading suspect and no two readings agreeing (a
    re-measure policy that always moves away and back)."""

    samples: dict = {}

    def judge(self, s):
        return Judgement(True, 1.0, 0.1, 10.0)

    def agree(self, a, b):
        return False

    def add(self, s):
        return False

    def warmup_suspects(self):
        return []


def _remeasuring_run(st, robot, tracker, retract_rad=0.01, count=2):
    plan = make_plan("poses", TOYM, count=count, seed=4)
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.0)
    rid = st.create_run(plan, RunContext(routine="poses", executor=opts))
    policy = Remeasure(_Suspicious(), plan, n=1, retract_rad=retract_rad,
                       limits=TOYM.limits_rad())
    ex = Executor(st, rid, plan, robot, tracker, opts, guard=MotionGuard(TOYM),
                  remeasure=policy)
    return rid, ex.run()


def test_a_re_measurements_moves_are_checked_by_the_guard(tmp_path):
    robot, tracker = _toy("remeasure-guard")
    with RunStore(tmp_path / "c.db") as st:
        moves = robot.cell.n_moves
        rid, status = _remeasuring_run(st, robot, tracker, retract_rad=0.5)
        reason, n = st.run(rid).reason, st.n_samples(rid)
    assert status == "paused" and n == 0
    assert robot.cell.n_moves == moves + 1  # the planned move only: the retract refused
    assert "move_refused at point 0" in reason and "from the planned posture" in reason


class _MeddlingOnce(_Meddling):
    """Nudges the robot during its second measurement only (a point's re-measurement)."""

    n = 0

    def measure(self, duration_s=0.5, timeout=10.0):
        self.n += 1
        self.armed = self.n == 2
        return super().measure(duration_s, timeout)


def test_a_robot_moved_during_a_re_measurement_pauses_the_run(tmp_path):
    robot, inner = _toy("remeasure-meddle")
    with RunStore(tmp_path / "c.db") as st:
        rid, status = _remeasuring_run(st, robot, _MeddlingOnce(inner, robot.cell))
        reason, n, readings = st.run(rid).reason, st.n_samples(rid), st.readings(rid)
    assert status == "paused" and n == 0 and readings == []
    assert "motion_mismatch at point 0" in reason and "moved during the measurement" in reason


def test_a_repeated_re_measurement_is_never_stored(tmp_path):
    robot, inner = _toy("remeasure-repeat")
    tracker = _Repeating(inner)
    tracker.repeat = True  # the second reply repeats the first: the re-measurement's
    with RunStore(tmp_path / "c.db") as st:
        rid, status = _remeasuring_run(st, robot, tracker)
        s, readings = st.samples(rid), st.readings(rid)
        kinds = [k for _, _, k, _ in st.interruptions(rid)]
    assert status == "completed" and kinds == ["stale_measurement"]
    assert s.verdict == ["unresolved"] * 2 and len(readings) == 2
    t = sorted([*s.t_s, *(r.sample.t_s for r in readings)])
    assert np.all(np.diff(t) > 0)  # four distinct readings, none a repeat


# ------------------------------------------------------- stops on signals
@pytest.mark.parametrize("signals, name", [((signal.SIGTERM,), "SIGTERM"),
                                           ((signal.SIGINT, signal.SIGINT), "a second Ctrl-C"),
                                           ((signal.SIGHUP,), "SIGHUP")])
def test_a_signal_stops_the_robot_at_once(tmp_path, signals, name):
    robot, tracker = _toy(f"sig{len(signals)}{name[-3:]}")
    cell = robot.cell
    cell.time_scale = 1.0  # real time: moves take seconds
    cell._wall0 = time.monotonic()
    plan = Plan("poses", {}, (Target(0, "joints", q=[1.5, 0.5, -0.8]),
                              Target(1, "joints", q=[-1.5, 0.5, -0.8])), model="toyarm")
    opts = ExecutorOptions(measure_s=0.01, speed_rad_s=0.2)

    def send():
        while not cell.robot_state().moving:
            time.sleep(0.005)
        for s in signals:
            os.kill(os.getpid(), s)
            time.sleep(0.1)

    with RunStore(tmp_path / "c.db") as st:
        rid = st.create_run(plan, RunContext(routine="poses"))
        ex = Executor(st, rid, plan, robot, tracker, opts, guard=MotionGuard(TOYM))
        threading.Thread(target=send, daemon=True).start()
        assert ex.run() == "paused"
        run = st.run(rid)
        assert ex.stop_signal == signals[-1]
    s1 = cell.robot_state()
    time.sleep(0.3)
    s2 = cell.robot_state()
    assert not s1.moving and np.array_equal(s1.q, s2.q)  # the joint stopped and stays
    assert abs(s1.q[0] - 1.5) > 0.05  # short of the target it was sent to
    assert run.status == "paused" and f"stopped at once by {name} at point 0" in run.reason
    assert "the controller's stop was sent" in run.reason


# ------------------------------------------------- options before the run
@pytest.mark.parametrize("flag, value, words", [
    ("--speed", "100", "--speed: Input should be less than or equal to 3.14"),
    ("--speed", "-1", "--speed: Input should be greater than 0"),
    ("--io-timeout", "0", "--io-timeout: Input should be greater than 0"),
    ("--max-retries", "-1", "--max-retries: Input should be greater than or equal to 0"),
    ("--measure-s", "-1", "--measure-s: Input should be greater than 0"),
    ("--tool-mm", "nan,0,0", "--tool-mm: expected 3 finite numbers"),
    ("--floor-z-mm", "nan", "--floor-z-mm: Input should be a finite number"),
    ("--keepout-mm", "0,0,0,1,1", "--keepout-mm: expected 6 numbers"),
])
def test_capture_options_are_checked_before_a_run_exists(tmp_path, capsys, flag, value, words):
    db = tmp_path / "c.db"
    rc = main(["capture", "poses", "--count", "3", "--model", TOY, "--robot",
               toy_sim("robot", 1, "opts"), "--tracker", toy_sim("tracker", 1, "opts"),
               "--db", str(db), f"{flag}={value}"])
    err = capsys.readouterr().err
    assert rc == 2 and words in err and len(err.strip().splitlines()) == 1, err
    assert not db.exists()


def test_resume_options_are_checked_first(tmp_path, capsys):
    rc = main(["resume", "--db", str(tmp_path / "none.db"), "--speed", "0"])
    assert rc == 2 and "--speed: Input should be greater than 0" in capsys.readouterr().err


def test_the_robot_must_be_the_models_before_a_run_exists(tmp_path, capsys):
    db = tmp_path / "c.db"
    rc = main(["capture", "poses", "--count", "3", "--model", "ur10e", "--robot",
               "sim://robot?seed=1", "--tracker", "sim://tracker?seed=1", "--db", str(db),
               "--no-visibility"])
    assert rc == 2 and "needs model=NAME|PATH" in capsys.readouterr().err
    rc = main(["capture", "poses", "--count", "3", "--model", "ur10e", "--no-floor", "--robot",
               toy_sim("robot", 1, "toy"), "--tracker", toy_sim("tracker", 1, "toy"),
               "--db", str(db), "--json", "--no-visibility"])
    assert rc == 2 and "has 3 joints, the model ur10e has 6" in capsys.readouterr().err
    rc = main(["capture", "poses", "--count", "3", "--model", "ur5e", "--no-floor", "--robot",
               "sim://robot?model=ur10e&seed=1&name=ur", "--tracker",
               "sim://tracker?seed=1&name=ur", "--db", str(db), "--no-visibility"])
    assert rc == 2 and "simulates a ur10e, the run's model is ur5e" in capsys.readouterr().err
    with RunStore(db) as st:
        assert st.runs() == []
    assert inproc.get_cell("default", 1).n_moves == 0
    assert inproc.get_cell("ur", 1).n_moves == 0
    rc = main(["capture", "poses", "--count", "3", "--model", "ur10e", "--tool-mm", "0,0,60",
               "--no-floor", "--tracker-at", "2500,0,500",
               "--robot", "sim://robot?model=ur10e&seed=1&name=ur", "--tracker",
               "sim://tracker?seed=1&name=ur", "--db", str(db), "--json", "--measure-s", "0.01"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["samples"] == 3
    with RunStore(db) as st:
        ident = st.run(out["run"]).robot_identity
    assert ident["simulator"] and ident["kinematics"] == "ur10e" and ident["n_joints"] == 6
