"""The run store against files that are not (or no longer) stores, read-only opening, and a
disk that fills during a capture: refused in one line, nothing written to what is not
ours, nothing lost."""

from __future__ import annotations

import hashlib
import shutil
import sqlite3
from pathlib import Path

import pytest

import sim_drivers.inprocess as inproc
from calibration import load_model
from daq.routines import make_plan
from daq.run_context import ExecutorOptions, RunContext
from daq.store import RunStore, StoreError
from daq.store.schema import SCHEMA_VERSION
from drivers.urls import open_robot, open_tracker

from .capture_helpers import DATA, TOY, run_plan

V2 = DATA / "schema_v2" / "cell.db"


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _current_store(tmp_path) -> Path:
    p = tmp_path / "cell.db"
    shutil.copyfile(V2, p)
    RunStore(p).close()
    for side in ("-wal", "-shm"):
        Path(f"{p}{side}").unlink(missing_ok=True)
    return p


def test_read_only_open_changes_nothing_and_reads_an_old_schema_in_memory(tmp_path):
    cur = _current_store(tmp_path)
    old = tmp_path / "v2.db"
    shutil.copyfile(V2, old)
    before = {p: _sha(p) for p in (cur, old)}
    for p in (cur, old):
        with RunStore.open_existing(p, read_only=True) as st:
            assert st.version == SCHEMA_VERSION
            assert [r.routine for r in st.runs()] == ["frame", "steps", "zero20", "poses"]
            assert len(st.samples(3)) == 20
    assert {p: _sha(p) for p in (cur, old)} == before
    assert sorted(f.name for f in tmp_path.iterdir()) == ["cell.db", "v2.db"]  # no -wal/-shm


def test_read_only_open_sees_the_commits_of_a_writer(tmp_path):
    cur = _current_store(tmp_path)
    with RunStore(cur) as writer:
        writer.set_status(1, "failed", "seen by the reader")
        with RunStore.open_existing(cur, read_only=True) as reader:
            assert reader.run(1).reason == "seen by the reader"


def _foreign(p: Path) -> None:
    con = sqlite3.connect(p)
    con.execute("CREATE TABLE invoices (id INTEGER PRIMARY KEY, total REAL)")
    con.commit()
    con.close()


@pytest.mark.parametrize("read_only", [False, True])
def test_a_foreign_sqlite_file_is_refused_and_left_alone(tmp_path, read_only):
    p = tmp_path / "accounts.db"
    _foreign(p)
    before = _sha(p)
    with pytest.raises(StoreError, match="not a cellcal run store.*invoices"):
        RunStore(p, read_only=read_only)
    assert _sha(p) == before
    assert sorted(f.name for f in tmp_path.iterdir()) == ["accounts.db"]


def test_a_newer_store_is_refused_before_the_wal_switch(tmp_path):
    p = tmp_path / "new.db"
    con = sqlite3.connect(p)
    con.executescript("CREATE TABLE runs (id INTEGER); CREATE TABLE samples (id INTEGER);")
    con.execute(f"PRAGMA user_version={SCHEMA_VERSION + 1}")
    con.commit()
    con.close()
    before = _sha(p)
    for ro in (False, True):
        with pytest.raises(StoreError, match="newer"):
            RunStore(p, read_only=ro)
    assert _sha(p) == before  # still a rollback-journal file: nothing was switched


@pytest.mark.parametrize("make, message", [
    (lambda p: p.write_text("hello\n"), "not an SQLite database"),
    (lambda p: p.write_bytes(b""), "empty file"),
    (lambda p: p.mkdir(), "is a directory"),
    (lambda p: p.write_bytes(V2.read_bytes()[:20000]), "truncated"),
    (lambda p: p.write_bytes(V2.read_bytes()[:50]), "truncated"),
])
def test_what_is_not_a_store_is_refused_in_one_line(tmp_path, make, message):
    p = tmp_path / "x.db"
    make(p)
    with pytest.raises(StoreError, match=message) as e:
        RunStore.open_existing(p, read_only=True)
    assert "\n" not in str(e.value) and str(p) in str(e.value)


def test_missing_folder_and_file(tmp_path):
    with pytest.raises(StoreError, match="folder .* does not exist"):
        RunStore(tmp_path / "no" / "cell.db")
    with pytest.raises(StoreError, match="no such run store"):
        RunStore.open_existing(tmp_path / "cell.db")
    assert not (tmp_path / "cell.db").exists()


def test_a_full_disk_pauses_the_run_with_the_reason_and_loses_nothing(tmp_path):
    """The store's file may not grow past a few pages (SQLite's max_page_count: the same
    SQLITE_FULL a full disk gives). The commit fails by state, at whichever point reaches
    the limit: the run is paused with the reason, the samples stored stay, and once space
    is freed `resume` completes the run without a gap or a duplicate."""
    toy = load_model(TOY)
    inproc.reset_cells()
    plan = make_plan("poses", toy, count=80, seed=6)
    robot = open_robot(f"sim://robot?model={TOY}&seed=14&name=full&reflector=360")
    tracker = open_tracker(f"sim://tracker?model={TOY}&seed=14&name=full&reflector=360")
    robot.connect()
    tracker.connect()
    opts = ExecutorOptions(measure_s=0.01, backoff_s=0.0)
    try:
        with RunStore(tmp_path / "c.db") as st:
            rid = st.create_run(plan, RunContext(routine="poses"))
            pages = st.con.execute("PRAGMA page_count").fetchone()[0]
            st.con.execute(f"PRAGMA max_page_count={pages + 2}")
            _, status = run_plan(st, plan, robot, tracker, options=opts, run_id=rid)
            r = st.run(rid)
            assert status == "paused" and r.status == "paused"
            assert "could not be written" in r.reason and "full" in r.reason
            n = st.n_samples(rid)
            assert 0 < n < len(plan)
            st.con.execute("PRAGMA max_page_count=1073741823")  # space freed
            _, status = run_plan(st, plan, robot, tracker, options=opts, run_id=rid)
            assert status == "completed"
            s = st.samples(rid)
            assert s.point_index.tolist() == list(range(len(plan)))
    finally:
        robot.close()
        tracker.close()
        inproc.reset_cells()


def test_an_upgrade_adds_the_reserve_and_keeps_every_run(tmp_path):
    """Schema 8 is additive: a schema-3 store upgraded to today gains the reserve table
    (one row of RESERVE_BYTES zeros); runs and samples stay as they were."""
    from daq.store.schema import RESERVE_BYTES, UPGRADES

    p = tmp_path / "v3.db"
    shutil.copyfile(V2, p)
    con = sqlite3.connect(p, isolation_level=None)
    UPGRADES[2](con)  # 2 -> 3, as a schema-3 cellcal left it
    con.execute("PRAGMA user_version=3")
    before = con.execute("SELECT id, routine, status, plan_hash FROM runs").fetchall()
    n_samples = con.execute("SELECT count(*) FROM samples").fetchone()[0]
    con.close()
    with RunStore(p) as st:
        assert st.version == SCHEMA_VERSION
        assert st.con.execute("SELECT id, routine, status, plan_hash FROM runs"
                              ).fetchall() == before
        assert st.con.execute("SELECT count(*) FROM samples").fetchone()[0] == n_samples
        assert st.con.execute("SELECT length(pad) FROM reserve").fetchall() == [
            (RESERVE_BYTES,)]
        assert st.release_reserve() and not st.release_reserve()
    with RunStore(p) as st:  # given up, it is put back once there is space again
        assert st.con.execute("SELECT count(*) FROM reserve").fetchone()[0] == 1
