"""The orientation columns of the measurement CSV (qw..qz, sigma_deg, tool_id): strict,
every refusal one line naming the file, the line and the column; property tests
(derandomized hypothesis) over values and files."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calibration import DataError
from calibration.data.dataset import CsvTable
from calibration.data.orientation_columns import (
    UNIT_TOLERANCE,
    read_orientation_columns,
)
from calibration.model.transforms import matrix_to_quat, random_rotation

SETTINGS = settings(max_examples=80, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _table(tmp_path, header, rows, name="m.csv") -> CsvTable:
    p = tmp_path / name
    p.write_text(",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return CsvTable(p)


def _quat_rows(n, seed=0, decimals=12):
    rng = np.random.default_rng(seed)
    return [[f"{v:.{decimals}f}" for v in matrix_to_quat(random_rotation(rng))]
            for _ in range(n)]


def test_a_file_without_orientation_columns_has_none(tmp_path):
    got = read_orientation_columns(_table(tmp_path, ["x", "y"], [[1, 2]]))
    assert got.quat is None and got.sigma_deg is None and got.tool_id is None


def test_quaternions_sigma_and_tool_ids_are_read(tmp_path):
    rows = [[*q, 0.01, t] for q, t in zip(_quat_rows(3), ["tmac", "nest_A", "n2:b-1.x"],
                                          strict=True)]
    got = read_orientation_columns(
        _table(tmp_path, ["qw", "qx", "qy", "qz", "sigma_deg", "tool_id"], rows))
    np.testing.assert_allclose(np.linalg.norm(got.quat, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(got.quat, np.array(_quat_rows(3), float), atol=1e-11)
    assert got.sigma_deg.tolist() == [0.01] * 3
    assert got.tool_id.tolist() == ["tmac", "nest_A", "n2:b-1.x"]


def test_all_four_quaternion_columns_or_none(tmp_path):
    t = _table(tmp_path, ["qw", "qx", "qy"], [[1, 0, 0]])
    with pytest.raises(DataError, match=r"m\.csv: line 1: .*need all of qw\.\.qz; missing qz"):
        read_orientation_columns(t)


def test_a_quaternion_off_unit_length_is_refused_naming_its_line(tmp_path):
    rows = _quat_rows(3)
    rows[1] = [0.9, 0.1, 0.0, 0.0]  # length 0.906
    with pytest.raises(DataError, match=r"m\.csv: line 3, column qw\.\.qz: quaternion "
                                        r"\(0\.9, 0\.1, 0, 0\) has length 0\.905538"):
        read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz"], rows))


def test_the_tolerance_accepts_five_decimals_and_refuses_euler_angles(tmp_path):
    got = read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz"],
                                          _quat_rows(200, seed=3, decimals=5)))
    np.testing.assert_allclose(np.linalg.norm(got.quat, axis=1), 1.0, atol=1e-15)
    just_off = [[1.0 + 2 * UNIT_TOLERANCE, 0, 0, 0]]
    with pytest.raises(DataError, match="line 2, column qw..qz"):
        read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz"], just_off, "a.csv"))
    euler = [[0, 12.5, -3.0, 90.0]]  # someone's angles in the quaternion columns
    with pytest.raises(DataError, match="not 1"):
        read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz"], euler, "b.csv"))


@pytest.mark.parametrize("value, message", [
    ("", "empty value"), ("nan", "not a finite number"), ("abc", "not a number"),
    ("inf", "not a finite number")])
def test_non_numeric_quaternion_values_are_refused(tmp_path, value, message):
    rows = _quat_rows(2)
    rows[1][2] = value
    with pytest.raises(DataError, match=f"line 3, column qy: .*{message}"):
        read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz"], rows))


@pytest.mark.parametrize("sigma", ["0", "-0.01", "181", "nan"])
def test_sigma_deg_must_be_a_positive_finite_uncertainty(tmp_path, sigma):
    rows = [[*q, s] for q, s in zip(_quat_rows(2), ["0.01", sigma], strict=True)]
    with pytest.raises(DataError, match="line 3, column sigma_deg"):
        read_orientation_columns(_table(tmp_path, ["qw", "qx", "qy", "qz", "sigma_deg"], rows))


def test_sigma_deg_without_orientations_is_refused(tmp_path):
    with pytest.raises(DataError, match=r"line 1: sigma_deg .* needs the orientation columns"):
        read_orientation_columns(_table(tmp_path, ["x", "sigma_deg"], [[1, 0.01]]))


@pytest.mark.parametrize("tool", ["", "two words", "nest/1", "_x", "a" * 33, "é"])
def test_tool_id_must_be_a_short_token(tmp_path, tool):
    with pytest.raises(DataError, match="line 3, column tool_id"):
        read_orientation_columns(_table(tmp_path, ["x", "tool_id"], [[1, "ok"], [2, tool]]))


def test_tool_ids_without_orientations_are_fine(tmp_path):
    """Two or three SMR nests on the tool: positions only, each row names its nest."""
    got = read_orientation_columns(_table(tmp_path, ["x", "tool_id"], [[1, "A"], [2, "B"]]))
    assert got.quat is None and got.tool_id.tolist() == ["A", "B"]


# ------------------------------------------------------------------ properties
quat_values = st.lists(st.floats(-1.5, 1.5, allow_nan=False), min_size=4, max_size=4)


@SETTINGS
@given(st.lists(quat_values, min_size=1, max_size=6))
def test_any_quaternions_either_read_as_unit_or_refused_naming_the_line(tmp_path_factory, qs):
    folder = tmp_path_factory.mktemp("q")
    t = _table(folder, ["qw", "qx", "qy", "qz"], [[repr(v) for v in q] for q in qs])
    norms = np.linalg.norm(np.array(qs), axis=1)
    try:
        got = read_orientation_columns(t)
    except DataError as e:
        assert "\n" not in str(e)
        first = int(np.argmax(~(np.abs(norms - 1.0) <= UNIT_TOLERANCE)))
        assert f"line {first + 2}, column qw..qz" in str(e)
        return
    assert np.all(np.abs(norms - 1.0) <= UNIT_TOLERANCE)
    assert np.isfinite(got.quat).all()
    np.testing.assert_allclose(np.linalg.norm(got.quat, axis=1), 1.0, atol=1e-15)


@SETTINGS
@given(st.lists(st.text(min_size=0, max_size=40), min_size=1, max_size=5),
       st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=1, max_size=5))
def test_any_tool_ids_and_sigmas_are_read_or_refused_in_one_line(tmp_path_factory, ids, sig):
    folder = tmp_path_factory.mktemp("t")
    n = min(len(ids), len(sig))
    rows = [[*q, repr(s), i.replace(",", "").replace("\n", "").replace("\r", "")
             .replace('"', "")]
            for q, s, i in zip(_quat_rows(n), sig[:n], ids[:n], strict=True)]
    try:
        t = _table(folder, ["qw", "qx", "qy", "qz", "sigma_deg", "tool_id"], rows)
        got = read_orientation_columns(t)
    except DataError as e:
        assert "\n" not in str(e) and "line " in str(e)
        return
    assert (got.sigma_deg > 0).all() and np.isfinite(got.sigma_deg).all()
    assert all(0 < len(v) <= 32 and " " not in v for v in got.tool_id)
