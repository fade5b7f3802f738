"""Robot models from URDF serial chains: exact FK against yourdfpy and the built-in
models, mass models from inertials, prismatic joints, and refused files."""

import math

import numpy as np
import pytest

from calibration import Dataset, ErrorModel, load_model
from calibration.exports.urdf_export import urdf_joint_values
from calibration.fit.simulate import random_joints, realistic_truth
from calibration.model.gravity import gravity_torques, potential_energy
from calibration.model.kinematics import PRISMATIC_MM_PER_UNIT, run_chain
from calibration.model.urdf_model import UrdfError, mount_transform

from .urdf_writers import UR_JOINTS, dh_chain_urdf, rot, trans, ur_style_urdf, urdf_tip_poses


def rows_of(model) -> list[dict]:
    return [j.model_dump() for j in model.joints]


def masses_of(model):
    return [(l.mass_kg, l.com) for l in model.links]


def chain(model, q):
    return run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                     prismatic=model.prismatic_mask())


def assert_matches_urdf(model, path, n=40, seed=0):
    """Tool point and flange orientation equal yourdfpy's tip link, in the root frame."""
    q = random_joints(model, n, np.random.default_rng(seed))
    T = urdf_tip_poses(path, model.urdf.root, model.urdf.tip, urdf_joint_values(model, q))
    r = chain(model, q)
    M = mount_transform(model)
    P = r.base_p_tcp @ M[:3, :3].T + M[:3, 3]
    np.testing.assert_allclose(P, T[:, :3, 3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(M[:3, :3] @ r.base_R_flange, T[:, :3, :3], rtol=0, atol=1e-12)


@pytest.fixture
def ur10e_urdf(tmp_path):
    return ur_style_urdf(tmp_path / "ur10e.urdf", load_model("ur10e"))


def test_ur_style_urdf_from_base_link_inertia_is_the_builtin_ur10e(ur10e_urdf):
    ref = load_model("ur10e")
    m = load_model(f"{ur10e_urdf}#base_link_inertia:tool0")
    assert m.convention == "dh" and m.n_joints == 6
    np.testing.assert_allclose(m.dh_table(), ref.dh_table(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(m.tool_mm(), 0.0, atol=1e-9)
    assert m.urdf.joints == UR_JOINTS
    np.testing.assert_allclose([[j.min, j.max] for j in m.joints],
                               [[j.min, j.max] for j in ref.joints], atol=1e-9)
    assert_matches_urdf(m, ur10e_urdf)
    # the mass model from the inertials gives the built-in's gravity torques
    q = random_joints(ref, 30, np.random.default_rng(1))
    np.testing.assert_allclose(gravity_torques(m, chain(m, q)), gravity_torques(ref, chain(ref, q)),
                               rtol=0, atol=1e-9)


def test_ur_style_urdf_alone_takes_the_unambiguous_chain(ur10e_urdf):
    ref = load_model("ur10e")
    m = load_model(str(ur10e_urdf))
    # tips tool0 and ft_frame share all six joints: the chain ends where they part
    assert (m.urdf.root, m.urdf.tip) == ("base_link", "wrist_3_link")
    assert_matches_urdf(m, ur10e_urdf)
    # base_link is base_link_inertia turned 180 deg about z (REP-103)
    q = random_joints(ref, 30, np.random.default_rng(2))
    turned = chain(ref, q).base_p_tcp @ rot("z", math.pi)[:3, :3].T
    np.testing.assert_allclose(chain(m, q).base_p_tcp, turned, rtol=0, atol=1e-9)


def test_mdh_arm_with_turned_link_frames_and_fixed_joints(tmp_path):
    ref = load_model("rv16")
    path = dh_chain_urdf(tmp_path / "rv16.urdf", "mdh", rows_of(ref), tool=ref.tool,
                         rng=np.random.default_rng(3), split_fixed=True)
    text = path.read_text()
    assert 'type="fixed"' in text and '<axis xyz="0 0 1"/>' not in text  # axes are not z
    m = load_model(f"{path}#base_link:tool0")
    assert m.n_joints == 6 and m.convention == "dh"
    assert_matches_urdf(m, path)
    q = random_joints(ref, 50, np.random.default_rng(4))
    np.testing.assert_allclose(chain(m, q).base_p_tcp, chain(ref, q).base_p_tcp, rtol=0, atol=1e-9)
    # the parallel axes 2 and 3 carry beta in the converted table as in the MDH original
    assert 1 in m.parallel_rows()


def test_seven_axis_urdf_is_the_builtin_panda(tmp_path):
    ref = load_model("panda")
    path = dh_chain_urdf(tmp_path / "panda.urdf", "mdh", rows_of(ref), tool=ref.tool,
                         rng=np.random.default_rng(5), name="panda_urdf")
    m = load_model(str(path))
    assert m.n_joints == 7 and m.name == "panda_urdf"
    assert m.urdf.tip == "tool0"
    np.testing.assert_allclose([[j.min, j.max] for j in m.joints],
                               [[j.min, j.max] for j in ref.joints], atol=1e-9)
    assert_matches_urdf(m, path)
    q = random_joints(ref, 50, np.random.default_rng(6))
    np.testing.assert_allclose(chain(m, q).base_p_tcp, chain(ref, q).base_p_tcp, rtol=0, atol=1e-9)


def test_base_frame_on_a_tilted_first_axis_is_the_mount(tmp_path):
    ref = load_model("ur10e")
    mount = trans(300.0, -200.0, 50.0) @ rot("x", 0.4) @ rot("y", -0.3)
    path = dh_chain_urdf(tmp_path / "tilted.urdf", "dh", rows_of(ref), masses=masses_of(ref),
                         mount=mount)
    m = load_model(f"{path}#base_link:tool0")
    M = mount_transform(m)
    assert not np.allclose(M, np.eye(4))
    np.testing.assert_allclose(M[:3, 2], mount[:3, 2], atol=1e-12)  # z on joint 1's axis
    assert_matches_urdf(m, path)
    # gravity is turned into the model's base frame; torques are those of the robot so mounted
    g = mount[:3, :3].T @ [0.0, 0.0, -9.81]
    np.testing.assert_allclose(M[:3, :3].T @ [0.0, 0.0, -9.81], m.gravity, atol=1e-12)
    tilted = ref.with_changes(gravity=tuple(g))
    q = random_joints(ref, 20, np.random.default_rng(7))
    np.testing.assert_allclose(chain(m, q).base_p_tcp @ M[:3, :3].T + M[:3, 3],
                               chain(ref, q).base_p_tcp @ mount[:3, :3].T + mount[:3, 3], atol=1e-9)
    np.testing.assert_allclose(gravity_torques(m, chain(m, q)),
                               gravity_torques(tilted, chain(tilted, q)), atol=1e-9)


def track_model(tmp_path, name="track.urdf"):
    """A UR10e on a linear track: a prismatic joint along the root's x axis, then six
    revolute joints, inertials on every body, link frames turned at random."""
    ur = load_model("ur10e")
    rows = [{"type": "prismatic", "a": 0.0, "alpha": 0.0, "d": 150.0, "theta_offset": 0.0,
             "min": -500.0, "max": 1500.0}] + rows_of(ur)
    rows[1]["theta_offset"] = 90.0
    masses = [(40.0, (0.0, 0.0, -60.0)), *masses_of(ur)]
    path = dh_chain_urdf(tmp_path / name, "dh", rows, masses=masses, rng=np.random.default_rng(8),
                         mount=rot("y", math.pi / 2) @ rot("z", 0.3), tool=(0.0, 0.0, 60.0))
    return path, load_model(str(path))


def test_prismatic_joint_slides_like_the_urdf(tmp_path):
    path, m = track_model(tmp_path)
    assert m.n_joints == 7 and m.joints[0].type == "prismatic"
    assert (m.joints[0].min, m.joints[0].max) == pytest.approx((-500.0, 1500.0))
    assert_matches_urdf(m, path)
    # the travel in files is mm; inside it is mm * pi/180, like an angle in rad
    q = np.zeros((2, 7))
    q[1, 0] = np.radians(250.0)
    p = chain(m, q).base_p_tcp
    M = mount_transform(m)
    np.testing.assert_allclose((p[1] - p[0]) @ M[:3, :3].T, [250.0, 0.0, 0.0], atol=1e-9)


def test_prismatic_jacobians_match_finite_differences(tmp_path):
    _, m = track_model(tmp_path)
    em = ErrorModel(m, "geometric,base,tool,compliance:1,scale:1,compliance:3,thermal")
    rng = np.random.default_rng(9)
    q = random_joints(m, 30, rng)
    bound = em.bind(Dataset(q=q, tracker_p_smr=np.zeros((30, 3)), temp_c=rng.uniform(15, 30, 30)))
    x = realistic_truth(em, rng, length_mm=2.0, angle_deg=0.5)
    _, J = em.evaluate(x, bound)
    Jn = em.numeric_jacobian(x, bound)
    scale = np.abs(J).max(axis=(0, 1)) + 1.0
    err = np.abs(J - Jn).max(axis=(0, 1)) / scale
    assert err.max() < 1e-6, f"{em.names[int(np.argmax(err))]}: {err.max():.2e}"
    # the joint columns (what every joint correction acts through) of a model without joint
    # effects, and of the bare chain (incl. the flange's angular velocity), by differences
    em = ErrorModel(m, "geometric,base,tool,thermal")
    x = realistic_truth(em, rng, length_mm=2.0, angle_deg=0.5)
    temp = bound.data.temp_c

    def P(qq):
        return em.evaluate(x, em.bind(Dataset(q=qq, tracker_p_smr=np.zeros((30, 3)), temp_c=temp)),
                           False)[0]

    G = em.evaluate(x, em.bind(Dataset(q=q, tracker_p_smr=np.zeros((30, 3)), temp_c=temp)),
                    joints=True)[2]
    r = chain(m, q)
    h = 1e-6
    for j in range(m.n_joints):
        dq = np.zeros_like(q)
        dq[:, j] = h
        np.testing.assert_allclose(G[:, :, j], (P(q + dq) - P(q - dq)) / (2 * h), rtol=0,
                                   atol=1e-6 * np.abs(G).max())
        rp, rm = chain(m, q + dq), chain(m, q - dq)
        fd = (rp.base_p_tcp - rm.base_p_tcp) / (2 * h)
        np.testing.assert_allclose(r.dP_dq[:, :, j], fd, rtol=0,
                                   atol=1e-6 * np.abs(r.dP_dq).max())
        dR = ((rp.base_R_flange - rm.base_R_flange) / (2 * h)
              @ np.swapaxes(r.base_R_flange, 1, 2))
        w = np.stack([dR[:, 2, 1], dR[:, 0, 2], dR[:, 1, 0]], 1)
        np.testing.assert_allclose(r.dR_dq[:, :, j], w, rtol=0, atol=1e-7)


def test_prismatic_gravity_force_is_minus_gradient_of_potential(tmp_path):
    _, m = track_model(tmp_path)
    q = random_joints(m, 10, np.random.default_rng(10))
    tau = gravity_torques(m, chain(m, q))
    h = 1e-6
    for j in range(m.n_joints):
        dq = np.zeros_like(q)
        dq[:, j] = h
        V = [potential_energy(m, chain(m, q + s * dq)) for s in (1, -1)]
        dV = (V[0] - V[1]) / (2 * h)
        np.testing.assert_allclose(tau[:, j], -dV, rtol=1e-6, atol=1e-6)
    # the track carries the whole robot: its weight along the axis, per unit of travel
    total = sum(l.mass_kg for l in m.links)
    axis = chain(m, q).joint_axes[:, 0]
    np.testing.assert_allclose(tau[:, 0], axis @ np.asarray(m.gravity) * total
                               * PRISMATIC_MM_PER_UNIT / 1000.0, rtol=1e-12)


# ---- refused files ----------------------------------------------------------------------------
LIM = '<limit lower="-3" upper="3" effort="1" velocity="1"/>'
GOOD = f"""<?xml version="1.0"?>
<robot name="r">
  <link name="base"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>{LIM}</joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="1.5707963 0 0"/><axis xyz="0 0 1"/>{LIM}</joint>
</robot>
"""


def _bad(text, old, new):
    assert old in text
    return text.replace(old, new)


BAD = {
    "no chain": (GOOD, "#l2:l1", "no chain from link 'l2' down to link 'l1'"),
    "loop": (_bad(GOOD, "</robot>", '<joint name="j3" type="fixed"><parent link="base"/>'
                  '<child link="l2"/></joint></robot>'), "", "link 'l2' is the child of joints"),
    "cycle": (_bad(GOOD, "</robot>", '<joint name="j3" type="fixed"><parent link="l2"/>'
                   '<child link="base"/></joint></robot>'), "", "closes a loop"),
    "floating": (_bad(GOOD, 'name="j2" type="revolute"', 'name="j2" type="floating"'), "",
                 "joint 'j2' is floating"),
    "missing link": (_bad(GOOD, '<child link="l2"/>', '<child link="l3"/>'), "",
                     "joint 'j2' names child link 'l3', which is not declared"),
    "malformed": (GOOD[:-30], "", "malformed XML"),
    "no limits": (_bad(GOOD, f'{LIM}</joint>\n  <joint name="j2"',
                       '</joint>\n  <joint name="j2"'), "", "joint 'j1' (revolute) has no <limit"),
    "unknown link": (GOOD, "#base:tool9", "no tip link 'tool9'"),
    "ambiguous": (_bad(GOOD, "</robot>", f'<link name="f"/><joint name="j3" type="prismatic">'
                       f'<parent link="l1"/><child link="f"/>{LIM}</joint></robot>'), "",
                  "the chain below 'base' is ambiguous (tips: f, l2)"),
    "two roots": (_bad(GOOD, "</robot>", '<link name="other"/></robot>'), "",
                  "2 root links (base, other)"),
    "zero axis": (_bad(GOOD, '<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), "",
                  "joint 'j1': <axis xyz> is zero"),
    "no file": (None, "", "no such URDF file"),
}


def test_a_good_small_urdf_loads(tmp_path):
    p = tmp_path / "r.urdf"
    p.write_text(GOOD.replace('name="j2" type="revolute"', 'name="j2" type="continuous"'))
    m = load_model(str(p))
    assert m.n_joints == 2 and (m.urdf.root, m.urdf.tip) == ("base", "l2")
    assert (m.joints[0].min, m.joints[0].max) == pytest.approx(np.degrees([-3, 3]))
    assert (m.joints[1].min, m.joints[1].max) == (-360.0, 360.0)  # continuous
    assert m.links is None  # no inertials: no mass model


@pytest.mark.parametrize("case", list(BAD))
def test_bad_urdfs_are_refused_naming_the_element(tmp_path, case):
    text, suffix, expected = BAD[case]
    p = tmp_path / "bad.urdf"
    if text is not None:
        p.write_text(text)
    with pytest.raises(UrdfError) as e:
        load_model(f"{p}{suffix}")
    assert expected in str(e.value) and "\n" not in str(e.value)
