"""The column table (calibration.data.columns) covers every per-point field of the Dataset and
every column of the measurement CSV (docs/formats.md §1): a quantity added in one place
only fails here. The store's side is checked in tests/daq/test_column_table.py."""

from __future__ import annotations

import re
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from calibration import Dataset, load_csv, load_model
from calibration.data.columns import BY_NAME, COLUMNS, CSV_READ, column

ROOT = Path(__file__).resolve().parents[2]
UR = load_model("ur10e")


def _documented_csv_columns() -> set[str]:
    """The column names of docs/formats.md §1's table (``q1`` … ``qN`` as ``q{j}``)."""
    text = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
    section = text[text.index("## 1. Measurement CSV"):text.index("### Capture metadata")]
    out = set()
    for line in section.splitlines():
        if not line.startswith("| `"):
            continue
        first = line.split("|")[1]
        for name in re.findall(r"`([^`]+)`", first):
            out.add(re.sub(r"(\D)(1|N)$", r"\1{j}", name))
    return out


def full_dataset(n: int = 5, seed: int = 0) -> Dataset:
    """A Dataset with every per-point field the CSV carries (calibration, validation and
    drift rows), values within every reader's checks."""
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=(n, 4))
    return Dataset(
        q=np.radians(rng.uniform(-170, 170, (n, 6))), tracker_p_smr=rng.normal(0, 900, (n, 3)),
        pose_id=[f"p{i}" for i in range(n)], cmd=rng.normal(0, 900, (n, 3)),
        temp_c=rng.uniform(18, 24, n), t_s=1.7e9 + np.arange(n) * 3.25,
        payload_kg=rng.uniform(0, 10, n), sigma_mm=rng.uniform(0.01, 0.02, n),
        pressure_hpa=rng.uniform(990, 1020, n), humidity_pct=rng.uniform(30, 60, n),
        reflector=["RRR 1.5in", "CatsEye 3in, glass", *["RRR 1.5in"] * (n - 2)],
        face=rng.integers(1, 3, n), dirs=rng.integers(-1, 2, (n, 6)),
        is_valid=np.arange(n) % 3 == 1, is_drift=np.arange(n) % 3 == 2,
        joint_temp=rng.uniform(20, 40, (n, 6)),
        quat=quat / np.linalg.norm(quat, axis=1, keepdims=True),
        sigma_deg=rng.uniform(0.005, 0.02, n), tool_id=[f"nest{i % 2}" for i in range(n)],
        meta={"tracker_sigma_mm": "0.015"})


def assert_same_columns(got: Dataset, want: Dataset, names) -> None:
    """Every Dataset field of ``names`` (table entries) equal in ``got`` and ``want``."""
    for name in names:
        for f in column(name).dataset:
            a, b = getattr(got, f), getattr(want, f)
            assert (a is None) == (b is None), f
            if a is None:
                continue
            if f == "q":
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-14, err_msg=f)
            elif f == "quat":  # normalised again when read
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-15, err_msg=f)
            else:
                np.testing.assert_array_equal(np.asarray(a), np.asarray(b), err_msg=f)


def test_every_per_point_field_of_the_dataset_is_in_the_table():
    in_table = {f for c in COLUMNS for f in c.dataset}
    assert set(Dataset.per_point_fields()) == in_table
    others = {f.name for f in fields(Dataset)} - in_table
    assert others == {"meta", "source"}  # one per data set, not per point


def test_every_csv_column_is_in_the_table():
    in_table = {name for c in COLUMNS for name in c.csv}
    assert _documented_csv_columns() == in_table
    assert len(BY_NAME) == len(COLUMNS)  # one entry per name
    csv_names = [name for c in COLUMNS for name in c.csv]
    assert len(csv_names) == len(set(csv_names))  # one quantity per CSV column


def test_a_name_that_differs_says_why():
    for c in COLUMNS:
        names = {c.name, *c.dataset, *c.csv, *c.store} - {""}
        if names != {c.name} or not (c.csv and c.dataset):
            assert c.reason, f"{c.name}: {sorted(names)}"


def test_the_csv_writes_every_column_in_the_table_order_and_reads_it_back(tmp_path):
    d = full_dataset()
    p = tmp_path / "all.csv"
    d.to_csv(p)
    header = next(ln for ln in p.read_text().splitlines() if not ln.startswith("#"))
    written = [n for c in COLUMNS if c.name not in ("reading", "reason")
               for n in c.csv_names(6)]
    assert header.split(",") == written
    back = load_csv(p, UR)
    assert_same_columns(back, d, [c.name for c in CSV_READ])
    assert back.lines.tolist() == list(range(3, 3 + d.n))


def test_subset_and_concat_keep_every_per_point_field():
    d = full_dataset(6)
    s = d.subset(np.array([5, 1, 3]))  # a drift, a validation, a calibration row
    for f in Dataset.per_point_fields():
        v = getattr(d, f)
        want = [v[5], v[1], v[3]] if isinstance(v, list) else v[[5, 1, 3]]
        np.testing.assert_array_equal(np.asarray(getattr(s, f)), np.asarray(want), err_msg=f)
    both = s.concat(d)
    for f in Dataset.per_point_fields():
        a, b = getattr(s, f), getattr(d, f)
        want = a + b if isinstance(a, list) else np.concatenate([a, b])
        np.testing.assert_array_equal(np.asarray(getattr(both, f)), np.asarray(want),
                                      err_msg=f)
    # a column one side lacks is dropped; a missing drift mask reads as "no drift rows"
    bare = Dataset(q=d.q[:2], tracker_p_smr=d.tracker_p_smr[:2])
    mixed = d.concat(bare)
    assert mixed.joint_temp is None and mixed.quat is None and mixed.n == 8
    assert mixed.is_drift.tolist() == d.is_drift.tolist() + [False, False]
    assert bare.concat(bare).is_drift is None


def test_unknown_column_names_the_known_ones():
    with pytest.raises(KeyError, match="no per-point column 'nope'; known: point_index"):
        column("nope")
