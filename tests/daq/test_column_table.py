"""The column table (calibration.data.columns) on the store's side: it names every column of the
``samples`` and ``readings`` tables with its SQL type and the schema version that added it,
the store's records (Sample, Samples) have exactly its fields, and a point with every
quantity set keeps each one from capture to store to export to CSV to Dataset, on both
backends (``store_address``, tests/conftest.py)."""

from __future__ import annotations

import sqlite3
from dataclasses import fields

import numpy as np
import pytest

from calibration import load_csv, load_model
from calibration.data.columns import (
    COLUMNS,
    READING_COLUMNS,
    RECORD,
    SAMPLE_COLUMNS,
    column,
    store_columns,
)
from cellcal.cli import main
from daq.routines import make_plan
from daq.run_context import RunContext
from daq.store import Reading, RunStore, Sample, Samples, open_store
from daq.store.schema import SCHEMA_V1, SCHEMA_VERSION, UPGRADES

from .capture_helpers import TOY

TOYM = load_model(TOY)
#: the tables' own keys and a rejected reading's reason: not per-point quantities
KEYS = {"samples": {"id", "run_id"}, "readings": {"id", "run_id", "reason"}}


def _schema_at(version: int) -> dict[str, dict[str, str]]:
    """{table: {column: SQL type}} of the samples and readings tables at ``version``."""
    con = sqlite3.connect(":memory:", isolation_level=None)
    con.executescript(SCHEMA_V1)
    for v in range(1, version):
        UPGRADES[v](con)
    out = {t: {r[1]: r[2] for r in con.execute(f"PRAGMA table_info({t})")}
           for t in ("samples", "readings")}
    con.close()
    return out


@pytest.mark.parametrize("version", range(1, SCHEMA_VERSION + 1))
def test_the_table_names_every_store_column_of_every_schema(version):
    schema = _schema_at(version)
    for table, entries in (("samples", SAMPLE_COLUMNS), ("readings", READING_COLUMNS)):
        have = {c: t for c, t in schema[table].items() if c not in KEYS[table]}
        if not have:
            continue  # no readings table before schema 6
        want = {s: c.kind.sql for c in entries if c.since <= version for s in c.store}
        if table == "readings":
            want["point_index"] = "INTEGER"
        assert have == want, table


def test_every_store_column_is_a_record_field_and_the_records_have_no_other():
    assert all(c.record for c in COLUMNS if c.store)
    names = {c.name for c in RECORD}
    assert {f.name for f in fields(Sample)} == names
    assert {f.name for f in fields(Samples)} == names
    cols = store_columns(SAMPLE_COLUMNS)
    assert len(cols) == len(set(cols))  # one quantity per store column


def _every_column(i: int, set_name: str) -> Sample:
    """Point ``i`` with every quantity the store keeps set."""
    rng = np.random.default_rng(i)
    quat = rng.normal(size=4)
    cov = np.diag(rng.uniform(1e-4, 4e-4, 3)) + 1e-5
    return Sample(
        point_index=i, q=np.radians(rng.uniform(-170, 170, 3)),
        tracker_p_smr=rng.normal(0, 500, 3), std_mm=rng.uniform(0.005, 0.02, 3),
        n_averaged=int(rng.integers(1, 600)), t_s=1.7e9 + 10.0 * i + 0.123456,
        pose_id=f"p{i}", set_name=set_name, target={"index": i, "info": {"k": i}},
        temp_c=20.0 + i / 8, pressure_hpa=1013.25 - i, humidity_pct=40.0 + i,
        cmd=rng.normal(0, 500, 3), dirs=rng.integers(-1, 2, 3), attempts=2,
        joints_t=1.7e9 + 10.0 * i, reflector=f"RRR {i}", face=1 + i % 2, cov_mm2=cov,
        verdict="ok", remeasures=1, model_residual_mm=0.01 * i, model_threshold_mm=0.09,
        joint_temp=rng.uniform(20, 40, 3), quat=quat / np.linalg.norm(quat),
        sigma_deg=0.01 + i / 1000, tool_id=f"nest{i % 2}")


def _equal(a, b, what) -> None:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        np.testing.assert_array_equal(a, b, err_msg=what)
    else:
        assert a == b, what


def test_every_column_survives_capture_store_export_csv_dataset(store_address, tmp_path):
    plan = make_plan("poses", TOYM, count=6, seed=0)
    points = [_every_column(i, s) for i, s in
              enumerate(["calib", "valid", "drift", "calib", "calib", "valid"])]
    rejected = _every_column(7, "calib")
    rejected.point_index, rejected.t_s = 0, points[0].t_s - 1.0
    with RunStore(store_address) as st:
        rid = st.create_run(plan, RunContext(routine="poses", model=TOY))
        st.add_sample(rid, points[0], [Reading(rejected, "2 mm from the model")])
        for p in points[1:]:
            st.add_sample(rid, p)
    with open_store(store_address, create=False, read_only=True) as st:
        s = st.samples(rid)
        (reading,) = st.readings(rid)
    stacked = Samples.from_records(points)  # the columns, stacked from the records
    for c in RECORD:  # the store keeps every field of the record
        _equal(getattr(s, c.name), getattr(stacked, c.name), c.name)
        for i, p in enumerate(points):
            _equal(getattr(s.sample(i), c.name), getattr(p, c.name), f"{c.name} of {i}")
    for c in READING_COLUMNS:  # and every measured field of a rejected reading
        _equal(getattr(reading.sample, c.name), getattr(rejected, c.name), c.name)
    assert reading.sample.pose_id == "p0" and reading.reason == "2 mm from the model"

    out = tmp_path / "run.csv"
    assert main(["export", str(rid), "--db", store_address, "--out", str(out)]) == 0
    d = load_csv(out, TOYM)
    for c in RECORD:
        if not c.dataset or c.name in ("pose_id", "set_name"):
            continue
        want = c.gather([getattr(p, c.name) for p in points])[c.name]
        got = getattr(d, c.name)
        if c.name == "q":
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-14, err_msg=c.name)
        elif c.name == "quat":
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-15, err_msg=c.name)
        else:
            _equal(np.asarray(got), np.asarray(want), c.name)
    assert d.pose_id == [p.pose_id for p in points]
    assert d.is_valid.tolist() == [p.set_name == "valid" for p in points]
    assert d.is_drift.tolist() == [p.set_name == "drift" for p in points]
    np.testing.assert_allclose(d.sigma_mm, [np.sqrt(np.mean(p.std_mm ** 2)) for p in points],
                               rtol=1e-15)
    # every column the export wrote is one of the table's
    header = next(ln for ln in out.read_text().splitlines() if not ln.startswith("#"))
    assert header.split(",") == [n for c in COLUMNS if c.dataset and c.name != "payload_kg"
                                 for n in c.csv_names(3)]

    every = tmp_path / "every.csv"
    assert main(["export", str(rid), "--db", store_address, "--out", str(every),
                 "--all-readings"]) == 0
    header = next(ln for ln in every.read_text().splitlines() if not ln.startswith("#"))
    assert header.split(",")[-2:] == [*column("reading").csv, *column("reason").csv]
    again = load_csv(every, TOYM)  # the rejected reading is left out
    np.testing.assert_array_equal(again.tracker_p_smr, d.tracker_p_smr)
