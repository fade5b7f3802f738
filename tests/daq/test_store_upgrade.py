"""A run store written at schema 2 (by commit 5ca46ae: ``data/schema_v2``, built by
``data/make_schema_v2_store.py``) is upgraded in place: its loose options become typed run
contexts, it exports as that version exported, and its paused run resumes."""

from __future__ import annotations

import json
import shutil
import sqlite3

import numpy as np
import pytest

from daq.cli import main
from daq.plans import Plan
from daq.routines.zero20 import ZeroLoopOptions
from daq.run_context import CONTEXT_VERSION, ExecutorOptions
from daq.store import RunStore
from daq.store_schema import _V2_EXECUTOR_KEYS, SCHEMA_VERSION
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import DATA, served_cell

V2 = DATA / "schema_v2"


@pytest.fixture
def v2_db(tmp_path):
    db = tmp_path / "cell.db"
    shutil.copy(V2 / "cell.db", db)  # the fixture itself is never written
    return db


def _v2_options(db) -> dict[int, dict]:
    con = sqlite3.connect(db)
    try:
        assert con.execute("PRAGMA user_version").fetchone()[0] == 2
        return {rid: json.loads(o) for rid, o in con.execute("SELECT id, options_json FROM runs")}
    finally:
        con.close()


def test_upgrade_turns_the_options_into_typed_contexts(v2_db):
    old = _v2_options(v2_db)
    with RunStore(v2_db) as st:
        assert st.version == SCHEMA_VERSION
        frame, steps, zero, poses = st.runs()
        for r in (frame, steps, zero, poses):
            assert Plan.from_json(r.plan_json).hash == r.plan_hash  # plans load unchanged
    con = sqlite3.connect(v2_db)
    cols = [c[1] for c in con.execute("PRAGMA table_info(runs)")]
    con.close()
    assert "context_json" in cols and "options_json" not in cols
    T = frame.frame["tracker_T_base"]
    for r in (frame, steps, zero, poses):
        c = r.context
        assert c.version == CONTEXT_VERSION and c.routine == r.routine
        assert c.model == "ur10e" and c.tool_mm == (0.0, 0.0, 60.0)
        assert c.robot_url == r.robot_url and c.robot_url.startswith("socket://127.0.0.1:")
        assert c.tracker_url.startswith("tracker+tcp://127.0.0.1:")
        # every executor option as it was stored, none lost
        dumped = c.executor.model_dump()
        assert {k: dumped[k] for k in _V2_EXECUTOR_KEYS} == {
            k: old[r.id][k] for k in _V2_EXECUTOR_KEYS}
        assert dumped == ExecutorOptions(**{k: old[r.id][k] for k in _V2_EXECUTOR_KEYS}
                                         ).model_dump()  # options added since: defaults
    assert frame.context.frame_run is None and frame.context.tracker_T_base is None
    for r in (steps, zero, poses):
        assert r.context.frame_run == 1
        np.testing.assert_array_equal(r.context.tracker_T_base_matrix, T)
        np.testing.assert_array_equal(r.context.tracker_T_base_matrix[:3, :3],
                                      old[r.id]["tracker_R_base"])
    assert steps.context.seed == 7 and steps.context.executor.speed_rad_s == 0.4
    assert steps.context.executor.dwell_s == 0.01 and steps.context.executor.measure_s == 0.05
    # the zero-point loop's options became zero20's acquisition options; others have none
    assert zero.context.acquire == ZeroLoopOptions(tol_mm=0.02, average=2).model_dump()
    assert frame.context.acquire == steps.context.acquire == poses.context.acquire == {}
    with RunStore(v2_db) as st:  # reopened: already current, nothing to do
        assert st.run(3).context == zero.context


def test_upgraded_store_exports_as_schema_2_did(v2_db, tmp_path, capsys):
    for run in (1, 2, 3, 4):
        out = tmp_path / f"run{run}.csv"
        assert main(["export", str(run), "--db", str(v2_db), "--out", str(out)]) == 0
        assert out.read_text() == (V2 / f"run{run}.csv").read_text(), run
    out = tmp_path / "postures3.csv"  # tips in the base frame: the context's tracker_T_base
    assert main(["export", "3", "--postures", "--db", str(v2_db), "--out", str(out)]) == 0
    assert out.read_text() == (V2 / "postures3.csv").read_text()
    capsys.readouterr()
    assert main(["runs", "--db", str(v2_db), "--json"]) == 0
    expected = [{**r, "robot_id": None}  # schema 4 added who the robot is: unknown here
                for r in json.loads((V2 / "runs.json").read_text())]
    assert json.loads(capsys.readouterr().out) == expected


def test_paused_schema_2_run_resumes_with_its_context(v2_db, capsys):
    with served_cell(model_truth_factory, seed=5) as stack:
        robot, tracker = stack.urls[1], stack.urls[2]
        rc = main(["resume", "4", "--db", str(v2_db), "--robot", robot, "--tracker", tracker,
                   "--json"])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["status"] == "completed" and out["samples"] == 6
    with RunStore(v2_db) as st:
        r = st.run(4)
        s = st.samples(4)
        kinds = [k for _, _, k, _ in st.interruptions(4)]
    assert s.point_index.tolist() == list(range(6))
    assert r.context.robot_url == r.robot_url == robot  # the new URLs are stored
    assert r.tracker_url == tracker
    assert r.context.executor.measure_s == 0.05
    assert kinds[-1] == "resume" and "protective_stop" in kinds
