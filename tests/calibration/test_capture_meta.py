"""The capture metadata of a measurement file (``# key: value``): parsed strictly, written
back the same, applied to the model."""

from __future__ import annotations

import numpy as np
import pytest

from calibration import DataError, load_csv, load_model
from calibration.data.capture_meta import CaptureMeta
from calibration.data.dataset import read_meta


def _T():
    c, s = np.cos(0.3), np.sin(0.3)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [100.0, -2500.0, 2000.0]
    return T


def test_round_trip_through_header_lines_and_json():
    m = CaptureMeta(run=2, store="cell.db", model="ur10e", tool_mm=np.array([0, 0, 60.0]),
                    smr_radius_mm=19.05, reflector="RRR 1.5in", frame_run=1,
                    tracker_T_base=_T(), tracker_sigma_mm=0.0184)
    lines = m.to_meta()
    assert lines["tool_mm"] == "0, 0, 60" and lines["run"] == "2"
    back = CaptureMeta.from_meta(lines, "f.csv")
    np.testing.assert_allclose(back.tracker_T_base, m.tracker_T_base, atol=1e-9)
    np.testing.assert_array_equal(back.tool_mm, m.tool_mm)
    assert (back.run, back.smr_radius_mm, back.reflector, back.frame_run) == (2, 19.05,
                                                                              "RRR 1.5in", 1)
    again = CaptureMeta.from_json(back.to_json())
    assert again.to_meta() == lines
    assert "run 2 of cell.db, tool 0, 0, 60 mm, SMR radius 19.05 mm" in m.describe()
    assert not CaptureMeta().known and CaptureMeta.from_meta({}).to_meta() == {}


@pytest.mark.parametrize("key, value, message", [
    ("tool_mm", "0, 60", "metadata tool_mm: '0, 60' is not 3"),
    ("tool_mm", "0, x, 60", "is not 3 comma-separated finite numbers"),
    ("smr_radius_mm", "-1", "metadata smr_radius_mm: '-1' is not a positive number"),
    ("tracker_sigma_mm", "nan", "metadata tracker_sigma_mm"),
    ("run", "two", "metadata run: 'two' is not an integer"),
    ("tracker_T_base", "1,0,0,0, 0,2,0,0, 0,0,1,0", "its rotation is not a rotation"),
    ("tracker_T_base", "1,0,0,0", "is not 12"),
])
def test_malformed_metadata_is_refused_naming_file_and_key(tmp_path, key, value, message):
    f = tmp_path / "m.csv"
    f.write_text(f"# {key}: {value}\nq1,q2,q3,q4,q5,q6,x,y,z\n0,0,0,0,0,0,1,2,3\n")
    with pytest.raises(DataError, match=message) as e:
        load_csv(f, load_model("ur10e"))
    assert str(e.value).startswith(f"{f}: metadata {key}")


def test_the_capture_tool_becomes_the_nominal_tool(tmp_path):
    f = tmp_path / "m.csv"
    f.write_text("# model: ur10e\n# tool_mm: 1, 2, 60\n# note: x: y\nq1,q2,q3,q4,q5,q6,x,y,z\n"
                 "0,0,0,0,0,0,1,2,3\n# tool_mm: 9, 9, 9\n")
    assert read_meta(f) == {"model": "ur10e", "tool_mm": "1, 2, 60", "note": "x: y"}
    data = load_csv(f, load_model("ur10e"))
    model = data.capture.with_tool(load_model("ur10e"))
    assert model.tool == (1.0, 2.0, 60.0)
    bare = load_model("ur5")
    assert CaptureMeta().with_tool(bare) is bare
    assert read_meta(tmp_path / "missing.csv") == {}
