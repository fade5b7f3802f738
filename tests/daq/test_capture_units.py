"""Plans, dry run, frame fits, executor control flow, CLI safety."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

import sim_drivers.inprocess as inproc
from calibration import ErrorModel, identify, load_csv, load_model
from calibration.cell.frame_fit import axis_angle_deg, fit_circle, fit_line, measurement_frame
from cellcal.cli import main
from cellcal.commands.capture import confirm_motion
from cellcal.progress import Progress
from daq.check import PlanRefused, check_plan, require_ok
from daq.devices import CellIdentity
from daq.plans import Plan, Target
from daq.routines import make_plan
from daq.routines.poses import observability
from daq.run_context import ExecutorOptions
from daq.run_data import dataset_from_run
from daq.store import RunStore
from drivers.protocols import DeviceIdentity
from drivers.urls import open_robot, open_tracker

from .capture_helpers import TOY, run_plan, toy_sim

TOYM = load_model(TOY)


# ---------------------------------------------------------------- plans
def test_plan_hash_is_content_hash_and_round_trips():
    a = make_plan("steps", TOYM, start_deg=[0, 20, -60], count=3)
    b = make_plan("steps", TOYM, start_deg=[0, 20, -60], count=3)
    c = make_plan("steps", TOYM, start_deg=[0, 20, -60], count=4)
    assert a.hash == b.hash != c.hash
    assert Plan.from_json(a.to_json()).hash == a.hash
    assert [t.index for t in a.targets] == list(range(len(a)))
    with pytest.raises(ValueError, match="index"):
        Plan("x", {}, (Target(1, "joints", q=[0, 0, 0]),))


def test_check_plan_names_the_offending_points():
    ok = Target(0, "joints", q=[0.0, 0.3, -0.5])
    over = Target(1, "joints", q=[0.0, 0.3, np.radians(190.0)], label="over")
    floor = Target(2, "joints", q=[0.0, -1.2, 0.0], label="low")
    far = Target(3, "linear", q=[0.0, 0.0, 0.0], base_p_tcp=[900.0, 0.0, 100.0], label="far")
    res = check_plan(Plan("t", {}, (ok, over, floor, far)), TOYM, floor_z_mm=0.0)
    assert res.bad_indices == [1, 2, 3]
    text = res.report()
    assert "point 1 (over): target joint 3 = 190.000 deg beyond its max limit 180 deg" in text
    assert "point 2 (low)" in text and "below the floor 0 mm" in text
    assert "point 3 (far): unreachable" in text
    with pytest.raises(PlanRefused, match="3 of 4 targets"):
        require_ok(Plan("t", {}, (ok, over, floor, far)), TOYM)


def test_routines_make_checked_plans():
    ur = load_model("ur10e")
    p = make_plan("frame", TOYM, start_deg=[0, 20, -60], line_length_mm=150)
    assert check_plan(p, TOYM).ok and len(p) == 23
    p = make_plan("iso9283", TOYM, start_deg=[0, 20, -60], side_mm=100, cycles=4)
    assert check_plan(p, TOYM).ok and len(p) == 20 and all(t.via is not None for t in p.targets)
    p = make_plan("poses", TOYM, count=40, seed=1, valid_fraction=0.25)
    assert check_plan(p, TOYM).ok and sum(t.set == "valid" for t in p.targets) == 10
    z = make_plan("zero20", ur, target_xyz=[600.0, 200.0, 300.0])
    assert len(z) == 20 and sorted({t.info["plane"] for t in z.targets}) == [1, 2, 3, 4]
    assert check_plan(z, ur, floor_z_mm=None).ok
    assert len({tuple(np.round(t.q, 3)) for t in z.targets}) == 20  # 20 distinct postures
    with pytest.raises(ValueError, match="6\\+ joints"):
        make_plan("zero20", TOYM, target_xyz=[400, 0, 200])


def test_optimal_poses_observe_more_than_random():
    ur = load_model("ur10e")
    em = ErrorModel(ur, "geometric,base,tool")
    opt = make_plan("poses", ur, count=40, seed=2, method="optimal", floor_z_mm=None)
    o_opt = observability(em, np.array([t.q for t in opt.targets]))
    assert opt.params["observability_index"] == pytest.approx(o_opt)
    for seed in range(3):
        rnd = make_plan("poses", ur, count=40, seed=seed, floor_z_mm=None)
        assert o_opt > 1.04 * observability(em, np.array([t.q for t in rnd.targets]))


# ------------------------------------------------------------ frame fit
def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_circle_and_line_fits_exact_and_noisy():
    rng = np.random.default_rng(0)
    R, c = _rotation(rng), rng.normal(size=3) * 1000
    a = np.linspace(-1.0, 1.0, 30)
    P = c + 600 * (np.outer(np.cos(a), R[:, 0]) + np.outer(np.sin(a), R[:, 1]))
    fit = fit_circle(P)
    assert np.allclose(fit.centre, c, atol=1e-8) and abs(fit.radius - 600) < 1e-8
    assert axis_angle_deg(fit.normal, R[:, 2]) < 1e-8 and fit.rms < 1e-8
    assert axis_angle_deg(fit_circle(P[::-1]).normal, -R[:, 2]) < 1e-8  # orientation by order
    noisy = fit_circle(P + rng.normal(0, 0.01, P.shape))
    assert np.linalg.norm(noisy.centre - c) < 0.05 and 0.005 < noisy.rms < 0.02
    L = c + np.outer(np.linspace(0, 300, 20), R[:, 0])
    ln = fit_line(L + rng.normal(0, 0.01, L.shape))
    assert axis_angle_deg(ln.direction, R[:, 0]) < 0.01 and ln.rms < 0.02
    with pytest.raises(ValueError, match="collinear"):
        fit_circle(L)


def test_measurement_frame_recovers_a_known_transform():
    rng = np.random.default_rng(1)
    R, t = _rotation(rng), np.array([-2100.0, 350.0, -80.0])
    h = 420.0
    a = np.linspace(-0.8, 0.8, 15)
    circ_base = np.column_stack([700 * np.cos(a), 700 * np.sin(a), np.full(a.size, h)])
    line_base = np.column_stack([np.linspace(500, 800, 11), np.zeros(11), np.full(11, h)])
    fit = measurement_frame(circ_base @ R.T + t, line_base @ R.T + t, h)
    assert np.allclose(fit.tracker_T_base[:3, :3], R, atol=1e-9)
    assert np.allclose(fit.tracker_T_base[:3, 3], t, atol=1e-7)


# ---------------------------------------------------------------- store
# the store's own tests: test_store.py (both backends)


def test_export_loads_and_identifies(tmp_path):
    """In-process sim: a poses run exported to CSV is read by load_csv and identified."""
    inproc.reset_cells()
    plan = make_plan("poses", TOYM, count=40, seed=3, valid_fraction=0.25)
    robot = open_robot(toy_sim("robot", 11, "export"))
    tracker = open_tracker(toy_sim("tracker", 11, "export"))
    robot.connect()
    tracker.connect()
    with RunStore(tmp_path / "c.db") as st:
        rid, status = run_plan(st, plan, robot, tracker, options=ExecutorOptions(measure_s=0.01))
        assert status == "completed"
        data = dataset_from_run(st, rid)
        data.to_csv(tmp_path / "d.csv")
    inproc.reset_cells()
    back = load_csv(tmp_path / "d.csv", TOYM)
    assert back.n == 40 and back.is_valid.sum() == 10
    assert back.cmd is not None and back.dirs is not None and back.temp_c is not None
    assert back.meta["routine"] == "poses"
    fit = identify(ErrorModel(TOYM, "geometric,base,tool"), back)
    assert fit.converged and fit.valid["rms_mm"] < 0.1


# ------------------------------------------------------------- executor
def test_pause_on_protective_stop_stop_request_and_resume(tmp_path):
    inproc.reset_cells()
    plan = make_plan("poses", TOYM, count=12, seed=4)
    robot = open_robot(toy_sim("robot", 12, "pause"))
    tracker = open_tracker(toy_sim("tracker", 12, "pause"))
    robot.connect()
    tracker.connect()
    cell = robot.cell
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.0)
    with RunStore(tmp_path / "c.db") as st:
        cell.faults.arm("beam", 2)  # transient: retried on the same point
        cell.faults.arm("pstop")
        rid, status = run_plan(st, plan, robot, tracker, options=opts)
        assert status == "paused" and "protective stop" in st.run(rid).reason
        cell.clear_protective_stop()
        from daq.executor import Executor

        ex = Executor(st, rid, plan, robot, tracker, opts,
                      progress=lambda done, total, err: ex.request_stop() if done >= 5 else None)
        assert ex.run() == "stopped" and st.run(rid).status == "stopped"
        n_stopped = st.n_samples(rid)
        assert 5 <= n_stopped < 12
        _, status = run_plan(st, plan, robot, tracker, options=opts, run_id=rid)
        assert status == "completed"
        s = st.samples(rid)
        kinds = [k for _, _, k, _ in st.interruptions(rid)]
    inproc.reset_cells()
    assert s.point_index.tolist() == list(range(12))
    assert kinds.count("beam") == 2 and "protective_stop" in kinds and "sigint" in kinds
    assert set(np.unique(s.dirs)) <= {-1, 0, 1}


def test_quality_threshold_remeasures_then_gives_up(tmp_path):
    inproc.reset_cells()
    plan = make_plan("poses", TOYM, count=2, seed=5)
    robot = open_robot(toy_sim("robot", 13, "q"))
    tracker = open_tracker(toy_sim("tracker", 13, "q"))
    robot.connect()
    tracker.connect()
    with RunStore(tmp_path / "c.db") as st:
        rid, status = run_plan(st, plan, robot, tracker, options=ExecutorOptions(
            measure_s=0.01, max_std_mm=1e-6, max_remeasure=2, max_retries=1, backoff_s=0.0))
        kinds = [k for _, _, k, _ in st.interruptions(rid)]
        assert status == "paused" and st.n_samples(rid) == 0
    inproc.reset_cells()
    assert kinds.count("quality") == 2 and "attempts failed" in kinds[-1] or kinds[-1] == "pause"


# ------------------------------------------------------------------ CLI
def test_only_identified_simulators_move_without_confirmation():
    from cellcal.errors import UsageError

    class NoTTY(io.StringIO):
        def isatty(self):
            return False

    class TTY(io.StringIO):
        def isatty(self):
            return True

    sim = CellIdentity(DeviceIdentity("robot", "SIMBOT-1", "S1", simulator=True),
                       DeviceIdentity("tracker", "SIMTRACK-1", "T1", simulator=True))
    # a loopback bridge to a real controller says nothing of the kind
    real = CellIdentity(DeviceIdentity("robot", "SIMBOT-1", "S1"), sim.tracker)
    urls = ["socket://127.0.0.1:15021", "tracker+tcp://127.0.0.1:15700"]
    confirm_motion(sim, urls, yes=False, stdin=NoTTY())
    confirm_motion(real, urls, yes=True, stdin=NoTTY())
    with pytest.raises(UsageError, match="127.0.0.1:15021.*did not identify as a simulator.*--yes"):
        confirm_motion(real, urls, yes=False, stdin=NoTTY())
    confirm_motion(real, urls, yes=False, stdin=TTY("yes\n"), stderr=io.StringIO())
    with pytest.raises(UsageError, match="not confirmed"):
        confirm_motion(real, urls, yes=False, stdin=TTY("n\n"), stderr=io.StringIO())


def test_cli_refuses_a_bad_plan_and_an_unidentified_robot_without_tty(tmp_path, capsys,
                                                                      monkeypatch):
    db = str(tmp_path / "c.db")
    rc = main(["capture", "steps", "--model", TOY, "--start-deg", "0,20,-60", "--step-mm", "50",
               "--robot", "sim://robot", "--tracker", "sim://tracker", "--db", db,
               "--no-visibility"])
    assert rc == 2 and "unreachable" in capsys.readouterr().err
    inproc.reset_cells()
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    monkeypatch.setattr(inproc.SimRobot, "identify", lambda self, timeout=2.0: DeviceIdentity(
        "robot", "ACME-7", "A1", n_joints=3))
    rc = main(["capture", "poses", "--count", "3", "--model", TOY, "--robot",
               toy_sim("robot", 3, "real"), "--tracker", toy_sim("tracker", 3, "real"),
               "--db", db, "--no-visibility"])
    assert rc == 2 and "--yes" in capsys.readouterr().err
    with RunStore(db) as st:
        assert st.runs() == []  # nothing stored, nothing moved
    assert inproc.get_cell("real", 3).n_moves == 0
    inproc.reset_cells()


def test_cli_capture_runs_export_in_process(tmp_path, capsys):
    inproc.reset_cells()
    db, csv = str(tmp_path / "c.db"), str(tmp_path / "d.csv")
    rc = main(["capture", "poses", "--count", "8", "--seed", "1", "--model", TOY,
               "--robot", toy_sim("robot", 21, "cli"), "--tracker",
               toy_sim("tracker", 21, "cli"), "--db", db, "--json", "--measure-s", "0.01",
               "--no-visibility"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["samples"] == 8 and out["status"] == "completed"
    assert main(["runs", "--db", db, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["samples"] == 8
    assert main(["resume", "--db", db]) == 0  # already completed: nothing to do
    assert main(["export", "--db", db, "--out", csv]) == 0
    inproc.reset_cells()
    assert load_csv(csv, TOYM).n == 8


def test_progress_lines():
    buf = io.StringIO()
    p = Progress(buf, tty=False, interval_s=0.0)
    p(0, 10)
    p(5, 10, "beam: BEAM_BROKEN")
    p(10, 10)
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith("0/10 points") and "last error: beam" in lines[1]
    tty = io.StringIO()
    p = Progress(tty, tty=True)
    p(1, 3)
    p(3, 3)
    p.close()
    # refreshed in place, then erased: the summary line that follows starts at column 0
    assert tty.getvalue().startswith("\r1/3") and tty.getvalue().endswith(" \r")
    assert "\n" not in tty.getvalue()
    quiet = io.StringIO()
    Progress(quiet, enabled=False)(1, 2)
    assert quiet.getvalue() == ""


# ------------------------------------------------------ layout contracts
def test_every_routine_has_its_command_line_options():
    from cellcal.flags.routine_args import ROUTINE_ARGS
    from daq.routines import ROUTINES

    assert set(ROUTINE_ARGS) == set(ROUTINES)


def test_capture_errors_are_their_own_family():
    from daq.errors import CaptureError, QualityError, ZeroNotReached
    from daq.executor import fault_kind
    from drivers.errors import DriverError

    for cls in (QualityError, ZeroNotReached):
        assert issubclass(cls, CaptureError) and not issubclass(cls, DriverError)
    assert QualityError.transient and not ZeroNotReached.transient
    assert fault_kind(QualityError("tracker t", "measure", "std")) == "quality"
    assert str(QualityError("tracker t", "measure", "std")) == "tracker t: measure: std"


def test_zero_loop_rotation_fit_recovers_the_tracker_orientation():
    from calibration.model.transforms import random_rotation
    from daq.routines.zero20 import rotation_between

    rng = np.random.default_rng(3)
    R = random_rotation(rng)
    a = 5.0 * np.eye(3) + rng.normal(0, 0.05, (3, 3))  # three probe displacements, mm
    np.testing.assert_allclose(rotation_between(a, a @ R.T), R, atol=1e-12)
