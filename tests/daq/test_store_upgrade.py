"""A run store written at schema 2 (by commit 5ca46ae: ``data/schema_v2``, built by
``data/make_schema_v2_store.py``) is upgraded in place: its loose options become typed run
contexts, it exports as that version exported, and its paused run resumes. A schema-3
store (the same file taken to 3 by hand) gains the per-sample tracker columns of 4. A
schema-9 store (on both backends) gains the checks table of 10, its calibrations kept."""

from __future__ import annotations

import csv
import json
import shutil
import sqlite3

import numpy as np
import pytest

from calibration.cell.cell import CellSpec, Smr
from cellcal.cli import main
from daq.plans import Plan
from daq.routines.zero20 import ZeroLoopOptions
from daq.run_context import CONTEXT_VERSION, ExecutorOptions
from daq.store import RunStore, Sample
from daq.store.dialect import connect
from daq.store.schema import _V2_EXECUTOR_KEYS, SCHEMA_VERSION, UPGRADES
from sim_drivers.model_truth import model_truth_factory

from .capture_helpers import DATA, served_cell
from .test_store import _at_version

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
        # every executor option as it was stored, none lost; options added since at their
        # defaults
        assert c.executor.model_dump() == {**ExecutorOptions().model_dump(),
                                           **{k: old[r.id][k] for k in _V2_EXECUTOR_KEYS}}
    assert frame.context.frame_run is None and frame.context.tracker_T_base is None
    for r in (steps, zero, poses):
        assert r.context.frame_run == 1
        np.testing.assert_array_equal(r.context.tracker_T_base_matrix, T)
        np.testing.assert_array_equal(r.context.tracker_T_base_matrix[:3, :3],
                                      old[r.id]["tracker_R_base"])
    assert steps.context.seed == 7 and steps.context.executor.speed_rad_s == 0.4
    assert steps.context.executor.dwell_s == 0.01 and steps.context.executor.measure_s == 0.05
    # the zero-point loop's options became zero20's acquisition options; others have none
    # (approach_rad came after schema 3: a schema-2 run records none, the default applies)
    assert ZeroLoopOptions(**zero.context.acquire) == ZeroLoopOptions(tol_mm=0.02, average=2)
    assert frame.context.acquire == steps.context.acquire == poses.context.acquire == {}
    with RunStore(v2_db) as st:  # reopened: already current, nothing to do
        assert st.run(3).context == zero.context


def _columns(text: str) -> dict[str, list[str]]:
    """A CSV's columns by name (as text)."""
    rows = list(csv.reader(ln for ln in text.splitlines() if not ln.startswith("#")))
    return {h: [r[k] for r in rows[1:]] for k, h in enumerate(rows[0])}


def _split(text: str) -> tuple[dict, list[str]]:
    """(``# key: value`` metadata, the other lines) of a CSV."""
    meta = dict(line[2:].split(": ", 1) for line in text.splitlines() if line.startswith("# "))
    return meta, [line for line in text.splitlines() if not line.startswith("#")]


def _exported_as_before(new: str, old: str) -> None:
    """The same rows, and every metadata line of before with its value (new lines, the
    run's capture context, extend the header: docs/formats.md §1)."""
    meta_new, rows_new = _split(new)
    meta_old, rows_old = _split(old)
    assert rows_new == rows_old
    assert {k: meta_new.get(k) for k in meta_old} == meta_old


def test_upgraded_store_exports_as_schema_2_did(v2_db, tmp_path, capsys):
    for run in (1, 2, 3, 4):
        out = tmp_path / f"run{run}.csv"
        assert main(["export", str(run), "--db", str(v2_db), "--out", str(out)]) == 0
        text, old = out.read_text(), (V2 / f"run{run}.csv").read_text()
        cols, cols2 = _columns(text), _columns(old)
        # every column as schema 2 exported it, plus the air schema 2 stored but did not
        # export (docs/formats.md §1 optional columns); no reflector or face: not recorded then
        assert {k: cols[k] for k in cols2} == cols2, run
        assert set(cols) - set(cols2) == {"pressure_hpa", "humidity_pct"}
        assert set(cols["pressure_hpa"]) == {"1013.25"}
        # every metadata line of before with its value; the run's capture context extends
        # the header (docs/formats.md §1)
        meta, meta2 = _split(text)[0], _split(old)[0]
        assert {k: meta.get(k) for k in meta2} == meta2, run
        assert meta["tool_mm"] == "0, 0, 60" and meta["store"] == str(v2_db)
        assert ("tracker_T_base" in meta) == (run != 1)  # run 1 is the frame run
    out = tmp_path / "postures3.csv"  # tips in the base frame: the context's tracker_T_base
    assert main(["export", "3", "--postures", "--db", str(v2_db), "--out", str(out)]) == 0
    _exported_as_before(out.read_text(), (V2 / "postures3.csv").read_text())
    capsys.readouterr()
    assert main(["runs", "--db", str(v2_db), "--json"]) == 0
    runs = json.loads(capsys.readouterr().out)
    # schema 6 added the re-measure counts (nothing judged, nothing re-measured)
    assert all(r.pop("remeasure") == {"judged": 0, "warmup": 0, "suspects": 0,
                                      "remeasurements": 0, "rejected": 0,
                                      "model_disagrees": 0, "unresolved": 0} for r in runs)
    # schema 7 added who the robot is: unknown here
    assert runs == [{**r, "robot_id": None} for r in json.loads((V2 / "runs.json").read_text())]


def test_paused_schema_2_run_resumes_with_its_context(v2_db, capsys):
    # the fixture's poses were drawn before plans knew the tracker's line of sight: a
    # 360-degree reflector sees them from where the simulated tracker stands
    with served_cell(model_truth_factory, seed=5, cell=CellSpec(smr=Smr(reflector="360"))) \
            as stack:
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


@pytest.fixture
def v3_db(v2_db):
    """The schema-2 fixture taken to schema 3 by its own upgrade (what schema 3 wrote)."""
    con = sqlite3.connect(v2_db, isolation_level=None)
    try:
        con.execute("BEGIN")
        UPGRADES[2](con)
        con.execute("PRAGMA user_version=3")
        con.execute("COMMIT")
    finally:
        con.close()
    return v2_db


def test_schema_3_gains_reflector_face_and_covariance(v3_db, tmp_path):
    con = sqlite3.connect(v3_db)
    before = con.execute("SELECT * FROM samples ORDER BY id").fetchall()
    n_cols = len(before[0])
    con.close()
    with RunStore(v3_db) as st:
        assert st.version == SCHEMA_VERSION
        s = st.samples(2)
        assert s.reflector == [None] * len(s) and np.all(s.face == 0)
        assert np.all(np.isnan(s.cov_mm2))
        cov = np.array([[4e-4, 1e-5, -2e-5], [1e-5, 3e-4, 0.0], [-2e-5, 0.0, 5e-4]])
        new = Sample(point_index=99, q=np.zeros(6), tracker_p_smr=np.ones(3),
                     std_mm=np.sqrt(np.diag(cov)), n_averaged=1, t_s=1.0, reflector="RRR 1.5in",
                     face=2, cov_mm2=cov)
        assert st.add_sample(2, new)
        s = st.samples(2)
    assert s.reflector[-1] == "RRR 1.5in" and s.face[-1] == 2
    np.testing.assert_array_equal(s.cov_mm2[-1], cov)
    con = sqlite3.connect(v3_db)
    cols = [c[1] for c in con.execute("PRAGMA table_info(samples)")]
    after = con.execute("SELECT * FROM samples ORDER BY id").fetchall()
    con.close()
    v4 = ["reflector", "face", "cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"]
    assert cols[n_cols:n_cols + len(v4)] == v4
    # the old rows are untouched, their new columns NULL (6's remeasures: 0)
    assert [r[:n_cols] for r in after[:len(before)]] == before
    assert all(v is None for r in after[:len(before)] for v in r[n_cols:n_cols + len(v4)])


def test_a_schema_9_store_gains_the_checks_table_and_keeps_its_calibrations(store_address):
    """v10 is additive: the calibrations recorded before it stay as they were, and a check
    of one links to it."""
    _at_version(store_address, 9)
    params = {"parameters": [{"name": "x", "value": 1.5}], "effects": ["base"]}
    db = connect(store_address)
    try:
        with db.transaction():
            db.execute("INSERT INTO calibrations (robot_id, t, recorded, params_json, "
                       "params_sha256, software) VALUES (?,?,?,?,?,?)",
                       ("R1", 10.0, 11.0, json.dumps(params, sort_keys=True),
                        RunStore.params_digest(params), "cellcal 0.0.9"))
    finally:
        db.close()
    result = {"n": 12, "rms_mm": 0.03, "mean_mm": 0.02, "p95_mm": 0.05, "max_mm": 0.06,
              "tolerance_mm": 0.05, "within_tolerance": True, "refitted": []}
    with RunStore(store_address) as st:
        assert st.version == SCHEMA_VERSION
        (cal,) = st.calibrations("R1")
        assert (cal.t, cal.params, cal.software) == (10.0, params, "cellcal 0.0.9")
        assert st.checks("R1") == []
        check_id, new, cal_id = st.add_check("R1", params, result, t=20.0, source_file="a.csv")
        assert new and cal_id == cal.id
        assert st.add_check("R1", params, result, t=30.0) == (check_id, False, cal.id)
        other = st.add_check("R1", {"parameters": []}, {**result, "within_tolerance": False,
                                                        "refitted": ["base"]})
        assert other[1] and other[2] is None  # parameters no calibration of R1 was
        c, d = st.checks("R1")
        assert (c.id, c.t, c.n, c.rms_mm, c.within_tolerance, c.refitted, c.source_file) == \
            (check_id, 20.0, 12, 0.03, True, (), "a.csv")
        assert c.result == result and c.software.startswith("cellcal")
        assert d.within_tolerance is False and d.refitted == ("base",)
        assert st.checked_robots() == [("R1", 2)] and st.checks("R2") == []
