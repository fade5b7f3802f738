"""Exports of a calibrated model (URDF, UR kinematics YAML, DH/MDH CSV, calibration.conf),
each read back and compared with the calibrated model."""

import math

import numpy as np
import pytest
import yaml

from calibration import ErrorModel, load_model
from calibration.exports.controller_export import (
    ExportError,
    libstdcxx_hash,
    read_table_csv,
    table_csv,
    ur_conf_parity,
    ur_kinematics,
    ur_kinematics_hash,
    write_table_csv,
    write_ur_kinematics_yaml,
)
from calibration.exports.model_export import calibrated_model, write_ur_conf
from calibration.exports.parity import model_poses, parity_joints
from calibration.exports.urdf_export import urdf_text, write_urdf
from calibration.fit.simulate import realistic_truth
from calibration.model.kinematics import run_chain
from calibration.model.urdf_model import mount_transform

from .test_urdf_model import track_model
from .urdf_writers import rot, trans, ur_style_urdf


def calibrated(spec, seed=1, effects="geometric,base,tool"):
    m = load_model(spec)
    em = ErrorModel(m, effects)
    x = realistic_truth(em, np.random.default_rng(seed), length_mm=0.5, angle_deg=0.05)
    model, notes = calibrated_model(em, x)
    return em, x, model, notes


@pytest.mark.parametrize("name", ["ur10e", "rv16", "panda"])
def test_calibrated_urdf_matches_the_model_through_yourdfpy(tmp_path, name):
    em, x, model, notes = calibrated(name)
    parity = write_urdf(model, tmp_path / "cal.urdf", notes)
    assert parity.n == 1000 and parity.max_mm <= 1e-6 and parity.max_rad <= 1e-9
    text = (tmp_path / "cal.urdf").read_text()
    assert '<link name="tcp"/>' in text and "<calibration" not in text
    assert "base: the robot's pose in the tracker frame" in text
    # read back by cellcal itself: the same chain down to the measured point
    back = load_model(f"{tmp_path / 'cal.urdf'}#base_link:tcp")
    q = parity_joints(model, 200)
    M = mount_transform(back)  # a tilted joint 1 (MDH alpha_0 error) gets a mount
    np.testing.assert_allclose(model_poses(back, q)[0] @ M[:3, :3].T + M[:3, 3],
                               model_poses(model, q)[0], atol=1e-9)


def test_urdf_model_keeps_root_joint_names_and_mount(tmp_path):
    path, m = track_model(tmp_path)  # prismatic joint, mount turned 90 deg
    em = ErrorModel(m, "geometric,base,tool,compliance:3")
    x = realistic_truth(em, np.random.default_rng(2), length_mm=0.5, angle_deg=0.05)
    model, notes = calibrated_model(em, x)
    assert "compliance:3: not a fixed kinematic parameter, not exported" in notes
    parity = write_urdf(model, tmp_path / "cal.urdf", notes)
    assert parity.max_mm <= 1e-6 and parity.max_rad <= 1e-9
    text = (tmp_path / "cal.urdf").read_text()
    assert '<joint name="joint1" type="prismatic">' in text
    assert 'name="cellcal_mount"' in text and '<link name="base_link"/>' in text
    back = load_model(f"{tmp_path / 'cal.urdf'}#base_link:tcp")
    q = parity_joints(model, 100)
    Mb, Mm = mount_transform(back), mount_transform(model)
    np.testing.assert_allclose(model_poses(back, q)[0] @ Mb[:3, :3].T + Mb[:3, 3],
                               model_poses(model, q)[0] @ Mm[:3, :3].T + Mm[:3, 3], atol=1e-9)


def test_urdf_text_is_plain_urdf_with_limits_and_names():
    m = load_model("ur10e")
    text = urdf_text(m)
    assert text.count('type="revolute"') == 6 and text.count('type="fixed"') == 2
    assert f'lower="{-2 * math.pi!r}"' in text  # +-360 deg
    assert 'name="joint6"' in text and 'name="flange_joint"' in text


# ---- the UR driver's kinematics YAML --------------------------------------------------------
def test_libstdcxx_hash_matches_gcc():
    # std::hash<std::string>{}("hello") printed by a g++ (libstdc++, x86-64) program
    assert libstdcxx_hash(b"hello") == 2762169579135187400
    assert libstdcxx_hash(b"") == 6142509188972423790


def test_nominal_ur10e_hash_is_the_one_ur_description_ships():
    # config/ur10e/default_kinematics.yaml of ur_description: hash calib_5119701370761913513
    assert ur_kinematics_hash(load_model("ur10e").dh_table()) == "calib_5119701370761913513"


def _origin(k):
    T = trans(k["x"] * 1000, k["y"] * 1000, k["z"] * 1000)
    return T @ rot("z", k["yaw"]) @ rot("y", k["pitch"]) @ rot("x", k["roll"])


# ur_description config/ur30/default_kinematics.yaml (the UR30's nominal DH as UR's
# calibration tool writes it; alpha = 1.570796327 as the controller reports pi/2)
UR30_DEFAULT = {
    "shoulder": dict(x=0, y=0, z=0.2363, roll=0, pitch=0, yaw=0),
    "upper_arm": dict(x=0, y=0, z=0, roll=1.570796327, pitch=0, yaw=0),
    "forearm": dict(x=-0.637, y=0, z=0, roll=0, pitch=0, yaw=0),
    "wrist_1": dict(x=-0.5037, y=0, z=0.201, roll=0, pitch=0, yaw=0),
    "wrist_2": dict(x=0, y=-0.1593, z=0, roll=1.570796327, pitch=0, yaw=0),
    "wrist_3": dict(x=0, y=0.1543, z=-3.1647459019915597e-11, roll=1.5707963265897931,
                    pitch=3.1415926535897931, yaw=3.1415926535897931),
}


def test_ur_yaml_of_the_nominal_ur30_is_ur_descriptions_default(tmp_path):
    rows = [(236.3, 0, 90), (0, -637, 0), (0, -503.7, 0), (201, 0, 90), (159.3, 0, -90),
            (154.3, 0, 0)]
    p = tmp_path / "ur30.yaml"
    p.write_text("name: ur30\nconvention: dh\njoints:\n" + "".join(
        f"  - {{d: {d}, a: {a}, alpha: {al}, min: -360, max: 360}}\n" for d, a, al in rows))
    kin, tcp = ur_kinematics(load_model(p))
    for link, ref in UR30_DEFAULT.items():
        np.testing.assert_allclose(_origin(kin["kinematics"][link]), _origin(ref), atol=1e-6)
    assert tcp == pytest.approx([0, 0, 0])


@pytest.mark.parametrize("spec", ["ur10e", "URDF#base_link:tool0", "URDF#base_link_inertia:tool0"])
def test_ur_yaml_parity_for_builtin_and_urdf_models(tmp_path, spec):
    urdf = ur_style_urdf(tmp_path / "ur10e.urdf", load_model("ur10e"))
    spec = spec.replace("URDF", str(urdf))
    em, x, model, notes = calibrated(spec, seed=3)
    parity = write_ur_kinematics_yaml(model, tmp_path / "k.yaml", notes)
    assert parity.max_mm <= 1e-6 and parity.max_rad <= 1e-9
    data = yaml.safe_load((tmp_path / "k.yaml").read_text())["kinematics"]
    assert list(data) == ["shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3",
                          "hash"]
    assert set(data["shoulder"]) == {"x", "y", "z", "roll", "pitch", "yaw"}
    # the nominal robot from the built-in or either URDF root: ur_description's default
    nominal = ur_kinematics(load_model(spec))[0]["kinematics"]
    ref = ur_kinematics(load_model("ur10e"))[0]["kinematics"]
    for link in ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3"):
        np.testing.assert_allclose(_origin(nominal[link]), _origin(ref[link]), atol=1e-9)
    assert nominal["hash"] == ref["hash"] == "calib_5119701370761913513"


def test_ur_yaml_refuses_what_it_cannot_hold():
    for spec in ("panda", "rv16"):
        with pytest.raises(ExportError, match="6-joint revolute standard-DH"):
            ur_kinematics(load_model(spec))
    elsewhere = load_model("ur10e").with_changes(urdf={
        "file": "cell.urdf", "root": "world", "tip": "tool0",
        "joints": [f"j{i}" for i in range(6)]})
    with pytest.raises(ExportError, match="starts at base_link_inertia"):
        ur_kinematics(elsewhere)


# ---- tables and calibration.conf -------------------------------------------------------------
@pytest.mark.parametrize("name", ["ur10e", "rv16", "panda"])
def test_table_csv_round_trip(tmp_path, name):
    em, x, model, notes = calibrated(name)
    parity = write_table_csv(model, tmp_path / "t.csv", notes)
    assert parity.max_mm <= 1e-9 and parity.max_rad <= 1e-12
    lines = (tmp_path / "t.csv").read_text().splitlines()
    assert lines[0] == f"# convention: {model.convention}"
    header = next(line for line in lines if not line.startswith("#"))
    assert header == ("joint,name,type,theta_offset_deg,d_mm,a_mm,alpha_deg,beta_deg,min,max,"
                      "limit_unit")
    convention, table, tool, prismatic = read_table_csv(tmp_path / "t.csv")
    assert convention == model.convention and not prismatic.any()
    np.testing.assert_allclose(table, model.dh_table(), rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(tool, model.tool_mm(), rtol=0, atol=0)


def test_table_csv_marks_prismatic_joints_in_mm(tmp_path):
    _, m = track_model(tmp_path)
    text = table_csv(m)
    assert ",prismatic," in text and text.splitlines()[-7].endswith(",mm")
    (tmp_path / "t.csv").write_text(text)
    q = parity_joints(m, 50)
    convention, table, tool, prismatic = read_table_csv(tmp_path / "t.csv")
    r = run_chain(convention, table, q, tool, jacobian=False, prismatic=prismatic)
    np.testing.assert_allclose(r.base_p_tcp, model_poses(m, q)[0], atol=1e-9)


def test_calibration_conf_parity(tmp_path):
    em, x, model, notes = calibrated("ur10e", seed=4)
    write_ur_conf(em, x, tmp_path / "calibration.conf")
    parity = ur_conf_parity(tmp_path / "calibration.conf", model, em.model)
    assert parity.n == 1000 and parity.max_mm <= 1e-6 and parity.max_rad <= 1e-9


def test_ur_files_of_a_ur_urdf_from_base_link_are_the_controllers(tmp_path):
    """A calibrated UR10e written as a ur_description-style URDF and read from base_link
    (its own frames: turned 180 deg, signs of a and alpha flipped) gives the controller's
    pure-DH chain, calibration.conf deltas and hash of the original."""
    from calibration.exports.controller_export import ur_table
    from calibration.exports.model_export import ur_deltas
    from calibration.exports.ur_conf import to_pure_dh

    ref = load_model("ur10e")
    em = ErrorModel(ref)
    x = realistic_truth(em, np.random.default_rng(5), length_mm=0.5, angle_deg=0.05)
    x[[em.index("geometric.j6.a"), em.index("geometric.j6.alpha")]] = 0.0  # UR: flange on axis 6
    truth, _ = calibrated_model(em, x)
    path = ur_style_urdf(tmp_path / "calibrated_ur.urdf", truth)
    m = load_model(f"{path}#base_link:tool0")
    assert m.joints[1].a > 0  # not UR's frames
    a, b = to_pure_dh(ur_table(m)[0]), to_pure_dh(truth.dh_table())
    d = a - b
    d[:, 0] = (d[:, 0] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d[:, 0]).max() < 1e-9
    np.testing.assert_allclose(a[:, 1:], b[:, 1:], rtol=1e-9, atol=1e-9)
    kin_m, kin_t = ur_kinematics(m)[0]["kinematics"], ur_kinematics(truth)[0]["kinematics"]
    assert kin_m["hash"] == kin_t["hash"]
    # the URDF model (nominal: the nominal UR URDF) gives the truth's deltas to the nominal
    nominal = load_model(f"{ur_style_urdf(tmp_path / 'nominal.urdf', ref)}#base_link:tool0")
    em_u = ErrorModel(nominal, "geometric,base,tool")
    x_u = np.zeros(em_u.n_params)
    geo = em_u.slices[0]
    x_u[geo] = [(m.dh_table() - nominal.dh_table())[j, c] for j, c in em_u.effects[0].entries]
    assert np.allclose(calibrated_model(em_u, x_u)[0].dh_table(), m.dh_table(), atol=1e-12)
    got, _ = ur_deltas(em_u, x_u)
    want, _ = ur_deltas(em, x)
    for k in got:
        np.testing.assert_allclose(got[k], want[k], rtol=1e-9, atol=1e-12)
