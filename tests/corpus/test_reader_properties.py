"""Property-based tests of the readers: whatever the bytes, a reader returns valid data
or raises its own one-line error (DataError, ModelError, ParamsError), never anything
else; what it returns is finite. Derandomized, so every run tries the same examples."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calibration import DataError, ErrorModel, ModelError, load_csv, load_model
from calibration.compensation.compensation import load_targets
from calibration.exports.params_io import ParamsError, params_from_doc, read_params
from calibration.fit.simulate import random_joints, realistic_truth, simulate
from calibration.zero_point import load_postures

SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])
UR5 = load_model("ur5")


def _one_line(e: Exception) -> None:
    assert "\n" not in str(e), str(e)
    assert str(e)


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    folder = tmp_path_factory.mktemp("props")
    em = ErrorModel(UR5)
    rng = np.random.default_rng(5)
    data = simulate(em, realistic_truth(em, rng), random_joints(UR5, 12, rng), 0.01, rng)
    csv_text = data.to_csv()
    from calibration import identify
    from calibration.exports.params_io import fit_to_dict

    data40 = simulate(em, realistic_truth(em, rng), random_joints(UR5, 40, rng), 0.01, rng)
    params = fit_to_dict(identify(em, data40))
    return folder, csv_text, json.loads(json.dumps(params, default=float))


def _write(folder: Path, name: str, data: bytes) -> Path:
    p = folder / name
    p.write_bytes(data)
    return p


# --------------------------------------------------------------------------- CSV
def _check_dataset(d) -> None:
    assert np.isfinite(d.q).all() and np.isfinite(d.tracker_p_smr).all()
    assert len(d.pose_id) == d.n == len(set(d.pose_id))


@SETTINGS
@given(raw=st.binary(max_size=600))
def test_csv_reader_on_arbitrary_bytes(good, raw):
    folder = good[0]
    path = _write(folder, "raw.csv", raw)
    for read in (lambda: load_csv(path, UR5), lambda: load_targets(path, UR5),
                 lambda: load_postures(path, UR5)):
        try:
            out = read()
        except DataError as e:
            _one_line(e)
        else:
            if hasattr(out, "tracker_p_smr"):
                _check_dataset(out)


_FIELD = st.one_of(
    st.text(max_size=12),
    st.sampled_from(["nan", "NaN", "inf", "-inf", "1e999", "1e300", "", " ", "0x10", "1,5",
                     "true", "-0", "1e-320", "９", "١"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)


@SETTINGS
@given(data=st.data())
def test_csv_reader_on_damaged_good_files(good, data):
    """A good file with fields replaced, lines dropped or separators changed."""
    folder, text, _ = good
    lines = text.splitlines()
    header_at = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    action = data.draw(st.sampled_from(["field", "drop", "dup", "sep", "header"]))
    if action == "field":
        i = data.draw(st.integers(header_at + 1, len(lines) - 1))
        fields = lines[i].split(",")
        k = data.draw(st.integers(0, len(fields) - 1))
        fields[k] = data.draw(_FIELD).replace("\n", " ")
        lines[i] = ",".join(fields)
    elif action == "drop":
        del lines[data.draw(st.integers(0, len(lines) - 1))]
    elif action == "dup":
        i = data.draw(st.integers(0, len(lines) - 1))
        lines.insert(i, lines[i])
    elif action == "sep":
        lines = [ln.replace(",", data.draw(st.sampled_from([";", "\t", " ", ",,"])))
                 for ln in lines]
    else:
        fields = lines[header_at].split(",")
        k = data.draw(st.integers(0, len(fields) - 1))
        fields[k] = data.draw(st.sampled_from(["", "q7", "X", "q1", "set", "dir1", "sigma_mm",
                                               "payload_kg", "temp_c", "cmd_x"]))
        lines[header_at] = ",".join(fields)
    path = _write(folder, "damaged.csv", ("\n".join(lines) + "\n").encode())
    try:
        d = load_csv(path, UR5)
    except DataError as e:
        _one_line(e)
    else:
        _check_dataset(d)


@SETTINGS
@given(q=st.lists(st.lists(st.floats(-359, 359), min_size=6, max_size=6), min_size=1,
                  max_size=8),
       xyz=st.lists(st.floats(-9e5, 9e5), min_size=3, max_size=3))
def test_csv_round_trip(good, q, xyz):
    from calibration import Dataset

    q = np.radians(np.array(q))
    d = Dataset(q=q, tracker_p_smr=np.tile(xyz, (len(q), 1)))
    path = folder_file = good[0] / "rt.csv"
    d.to_csv(folder_file)
    back = load_csv(path, UR5)
    np.testing.assert_allclose(back.q, d.q, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.tracker_p_smr, d.tracker_p_smr)


# ------------------------------------------------------------------------ model YAML
_YAML_VALUE = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**20, 10**20),
    st.booleans(), st.none(), st.text(max_size=8), st.lists(st.integers(), max_size=3),
)


@SETTINGS
@given(raw=st.binary(max_size=400))
def test_model_reader_on_arbitrary_bytes(good, raw):
    path = _write(good[0], "raw.yaml", raw)
    try:
        m = load_model(path)
    except ModelError as e:
        _one_line(e)
    else:
        assert np.isfinite(m.dh_table()).all()


@SETTINGS
@given(field=st.sampled_from(["a", "alpha", "d", "theta_offset", "beta", "min", "max"]),
       joint=st.integers(0, 5), value=_YAML_VALUE)
def test_model_reader_on_damaged_fields(good, field, joint, value):
    import yaml

    doc = yaml.safe_load(UR5.to_yaml())
    doc["joints"][joint][field] = value
    path = _write(good[0], "damaged.yaml", yaml.safe_dump(doc).encode())
    try:
        m = load_model(path)
    except ModelError as e:
        _one_line(e)
        assert "damaged.yaml" in str(e)
    else:
        if isinstance(value, str):  # YAML 1.1 leaves "1e3" a string: read as the number
            value = float(value)
        assert isinstance(value, (int, float)) and not isinstance(value, bool)
        assert math.isfinite(value)
        assert np.isfinite(m.dh_table()).all() and np.isfinite(m.limits_rad()).all()


# ------------------------------------------------------------------------ params.json
_JSON = st.recursive(
    st.one_of(st.none(), st.booleans(), st.floats(allow_nan=True, allow_infinity=True),
              st.integers(-10**30, 10**30), st.text(max_size=10)),
    lambda children: st.one_of(st.lists(children, max_size=4),
                               st.dictionaries(st.text(max_size=6), children, max_size=4)),
    max_leaves=20,
)


@SETTINGS
@given(raw=st.binary(max_size=400))
def test_params_reader_on_arbitrary_bytes(good, raw):
    path = _write(good[0], "raw.json", raw)
    try:
        read_params(path)
    except ParamsError as e:
        _one_line(e)


def _leaves(o, path=()):
    if isinstance(o, dict):
        for k, v in o.items():
            yield from _leaves(v, (*path, k))
    elif isinstance(o, list):
        for i, v in enumerate(o):
            yield from _leaves(v, (*path, i))
    yield path


@SETTINGS
@given(data=st.data())
def test_params_reader_on_damaged_documents(good, data):
    """A real params document with one value anywhere replaced by any JSON value."""
    doc = json.loads(json.dumps(good[2]))
    paths = [p for p in _leaves(doc) if p]
    where = data.draw(st.sampled_from(paths))
    value = data.draw(_JSON)
    target = doc
    for k in where[:-1]:
        target = target[k]
    target[where[-1]] = value
    try:
        p = params_from_doc(doc, "damaged.json")
    except ParamsError as e:
        _one_line(e)
    else:
        assert np.isfinite(p.values).all() and np.isfinite(p.std).all()
