"""The measurement CSV reader is strict: every refusal names file, line and column."""

import numpy as np
import pytest

from calibration import DataError, Dataset, load_csv, load_model

UR = load_model("ur10e")
HEAD = "pose_id,q1,q2,q3,q4,q5,q6,x,y,z"
ROW = "{pid},10,-20,30,-40,50,-60,{x},200,300"


def _csv(tmp_path, lines, name="m.csv"):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_reads_required_and_optional_columns(tmp_path):
    p = _csv(tmp_path, [
        "# tracker_sigma_mm: 0.015",
        "# robot: cell 3",
        "q1,q2,q3,q4,q5,q6,x,y,z,temp_c,t_s,dir1,dir2,dir3,dir4,dir5,dir6,set,cmd_x,cmd_y,cmd_z",
        "10,20,30,40,50,60,1,2,3,21.5,100,1,-1,0,1,1,1,calib,1,2,3",
        "# a comment in the middle",
        "11,21,31,41,51,61,4,5,6,21.7,101,-1,1,0,1,1,1,valid,4,5,6",
    ])
    d = load_csv(p, UR)
    assert d.n == 2 and d.meta["tracker_sigma_mm"] == "0.015" and d.meta["robot"] == "cell 3"
    np.testing.assert_allclose(d.q[0], np.radians([10, 20, 30, 40, 50, 60]))
    assert d.dirs.tolist()[0] == [1, -1, 0, 1, 1, 1]
    assert d.is_valid.tolist() == [False, True]
    assert d.calib().n == 1 and d.valid().n == 1
    assert d.noise_floor_mm() == pytest.approx(np.sqrt(3) * 0.015)
    assert d.lines.tolist() == [4, 6]
    assert d.pose_id == ["1", "2"]


@pytest.mark.parametrize(
    "lines, where",
    [
        (["pose_id,q1,q2,q3,q4,q5,x,y,z", "a,1,2,3,4,5,1,2,3"], "missing required column(s) q6"),
        ([HEAD, ROW.format(pid="a", x="abc")], "line 2, column x: not a number"),
        ([HEAD, ROW.format(pid="a", x="nan")], "line 2, column x"),
        ([HEAD, ROW.format(pid="a", x="1"), ROW.format(pid="a", x="2")],
         "line 3, column pose_id: 'a' already used on line 2"),
        ([HEAD, "a,10,-20,200,-40,50,-60,1,2,3"], "line 2, column q3: 200 deg is outside"),
        ([HEAD + ",set", ROW.format(pid="a", x="1") + ",test"], "line 2, column set"),
        ([HEAD, "a,1,2,3"], "line 2: 4 fields"),
        ([HEAD + ",dir1", ROW.format(pid="a", x="1") + ",1"], "missing dir2"),
        ([HEAD], "no data rows"),
        ([HEAD + ",q7", ROW.format(pid="a", x="1") + ",0"], "q7 but the model has 6 joints"),
        ([HEAD + ",sigma_mm", ROW.format(pid="a", x="1") + ",-1"], "column sigma_mm"),
        ([HEAD, ROW.format(pid="a", x="")], "line 2, column x: empty value"),
        ([HEAD + ",face", ROW.format(pid="a", x="1") + ",3"], "line 2, column face: 3 is neither"),
        ([HEAD + ",face", ROW.format(pid="a", x="1") + ",front"], "column face: not a number"),
        ([HEAD + ",reflector", ROW.format(pid="a", x="1") + ","], "column reflector: empty"),
        ([HEAD + ",humidity_pct", ROW.format(pid="a", x="1") + ",120"], "column humidity_pct"),
        ([HEAD + ",pressure_hpa", ROW.format(pid="a", x="1") + ",0"], "column pressure_hpa"),
    ],
)
def test_refusals_name_file_line_and_column(tmp_path, lines, where):
    p = _csv(tmp_path, lines)
    with pytest.raises(DataError) as e:
        load_csv(p, UR)
    assert str(p) in str(e.value)
    assert where in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        load_csv(tmp_path / "nope.csv", UR)


def test_csv_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    d = Dataset(
        q=rng.uniform(-1, 1, (5, 6)), tracker_p_smr=rng.normal(size=(5, 3)),
        temp_c=rng.normal(20, 1, 5),
        dirs=rng.integers(-1, 2, (5, 6)), is_valid=np.array([0, 0, 1, 0, 1], bool),
        cmd=rng.normal(size=(5, 3)), meta={"tracker_sigma_mm": "0.02"},
    )
    p = tmp_path / "rt.csv"
    d.to_csv(p)
    e = load_csv(p, UR)
    np.testing.assert_allclose(e.q, d.q, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(e.tracker_p_smr, d.tracker_p_smr)
    np.testing.assert_array_equal(e.dirs, d.dirs)
    np.testing.assert_array_equal(e.is_valid, d.is_valid)
    np.testing.assert_array_equal(e.cmd, d.cmd)
    assert e.sigma() == 0.02


def test_tracker_columns_round_trip_and_subset(tmp_path):
    """pressure_hpa, humidity_pct, reflector (text) and face (1/2): docs/formats.md §1."""
    rng = np.random.default_rng(1)
    d = Dataset(
        q=rng.uniform(-1, 1, (4, 6)), tracker_p_smr=rng.normal(size=(4, 3)),
        temp_c=rng.normal(20, 1, 4), sigma_mm=np.full(4, 0.012),
        pressure_hpa=np.array([1013.25, 1013.0, 1012.5, 1012.0]),
        humidity_pct=np.array([45.0, 45.5, 46.0, 46.5]),
        reflector=["RRR 1.5in", "RRR 1.5in", "CatsEye 3in, glass", "RRR 1.5in"],
        face=[1, 2, 1, 2],
    )
    p = tmp_path / "rt.csv"
    d.to_csv(p)
    header = [ln for ln in p.read_text().splitlines() if not ln.startswith("#")][0].split(",")
    assert header[-5:] == ["sigma_mm", "pressure_hpa", "humidity_pct", "reflector", "face"]
    e = load_csv(p, UR)
    np.testing.assert_array_equal(e.pressure_hpa, d.pressure_hpa)
    np.testing.assert_array_equal(e.humidity_pct, d.humidity_pct)
    assert e.reflector.tolist() == d.reflector.tolist()  # a comma in a name is quoted
    assert e.face.tolist() == [1, 2, 1, 2] and e.face.dtype.kind == "i"
    s = e.subset(np.array([False, True, True, False]))
    assert s.reflector.tolist() == ["RRR 1.5in", "CatsEye 3in, glass"]
    assert s.face.tolist() == [2, 1]
    both = s.concat(e)
    assert both.n == 6 and both.face.tolist() == [2, 1, 1, 2, 1, 2]
    assert both.reflector[0] == "RRR 1.5in" and both.humidity_pct[-1] == 46.5
