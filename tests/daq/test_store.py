"""The run store on both backends: one suite, parametrised over a SQLite file and a
PostgreSQL database on a throwaway server (``store_address``, tests/conftest.py)."""

from __future__ import annotations

import sqlite3
import threading

import numpy as np
import pytest

from calibration import load_model
from daq.routines import make_plan
from daq.run_context import RunContext
from daq.store import Reading, RunStore, Sample, StoreError, StoreUnavailable, open_store
from daq.store.dialect import connect, display_address, is_server_address, translate
from daq.store.schema import SCHEMA_V1, SCHEMA_VERSION, UPGRADES

from .capture_helpers import TOY, toy_sim

TOYM = load_model(TOY)


def sample(i, n_joints=3):
    return Sample(point_index=i, q=np.full(n_joints, 0.1 * i),
                  tracker_p_smr=np.array([i + 1234.567890123456, 2.0, 3.0]),
                  std_mm=np.full(3, 0.01), n_averaged=500, t_s=1.7e9 + i + 0.123456,
                  pose_id=f"p{i}", temp_c=20.0, cmd=np.array([1.0, 2.0, 3.0]),
                  dirs=np.array([1, 0, -1]))


def _at_version(address, version: int) -> None:
    """Create the store's schema at ``version`` (as an older cellcal left it)."""
    db = connect(address)
    try:
        with db.transaction():
            for statement in SCHEMA_V1.split(";"):
                if statement.strip():
                    db.execute(statement)
            for v in range(1, version):
                UPGRADES[v](db)
            db.set_version(version)
    finally:
        db.close()


def test_idempotent_and_durable(store_address):
    plan = make_plan("poses", TOYM, count=5, seed=0)
    with RunStore(store_address) as st:
        assert st.version == SCHEMA_VERSION
        if st.kind == "sqlite":
            assert st.con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
            assert st.con.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
        else:
            assert st.con.execute("SHOW synchronous_commit").fetchone()[0] == "on"
        rid = st.create_run(plan, RunContext(routine="poses", robot_url="sim://robot",
                                             seed=2**40 + 3, model="toy"), robot_id="toy/1")
        assert st.add_sample(rid, sample(0)) is True
        assert st.add_sample(rid, sample(0)) is False  # second write of a point is ignored
        st.add_sample(rid, sample(3))
        st.add_interruption(rid, 3, "beam", "BEAM_BROKEN")
        assert st.done_indices(rid) == {0, 3}
    with open_store(store_address, create=False) as st:  # reopened: all there
        assert st.n_samples(rid) == 2 and st.interruptions(rid)[0][2] == "beam"
        r = st.run()
        assert r.id == rid and r.plan_hash == plan.hash and r.robot_id == "toy/1"
        assert r.seed == 2**40 + 3 and r.status == "running"
        s = st.samples(rid)
        assert s.tracker_p_smr[0, 0] == 1234.567890123456  # doubles, not 4-byte reals
        assert s.t_s[1] == 1.7e9 + 3.123456
        assert s.dirs.tolist() == [[1, 0, -1], [1, 0, -1]] and s.pose_id == ["p0", "p3"]
        st.set_status(rid, "completed")
        assert st.latest_run("poses").id == rid
        assert st.latest_run("poses", robot_id="toy/1").id == rid
        with pytest.raises(StoreError, match="no completed poses run of robot other"):
            st.latest_run("poses", robot_id="other")
        with pytest.raises(StoreError, match="no run 9"):
            st.run(9)


def test_update_run_and_context(store_address):
    plan = make_plan("poses", TOYM, count=3, seed=0)
    with RunStore(store_address) as st:
        rid = st.create_run(plan, RunContext(routine="poses", robot_url="a", tracker_url="b"))
        st.update_run(rid, robot_url="c", summary={"k": 1}, frame={"tracker_T_base": []},
                      robot_id="R")
        r = st.run(rid)
        assert (r.robot_url, r.tracker_url, r.summary, r.robot_id) == ("c", "b", {"k": 1}, "R")
        assert [x.id for x in st.runs("R")] == [rid] and st.runs("S") == []
        with pytest.raises(ValueError, match="cannot update"):
            st.update_run(rid, status="completed")


@pytest.mark.parametrize("version", [1, 3, 5, 6])
def test_upgrades_an_older_store(store_address, version):
    _at_version(store_address, version)
    db = connect(store_address)
    db.execute("INSERT INTO runs (routine, plan_json, plan_hash, n_points, status, model) "
               "VALUES ('poses', '{}', 'abc', 2, 'completed', 'toyarm')")
    db.execute("INSERT INTO samples (run_id, point_index, pose_id, q_json, x, y, z, sx, sy, sz, "
               "n, t, temp_c) VALUES (1, 0, 'a', '[0.1, 0.2, 0.3]', 1, 2, 3, .01, .01, .01, "
               "10, 5.0, 20.5)")
    if version >= 3:
        db.execute("UPDATE runs SET context_json=? WHERE id=1",
                   (RunContext(routine="poses", model="toyarm").to_json(),))
    db.close()
    with RunStore(store_address) as st:
        assert st.version == SCHEMA_VERSION
        r = st.run(1)
        assert r.routine == "poses" and r.frame is None and r.robot_id is None
        s = st.samples(1)
        assert s.q.tolist() == [[0.1, 0.2, 0.3]] and np.isnan(s.cmd).all()
        st.add_interruption(1, None, "test", "the new table exists")
        assert st.interruptions(1)[0][2] == "test"
        assert st.add_calibration("r", {"parameters": []})[1] is True  # schema 7's table
        assert "robot_id" in st.db.columns("runs")
        # 5 -> 6 (re-measure): the verdict columns, the readings table; old rows unjudged
        assert {"verdict", "remeasures", "model_residual_mm"} <= set(st.db.columns("samples"))
        assert s.verdict == [None] and s.remeasures.tolist() == [0] and st.readings(1) == []
        assert st.remeasure_counts(1)["suspects"] == 0
        # main's 3 -> 4 (tracker metadata) and 4 -> 5 (leases, identities) on either backend
        assert {"reflector", "face", "cov_zz"} <= set(st.db.columns("samples"))
        assert {"robot_identity", "tracker_identity", "source_run"} <= set(
            st.db.columns("runs"))
        assert st.db.has_table("leases") and r.robot_identity is None
        assert s.reflector == [None] and np.all(np.isnan(s.cov_mm2))
    db = connect(store_address)
    db.set_version(SCHEMA_VERSION + 1)
    db.close()
    with pytest.raises(StoreError, match="newer"):
        RunStore(store_address)


def test_two_processes_upgrade_an_old_store_once(store_address):
    _at_version(store_address, 1)
    errors = []

    def open_it():
        try:
            RunStore(store_address).close()
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=open_it) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    with RunStore(store_address) as st:
        assert st.version == SCHEMA_VERSION


def test_missing_and_empty_stores_are_refused(store_address, tmp_path):
    with pytest.raises(StoreError, match="no such run store|no run store here"):
        open_store(store_address, create=False)
    with pytest.raises(StoreError):
        open_store(store_address, read_only=True)
    if store_address.startswith("postgresql"):
        base = store_address.rsplit("/", 1)[0]
        with pytest.raises(StoreError, match="does not exist") as e:
            open_store(base + "/no_such_database")
        assert not isinstance(e.value, StoreUnavailable)


def test_read_only_reads_and_refuses_writes(store_address):
    plan = make_plan("poses", TOYM, count=3, seed=0)
    with RunStore(store_address) as st:
        rid = st.create_run(plan)
        st.add_sample(rid, sample(1))
    with open_store(store_address, read_only=True) as st:
        assert st.n_samples(rid) == 1 and st.run().id == rid
        with pytest.raises((StoreError, sqlite3.OperationalError)):
            st.add_sample(rid, sample(2))
    if not is_server_address(store_address):
        return  # an older SQLite store opened read-only is upgraded in a copy in memory
        # (test_store_robust); a server's tables are upgraded only with write access
    db = connect(store_address)
    db.set_version(SCHEMA_VERSION - 1)
    db.close()
    with pytest.raises(StoreError, match="with write access"):
        open_store(store_address, read_only=True)


def test_tracker_metadata_identities_and_readings_round_trip(store_address):
    """The columns and tables main added (schemas 4-6) on either backend: the tracker's
    reflector, face and covariance per sample; the devices' identities and the source run
    per run; the readings the re-measure policy did not accept, written with their
    point's sample, and a re-measured point replaced in a later point's commit."""
    plan = make_plan("poses", TOYM, count=6, seed=0)
    cov = np.array([[4e-4, 1e-5, -2e-5], [1e-5, 3e-4, 0.0], [-2e-5, 0.0, 5e-4]])
    ident = {"vendor": "sim", "model": "TOY", "serial": "7", "simulator": True}
    with RunStore(store_address) as st:
        rid = st.create_run(plan, robot_identity=ident, tracker_identity={"model": "T"},
                            source_run=None)
        other = st.create_run(plan, source_run=rid)
        first = sample(0)
        first.reflector, first.face, first.cov_mm2 = "RRR 1.5in", 2, cov
        first.verdict, first.remeasures = "remeasured", 1
        first.model_residual_mm, first.model_threshold_mm = 0.01, 0.09
        bad = sample(0)
        bad.tracker_p_smr = bad.tracker_p_smr + 2.0
        bad.model_residual_mm, bad.model_threshold_mm = 2.0, 0.09
        assert st.add_sample(rid, first, [Reading(bad, "2.000 mm from the model")])
        # the same commit again (a lost connection): nothing doubled
        assert not st.add_sample(rid, first, [Reading(bad, "2.000 mm from the model")])
        warm = sample(1)
        warm.verdict = "warmup"
        assert st.add_sample(rid, warm)
        # point 1 revisited while point 2 is done: its reading is replaced, the old one kept
        again = sample(1)
        again.t_s, again.verdict, again.remeasures = warm.t_s + 100.0, "remeasured", 1
        again.tracker_p_smr = again.tracker_p_smr + 0.001
        pair = (again, [Reading(warm, "revisited: 1.5 mm from the model")])
        assert st.add_sample(rid, sample(2), revisited=[pair])
        st.add_sample(rid, sample(2), revisited=[pair])  # repeated: a no-op
        with pytest.raises(StoreError, match="no point 5 to replace"):
            lost = sample(5)
            st.add_sample(rid, sample(3), revisited=[(lost, [])])
        assert st.done_indices(rid) == {0, 1, 2}  # the failed commit stored nothing
    with open_store(store_address, create=False) as st:
        r, o = st.run(rid), st.run(other)
        assert r.robot_identity == ident and r.tracker_identity == {"model": "T"}
        assert r.source_run is None and o.source_run == rid and o.robot_identity is None
        s = st.samples(rid)
        assert s.reflector == ["RRR 1.5in", None, None] and s.face.tolist() == [2, 0, 0]
        np.testing.assert_array_equal(s.cov_mm2[0], cov)
        assert np.isnan(s.cov_mm2[1:]).all()
        assert s.verdict == ["remeasured", "remeasured", None]
        assert s.remeasures.tolist() == [1, 1, 0]
        assert s.t_s[1] == warm.t_s + 100.0 and s.tracker_p_smr[1, 0] == again.tracker_p_smr[0]
        readings = st.readings(rid)
        assert [(x.sample.point_index, x.reason) for x in readings] == [
            (0, "2.000 mm from the model"), (1, "revisited: 1.5 mm from the model")]
        assert readings[0].sample.model_residual_mm == 2.0
        assert readings[0].sample.pose_id == "p0" and readings[1].sample.t_s == warm.t_s
        np.testing.assert_array_equal(readings[0].sample.tracker_p_smr, bad.tracker_p_smr)
        counts = st.remeasure_counts(rid)
        assert counts == {"judged": 2, "warmup": 0, "suspects": 2, "remeasurements": 2,
                          "rejected": 2, "model_disagrees": 0, "unresolved": 0}
        assert all(type(v) is int for v in counts.values())


def test_joint_temperatures_and_full_pose_round_trip(store_address):
    """Schema 9 on either backend: joint temperatures, a 6-DoF target's orientation and its
    uncertainty, and the tool target's id, per sample and per rejected reading; a
    position-only sample reads back without them."""
    plan = make_plan("poses", TOYM, count=4, seed=0)
    quat = np.array([0.5, 0.5, -0.5, 0.5])
    with RunStore(store_address) as st:
        rid = st.create_run(plan)
        full = sample(0)
        full.joint_temp = np.array([31.5, 33.25, 29.0])
        full.quat, full.sigma_deg, full.tool_id = quat, 0.01, "nest2"
        bad = sample(0)
        bad.joint_temp, bad.quat, bad.tool_id = full.joint_temp, -quat, "nest2"
        assert st.add_sample(rid, full, [Reading(bad, "1 mm from the model")])
        warm = sample(1)
        warm.joint_temp = np.array([32.0, 34.0, 30.0])
        assert st.add_sample(rid, warm)
        other = st.create_run(plan)
        assert st.add_sample(other, sample(0)) and st.add_sample(other, warm)
    with open_store(store_address, create=False, read_only=True) as st:
        assert st.samples(other).joint_temp is None  # not every sample has them
        s = st.samples(rid)
        np.testing.assert_array_equal(s.joint_temp[1], [32.0, 34.0, 30.0])
        np.testing.assert_array_equal(s.quat[0], quat)
        assert np.isnan(s.quat[1]).all() and np.isnan(s.sigma_deg[1])
        assert s.sigma_deg[0] == 0.01 and s.tool_id == ["nest2", None]
        first, second = s.sample(0), s.sample(1)
        np.testing.assert_array_equal(first.joint_temp, [31.5, 33.25, 29.0])
        assert first.tool_id == "nest2" and second.quat is None
        (reading,) = st.readings(rid)
        np.testing.assert_array_equal(reading.sample.quat, -quat)
        np.testing.assert_array_equal(reading.sample.joint_temp, full.joint_temp)
        assert reading.sample.tool_id == "nest2"


def test_calibrations_are_kept_per_robot_in_time_order(store_address):
    with RunStore(store_address) as st:
        a = st.add_calibration("ur10e/A", {"parameters": [{"name": "x", "value": 2}]}, t=20.0,
                               source_file="b.csv")
        b = st.add_calibration("ur10e/A", {"parameters": [{"name": "x", "value": 1}]}, t=10.0,
                               source_file="a.csv", source_run=4)
        again = st.add_calibration("ur10e/A", {"parameters": [{"name": "x", "value": 1}]},
                                   t=30.0)
        st.add_calibration("ur5/B", {"parameters": []}, t=5.0)
        assert a[1] and b[1] and again == (b[0], False)  # the same params: recorded once
        cals = st.calibrations("ur10e/A")
        assert [c.t for c in cals] == [10.0, 20.0]
        assert cals[0].source_file == "a.csv" and cals[0].source_run == 4
        assert cals[0].params == {"parameters": [{"name": "x", "value": 1}]}
        assert cals[0].software.startswith("cellcal")
        assert st.robots() == [("ur10e/A", 2), ("ur5/B", 1)]
        assert st.calibrations("nobody") == []


def test_an_additive_upgrade_in_sqlite_spelling_runs_on_both(store_address):
    """What another helper's upgrade writes (a lease-like table, a new column, inserts that skip
    duplicates, an upsert) runs unchanged on both backends."""
    with RunStore(store_address) as st:
        db = st.db
        with db.transaction(lock=True):
            db.execute("""CREATE TABLE probe_leases (
                id INTEGER PRIMARY KEY AUTOINCREMENT,
                key TEXT NOT NULL UNIQUE, owner_pid INTEGER NOT NULL, heartbeat REAL NOT NULL,
                what TEXT)""")
            db.execute("ALTER TABLE samples ADD COLUMN remeasured INTEGER DEFAULT 0")
        db.execute("INSERT OR IGNORE INTO probe_leases (key, owner_pid, heartbeat) VALUES (?,?,?)",
                   ("run:1", 2**33, 1.5e9 + 0.25))
        cur = db.execute("INSERT OR IGNORE INTO probe_leases (key, owner_pid, heartbeat) "
                         "VALUES (?,?,?)", ("run:1", 7, 0.0))
        assert cur.rowcount == 0
        db.upsert("probe_leases", ["key"], {"key": "run:1", "owner_pid": 9, "heartbeat": 2.5,
                                      "what": "capture 50% done"})
        db.upsert("probe_leases", ["key"], {"key": "run:2", "owner_pid": 10, "heartbeat": 3.0})
        db.executemany("UPDATE probe_leases SET heartbeat=? WHERE key=?", [(4.0, "run:1"),
                                                                   (5.0, "run:2")])
        rows = db.execute("SELECT key, owner_pid, heartbeat, what FROM probe_leases ORDER BY id"
                          ).fetchall()
        assert [tuple(r) for r in rows] == [("run:1", 9, 4.0, "capture 50% done"),
                                            ("run:2", 10, 5.0, None)]
        db.execute("BEGIN IMMEDIATE")  # SQLite code taking the write lock itself
        db.execute("DELETE FROM probe_leases WHERE key=?", ("run:2",))
        db.execute("COMMIT")
        other = st.new_connection()  # e.g. a heartbeat thread's, beside the store's
        try:
            assert other.execute("SELECT count(*) FROM probe_leases").fetchone()[0] == 1
        finally:
            other.close()
        assert "remeasured" in db.columns("samples") and db.has_table("probe_leases")
        rid = st.create_run(make_plan("poses", TOYM, count=2, seed=0))
        st.add_sample(rid, sample(0))  # the store's own SQL still fits the wider table
        assert db.execute("SELECT remeasured FROM samples").fetchone()[0] == 0


def test_translation_to_postgresql():
    assert translate("SELECT a FROM t WHERE b=? AND c LIKE 'x?%'") == \
        "SELECT a FROM t WHERE b=%s AND c LIKE 'x?%%'"
    assert translate("CREATE TABLE t (id INTEGER PRIMARY KEY AUTOINCREMENT, n INTEGER, "
                     "r REAL, b BLOB, s TEXT)") == (
        "CREATE TABLE t (id BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY, n BIGINT, "
        "r DOUBLE PRECISION, b BYTEA, s TEXT)")
    assert translate("ALTER TABLE t ADD COLUMN x REAL") == \
        "ALTER TABLE t ADD COLUMN x DOUBLE PRECISION"
    assert translate("INSERT OR IGNORE INTO t (a) VALUES (?) RETURNING id") == \
        "INSERT INTO t (a) VALUES (%s) ON CONFLICT DO NOTHING RETURNING id"
    assert translate("SELECT 'INTEGER' FROM t") == "SELECT 'INTEGER' FROM t"  # not DDL
    with pytest.raises(StoreError, match="upsert"):
        translate("INSERT OR REPLACE INTO t (a) VALUES (?)")
    assert display_address("postgresql://u:secret@h:5432/db") == "postgresql://u:***@h:5432/db"
    assert display_address("postgresql://u@h/db") == "postgresql://u@h/db"


def test_a_lost_server_connection_is_transient(pg_url, pg_server):
    plan = make_plan("poses", TOYM, count=3, seed=0)
    with RunStore(pg_url) as st:
        rid = st.create_run(plan)
        st.add_sample(rid, sample(0))
        pid = st.con.info.backend_pid
        pg_server.admin(f"SELECT pg_terminate_backend({pid})")
        with pytest.raises(StoreUnavailable, match="connection lost"):
            st.add_sample(rid, sample(1))
        st.reconnect()
        st.add_sample(rid, sample(1))
        assert st.add_sample(rid, sample(1)) is False
        assert st.done_indices(rid) == {0, 1}


@pytest.mark.parametrize("wait_s", [30.0, 0.0])
def test_the_executor_waits_for_a_lost_store_then_pauses(pg_url, pg_server, wait_s):
    """The store's connection is cut when 5 points are stored (in-process simulated cell):
    with time to wait the executor reconnects and commits the held sample; without, the
    run pauses and a resume finishes it. Every point once either way."""
    import sim_drivers.inprocess as inproc
    from daq.executor import Executor
    from daq.run_context import ExecutorOptions
    from drivers.urls import open_robot, open_tracker

    inproc.reset_cells()
    plan = make_plan("poses", TOYM, count=12, seed=4)
    robot = open_robot(toy_sim("robot", 12, "lost"))
    tracker = open_tracker(toy_sim("tracker", 12, "lost"))
    robot.connect()
    tracker.connect()
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.001, store_wait_s=wait_s)
    cut = []

    def progress(done, total, err):
        if done >= 5 and not cut:  # by state: once five samples are stored
            cut.append(st.con.info.backend_pid)
            pg_server.admin(f"SELECT pg_terminate_backend({cut[0]})")

    try:
        with RunStore(pg_url) as st:
            rid = st.create_run(plan)
            status = Executor(st, rid, plan, robot, tracker, opts, progress=progress).run()
            if wait_s == 0:
                assert status == "paused" and "run store unreachable" in st.run(rid).reason
                assert st.n_samples(rid) == 5
                status = Executor(st, rid, plan, robot, tracker, opts).run()
            assert status == "completed"
            s = st.samples(rid)
            kinds = [k for _, _, k, _ in st.interruptions(rid)]
    finally:
        robot.close()
        tracker.close()
        inproc.reset_cells()
    assert s.point_index.tolist() == list(range(12))
    assert kinds == (["store"] if wait_s else ["pause"])

