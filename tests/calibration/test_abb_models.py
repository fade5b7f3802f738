"""The built-in ABB models against an independent source: URDFs laid out as
ROS-Industrial's abb_irb2600_support and abb_irb4600_support publish them (joint origins
along the arm, axes y and x, tool0 turned 90 deg about y), written here from those
published figures. Forward kinematics (yourdfpy's, and cellcal's reading of the URDF) and
the flange's orientation agree at random joints; the controller's axis angles are the
model's joints (no axis 2/3 coupling on these serial arms)."""

import numpy as np
import pytest

from calibration import load_model
from calibration.exports.parity import compare, model_poses, parity_joints
from calibration.model.urdf_model import mount_transform

from .urdf_writers import urdf_tip_poses

#: per model: the URDF's joint origins (m, base_link to link_6) and axes; its tip tool0
#: sits on link_6 turned 90 deg about y (ABB's flange frame: z out of the flange)
PUBLISHED = {
    "irb2600_12_165": [(0, 0, 0.445), (0.15, 0, 0), (0, 0, 0.7), (0, 0, 0.115),
                       (0.795, 0, 0), (0.085, 0, 0)],
    "irb4600_60_205": [(0, 0, 0.495), (0.175, 0, 0), (0, 0, 0.9), (0, 0, 0.175),
                       (0.960, 0, 0), (0.135, 0, 0)],
}
AXES = ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "1 0 0"]


def abb_urdf(path, name: str):
    """A URDF with the published joint origins (no meshes, no limits but wide ones)."""
    links = ["base_link", *(f"link_{k}" for k in range(1, 7)), "tool0"]
    joints = []
    for k, (xyz, axis) in enumerate(zip(PUBLISHED[name], AXES, strict=True)):
        joints.append(
            f'<joint name="joint_{k + 1}" type="revolute"><parent link="{links[k]}"/>'
            f'<child link="{links[k + 1]}"/><origin xyz="{" ".join(map(str, xyz))}" '
            f'rpy="0 0 0"/><axis xyz="{axis}"/>'
            '<limit lower="-7" upper="7" effort="0" velocity="1"/></joint>')
    joints.append('<joint name="joint6-tool0" type="fixed"><parent link="link_6"/>'
                  '<child link="tool0"/><origin xyz="0 0 0" rpy="0 1.5707963267948966 0"/>'
                  "</joint>")
    body = "".join(f'<link name="{n}"/>' for n in links) + "".join(joints)
    path.write_text(f'<?xml version="1.0"?><robot name="{name}">{body}</robot>\n')
    return path


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_builtin_abb_model_is_the_published_urdf(tmp_path, name):
    model = load_model(name)
    path = abb_urdf(tmp_path / f"{name}.urdf", name)
    q = parity_joints(model, 200)
    # yourdfpy's forward kinematics of the URDF: tool0 in base_link
    T = urdf_tip_poses(path, "base_link", "tool0", q)
    max_mm, max_rad = compare(model, q, T[:, :3, 3], T[:, :3, :3])
    assert max_mm < 1e-6 and max_rad < 1e-9, (max_mm, max_rad)
    # cellcal's own reading of the URDF: the same arm, base frame on the floor
    read = load_model(f"{path}#base_link:tool0")
    np.testing.assert_allclose(mount_transform(read), np.eye(4), atol=1e-12)
    max_mm, max_rad = compare(model, q, *model_poses(read, q))
    assert max_mm < 1e-6 and max_rad < 1e-9, (max_mm, max_rad)


@pytest.mark.parametrize("name, flange_mm, wrist_mm", [
    ("irb2600_12_165", (1030.0, 0.0, 1260.0), (945.0, 0.0, 1260.0)),
    ("irb4600_60_205", (1270.0, 0.0, 1570.0), (1135.0, 0.0, 1570.0)),
])
def test_abb_zero_posture_and_axis_directions(name, flange_mm, wrist_mm):
    """At every axis 0 the flange is where the product specification draws it, z forward
    and x down; axis 2 positive leans the arm forward, axis 3 positive lowers the upper
    arm, as on the controller."""
    m = load_model(name)
    q = np.zeros((3, 6))
    q[1, 1] = q[2, 2] = np.radians(10.0)
    P, R = model_poses(m, q)
    np.testing.assert_allclose(P[0], flange_mm, atol=1e-9)
    np.testing.assert_allclose(R[0], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)
    assert P[1, 0] > P[0, 0] and P[2, 2] < P[0, 2]
    d6 = np.linalg.norm(np.subtract(flange_mm, wrist_mm))
    np.testing.assert_allclose(m.dh_table()[5, 1], d6)
    lim = np.degrees(m.limits_rad())
    assert lim.shape == (6, 2) and (lim[:, 0] < 0).all() and (lim[:, 1] > 0).all()
