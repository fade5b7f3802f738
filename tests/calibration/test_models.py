import numpy as np
import pytest

from calibration import ModelError, builtin_models, load_model


def test_builtins_load_with_sources():
    names = builtin_models()
    assert {"ur5", "ur5e", "ur10", "ur10e", "rv16", "panda"} <= set(names)
    for name in names:
        m = load_model(name)
        assert m.n_joints == (7 if name == "panda" else 6)
        assert m.dh_table().shape == (m.n_joints, 5)


def test_rv16_is_the_thesis_table():
    m = load_model("rv16")
    assert m.convention == "mdh"
    t = m.dh_table()
    np.testing.assert_allclose(np.degrees(t[:, 3]), [0, -90, 0, -90, 90, -90])
    np.testing.assert_allclose(t[:, 2], [0, 280, 615, 0, 0, 0])
    np.testing.assert_allclose(t[3, 1], 540)
    np.testing.assert_allclose(np.degrees(t[1, 0]), -90)
    assert m.parallel_rows() == [2]  # axes 2 and 3 are parallel


def test_ur_parallel_rows_carry_beta():
    assert load_model("ur10e").parallel_rows() == [1, 2]


def _write(tmp_path, text):
    p = tmp_path / "robot.yaml"
    p.write_text(text)
    return p


GOOD_ROW = "{a: 0, alpha: 90, d: 100, min: -180, max: 180}"


@pytest.mark.parametrize(
    "text, field",
    [
        (f"name: x\nconvention: xyz\njoints:\n  - {GOOD_ROW}\n", "convention"),
        ("name: x\nconvention: dh\njoints:\n  - {a: 0, alpha: 90, min: -1, max: 1}\n",
         "joints.0.d"),
        ("name: x\nconvention: dh\njoints:\n  - {a: 0, alpha: 0, d: 0, min: 10, max: -10}\n",
         "joints.0"),
        (f"convention: dh\njoints:\n  - {GOOD_ROW}\n", "name"),
        (f"name: x\nconvention: dh\njoints:\n  - {GOOD_ROW}\nlinks:\n  - {{mass_kg: 1}}\n"
         "  - {mass_kg: 2}\n", "links"),
        (f"name: x\nconvention: dh\njoints:\n  - {GOOD_ROW}\ncolour: red\n", "colour"),
        ("name: x\nconvention: dh\njoints: []\n", "joints"),
    ],
)
def test_bad_model_files_name_file_and_field(tmp_path, text, field):
    p = _write(tmp_path, text)
    with pytest.raises(ModelError) as e:
        load_model(p)
    assert str(p) in str(e.value)
    assert field in str(e.value)


def test_unknown_name_lists_builtins():
    with pytest.raises(ModelError, match="ur10e"):
        load_model("abb9999")


def test_yaml_round_trip(tmp_path):
    m = load_model("ur10e")
    p = tmp_path / "copy.yaml"
    p.write_text(m.to_yaml())
    assert load_model(p) == m
