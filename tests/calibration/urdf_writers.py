"""URDF files for the tests, written from published DH/MDH tables (nothing downloaded).

The writers are independent of :mod:`calibration.model.urdf_model`: each joint origin is
the product of elementary DH transforms, written as URDF xyz (m) and rpy (rad,
R = Rz(yaw) Ry(pitch) Rx(roll)). Options make the files harder than a plain DH
transcription: link frames turned at random (so axes are not z), fixed joints with
arbitrary offsets between the movable ones, inertials, prismatic joints.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np


def rot(axis: str, t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    R = {"x": [[1, 0, 0], [0, c, -s], [0, s, c]], "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
         "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[axis]
    T = np.eye(4)
    T[:3, :3] = R
    return T


def trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = x, y, z
    return T


def random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    T = np.eye(4)
    T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    return T


def origin_xml(T_mm: np.ndarray) -> str:
    """<origin> of a transform given in mm."""
    R = T_mm[:3, :3]
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0])))
    if abs(math.cos(pitch)) > 1e-9:
        roll, yaw = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:
        roll, yaw = 0.0, math.atan2(-R[0, 1], R[1, 1])
    xyz = " ".join(repr(float(v) / 1000.0) for v in T_mm[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{roll!r} {pitch!r} {yaw!r}"/>'


def _inertial(mass_com) -> str:
    if mass_com is None:
        return ""
    m, com = mass_com
    xyz = " ".join(repr(float(v) / 1000.0) for v in com)
    return (f'<inertial><origin xyz="{xyz}" rpy="0 0 0"/><mass value="{m!r}"/>'
            '<inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>')


def dh_chain_urdf(path: Path, convention: str, rows: list[dict], *, name: str = "arm",
                  tool=(0.0, 0.0, 0.0), joint_names: list[str] | None = None,
                  rng: np.random.Generator | None = None, split_fixed: bool = False,
                  masses: list | None = None, root: str = "base_link",
                  mount: np.ndarray | None = None) -> Path:
    """Write a URDF whose chain base_link -> ... -> tool0 has the kinematics of a DH table.

    rows : dicts with a, alpha, d, theta_offset, beta (mm, deg), min, max (deg or mm) and
        optional type ("prismatic")
    rng : turn every link frame by a random rotation (axes no longer z)
    split_fixed : put a fixed joint with a random offset before every movable joint
    masses : per joint (mass_kg, com in that joint's DH/MDH frame, mm), or None
    mount : root_T_(DH base frame), mm; default identity
    """
    N = len(rows)
    names = joint_names or [f"joint{i + 1}" for i in range(N)]
    C = [np.eye(4) for _ in range(N + 1)]
    if rng is not None:
        C = [np.eye(4)] + [random_rotation(rng) for _ in range(N)]
    links = [f'<link name="{root}"/>']
    joints = []
    parent = root
    prev_tail = np.eye(4) if mount is None else mount
    for i, r in enumerate(rows):
        th, al, be = (math.radians(r.get(k, 0.0)) for k in ("theta_offset", "alpha", "beta"))
        if convention == "dh":
            O = prev_tail @ rot("z", th) @ trans(z=r["d"])
            tail = trans(x=r["a"]) @ rot("x", al) @ rot("y", be)
            dh_frame = tail  # DH frame i = link frame i . tail
        else:
            O = prev_tail @ rot("x", al) @ trans(x=r["a"]) @ rot("y", be) @ rot("z", th) \
                @ trans(z=r["d"])
            tail = np.eye(4)
            dh_frame = np.eye(4)
        Oc = np.linalg.inv(C[i]) @ O @ C[i + 1]
        if split_fixed:
            S = random_rotation(rng or np.random.default_rng(i)) @ trans(*(
                (rng or np.random.default_rng(i)).normal(0, 50, 3)))
            links.append(f'<link name="mount{i + 1}"/>')
            joints.append(f'<joint name="fix{i + 1}" type="fixed"><parent link="{parent}"/>'
                          f'<child link="mount{i + 1}"/>{origin_xml(S)}</joint>')
            parent = f"mount{i + 1}"
            Oc = np.linalg.inv(S) @ Oc
        axis = [float(v) for v in C[i + 1][:3, :3].T @ [0.0, 0.0, 1.0]]
        kind = r.get("type") or "revolute"
        scale = 1000.0 if kind == "prismatic" else 180.0 / math.pi
        lim = f'<limit lower="{r["min"] / scale!r}" upper="{r["max"] / scale!r}" ' \
              'effort="100" velocity="1"/>'
        inertial = ""
        if masses is not None and masses[i] is not None:
            m, com = masses[i]
            com_link = (np.linalg.inv(C[i + 1]) @ dh_frame @ [*com, 1.0])[:3]
            inertial = _inertial((m, com_link))
        links.append(f'<link name="link{i + 1}">{inertial}</link>')
        joints.append(
            f'<joint name="{names[i]}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="link{i + 1}"/>{origin_xml(Oc)}'
            f'<axis xyz="{axis[0]!r} {axis[1]!r} {axis[2]!r}"/>{lim}</joint>')
        parent = f"link{i + 1}"
        prev_tail = tail
    links += ['<link name="flange"/>', '<link name="tool0"/>']
    joints.append(f'<joint name="flange_joint" type="fixed"><parent link="{parent}"/>'
                  f'<child link="flange"/>{origin_xml(np.linalg.inv(C[N]) @ prev_tail)}</joint>')
    joints.append('<joint name="tool0_joint" type="fixed"><parent link="flange"/>'
                  f'<child link="tool0"/>{origin_xml(trans(*tool))}</joint>')
    path = Path(path)
    path.write_text(f'<?xml version="1.0"?>\n<robot name="{name}">\n  '
                    + "\n  ".join(links + joints) + "\n</robot>\n")
    return path


UR_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
UR_LINKS = ["shoulder_link", "upper_arm_link", "forearm_link", "wrist_1_link",
            "wrist_2_link", "wrist_3_link"]


def ur_style_urdf(path: Path, model) -> Path:
    """A URDF laid out like ur_description's ur_macro.xacro for a standard-DH UR model:
    base_link -> base_link_inertia (turned 180 deg about z) -> shoulder ... wrist_3 ->
    flange -> tool0, the ROS-Industrial ``base`` and ``ft_frame`` beside them; every joint
    origin is UR's split of the DH chain (a, alpha, beta of one row with theta, d of the next),
    as the UR calibration tool writes it; inertials from the model's mass model."""
    t = model.dh_table()
    links = ['<link name="base_link"/>', '<link name="base_link_inertia"/>',
             '<link name="base"/>', '<link name="flange"/>', '<link name="tool0"/>',
             '<link name="ft_frame"/>']
    joints = [
        '<joint name="base_link-base_link_inertia" type="fixed"><parent link="base_link"/>'
        '<child link="base_link_inertia"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/>'
        '</joint>',
        '<joint name="base_link-base_fixed_joint" type="fixed"><parent link="base_link"/>'
        '<child link="base"/><origin xyz="0 0 0" rpy="0 0 3.141592653589793"/></joint>',
    ]
    parent = "base_link_inertia"
    tail = np.eye(4)
    for i in range(6):
        O = tail @ rot("z", t[i, 0]) @ trans(z=t[i, 1])
        tail = trans(x=t[i, 2]) @ rot("x", t[i, 3]) @ rot("y", t[i, 4])
        j = model.joints[i]
        inertial = ""
        if model.links:
            # the DH frame i is link frame i . tail_i: the centre in the link frame
            com = (tail @ [*model.links[i].com, 1.0])[:3]
            inertial = _inertial((model.links[i].mass_kg, com))
        links.append(f'<link name="{UR_LINKS[i]}">{inertial}</link>')
        joints.append(
            f'<joint name="{UR_JOINTS[i]}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{UR_LINKS[i]}"/>{origin_xml(O)}<axis xyz="0 0 1"/>'
            f'<limit lower="{math.radians(j.min)!r}" upper="{math.radians(j.max)!r}" '
            'effort="330" velocity="2.09"/></joint>')
        parent = UR_LINKS[i]
    joints += [
        '<joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/>'
        '<child link="flange"/><origin xyz="0 0 0" rpy="0 -1.5707963267948966 '
        '-1.5707963267948966"/></joint>',
        '<joint name="flange-tool0" type="fixed"><parent link="flange"/><child link="tool0"/>'
        '<origin xyz="0 0 0" rpy="1.5707963267948966 0 1.5707963267948966"/></joint>',
        '<joint name="wrist_3_link-ft_frame" type="fixed"><parent link="wrist_3_link"/>'
        '<child link="ft_frame"/><origin xyz="0 0 0" rpy="3.141592653589793 0 0"/></joint>',
    ]
    path = Path(path)
    path.write_text('<?xml version="1.0"?>\n<robot name="ur10e_urdf">\n  '
                    + "\n  ".join(links + joints) + "\n</robot>\n")
    return path


def urdf_tip_poses(path, root: str, tip: str, q: np.ndarray) -> np.ndarray:
    """root_T_tip (n, 4, 4, mm) from yourdfpy's own forward kinematics."""
    import yourdfpy

    u = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    out = []
    for qi in np.atleast_2d(q):
        u.update_cfg(qi)
        T = np.array(u.get_transform(tip, root), float)
        T[:3, 3] *= 1000.0
        out.append(T)
    return np.array(out)
