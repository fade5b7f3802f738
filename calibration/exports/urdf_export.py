"""A calibrated model written as a URDF, with the parity check through yourdfpy.

The identified geometry goes into the joint origins themselves (not into
``<calibration>`` tags, which carry only reference positions): each movable joint turns
(or slides) about the z axis of its own frame, and its ``<origin>`` is the fixed part of
the DH/MDH chain between the previous joint and this one:

- ``dh``:  origin_i = Tx(a_{i-1}) Rx(alpha_{i-1}) Ry(beta_{i-1}) · Rz(theta_i) Tz(d_i),
  then ``flange`` = Tx(a_N) Rx(alpha_N) Ry(beta_N) after the last joint;
- ``mdh``: origin_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Ry(beta_i) Rz(theta_i) Tz(d_i), and
  ``flange`` is the last joint's own frame;

(a joint's rotation about z commutes with Rz(theta_i) Tz(d_i), so origin · Rz(q) is the
chain exactly). The file ends in a link ``tcp`` at the measured point (the identified
tool) with the flange's orientation. A model read from a URDF keeps its root link name,
its joint names (so joint states and controllers still match) and its mount.

Only the robot's fixed kinematics fit a URDF: the base (the robot in the tracker frame)
belongs to the cell, and pose-dependent effects (compliance, harmonics, backlash,
thermal...) have no URDF element; they are listed in the notes as not exported. Link
frames are the DH/MDH frames, not the original link frames, and the file carries no
visuals or inertials.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import numpy.typing as npt

from ..files import write_atomic
from ..model.dh_conversion import rot_x, rot_y, rot_z, urdf_rpy
from ..model.kinematics import ALPHA, BETA, PRISMATIC_MM_PER_UNIT, THETA, A, D
from ..model.robot_model import RobotModel
from ..model.urdf_model import mount_transform
from .parity import Parity, compare, parity_joints

TCP_LINK = "tcp"
FLANGE_LINK = "flange"


def _T(R: npt.ArrayLike | None = None, p: npt.ArrayLike | None = None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def chain_origins(model: RobotModel) -> tuple[list[np.ndarray], np.ndarray]:
    """Joint origins (each (4, 4), mm, in the previous joint's frame) and the flange.

    The first origin is in the model's base frame.
    """
    t = model.dh_table()
    origins = []
    tail = np.eye(4)
    for row in t:
        spin = _T(rot_z(row[THETA])) @ _T(p=[0.0, 0.0, row[D]])
        if model.convention == "dh":
            origins.append(tail @ spin)
            tail = _T(p=[row[A], 0.0, 0.0]) @ _T(rot_x(row[ALPHA])) @ _T(rot_y(row[BETA]))
        else:
            origins.append(_T(rot_x(row[ALPHA])) @ _T(p=[row[A], 0.0, 0.0])
                           @ _T(rot_y(row[BETA])) @ spin)
    return origins, tail


def origin_xml(T: np.ndarray) -> str:
    """``<origin>`` of a transform in mm: xyz in m, URDF rpy in rad, full precision."""
    roll, pitch, yaw = urdf_rpy(T[:3, :3])
    xyz = " ".join(repr(float(v) / 1000.0) for v in T[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{roll!r} {pitch!r} {yaw!r}"/>'


def joint_names(model: RobotModel) -> list[str]:
    if model.urdf is not None:
        return list(model.urdf.joints)
    return [f"joint{i + 1}" for i in range(model.n_joints)]


def root_link(model: RobotModel) -> str:
    return model.urdf.root if model.urdf is not None else "base_link"


def urdf_text(model: RobotModel, notes: Sequence[str] = ()) -> str:
    """The URDF of a (calibrated) model; ``notes`` go into a comment at the top."""
    origins, flange = chain_origins(model)
    root = root_link(model)
    names = joint_names(model)
    links = [root]
    joints = []
    parent = root
    mount = mount_transform(model)
    if not np.allclose(mount, np.eye(4), rtol=0, atol=0):
        links.append("cellcal_base")
        joints.append(_fixed("cellcal_mount", root, "cellcal_base", mount))
        parent = "cellcal_base"
    prismatic = model.prismatic_mask()
    for i, (O, j) in enumerate(zip(origins, model.joints, strict=True)):
        child = f"link{i + 1}"
        links.append(child)
        slide = prismatic is not None and prismatic[i]
        scale = PRISMATIC_MM_PER_UNIT / 1000.0 if slide else 1.0  # internal unit -> m
        lo, hi = (float(v) for v in np.radians([j.min, j.max]) * scale)
        joints.append(
            f'  <joint name={quoteattr(names[i])} type="{"prismatic" if slide else "revolute"}">'
            f"\n    <parent link={quoteattr(parent)}/>\n    <child link={quoteattr(child)}/>"
            f'\n    {origin_xml(O)}\n    <axis xyz="0 0 1"/>'
            f'\n    <limit lower="{lo!r}" upper="{hi!r}" effort="0" velocity="0"/>'
            "\n  </joint>")
        parent = child
    links += [FLANGE_LINK, TCP_LINK]
    joints.append(_fixed("flange_joint", parent, FLANGE_LINK, flange))
    joints.append(_fixed("tcp_joint", FLANGE_LINK, TCP_LINK,
                         _T(R=model.tool_R(), p=model.tool_mm())))
    head = "\n".join(f"  <!-- {_comment(n)} -->" for n in notes)
    body = "\n".join(f"  <link name={quoteattr(n)}/>" for n in links) + "\n" + "\n".join(joints)
    return (f'<?xml version="1.0"?>\n<robot name={quoteattr(model.name)}>\n'
            + (head + "\n" if head else "") + body + "\n</robot>\n")


def _comment(text: str) -> str:
    return text.replace("--", "- -")


def _fixed(name: str, parent: str, child: str, T: np.ndarray) -> str:
    return (f'  <joint name={quoteattr(name)} type="fixed">\n    <parent link={quoteattr(parent)}/>'
            f"\n    <child link={quoteattr(child)}/>\n    {origin_xml(T)}\n  </joint>")


def urdf_joint_values(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """Joint values as a URDF takes them (rad, m) from internal ones (rad; prismatic
    internal units)."""
    q = np.array(q, float)
    mask = model.prismatic_mask()
    if mask is not None:
        q[:, mask] *= PRISMATIC_MM_PER_UNIT / 1000.0
    return q


def yourdfpy_poses(path: str | Path, root: str, link: str, q_urdf: np.ndarray) -> np.ndarray:
    """root_T_link (n, 4, 4), mm, by yourdfpy's own forward kinematics of the file."""
    import yourdfpy

    u = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    out = np.empty((len(q_urdf), 4, 4))
    for k, qi in enumerate(q_urdf):
        u.update_cfg(qi)
        out[k] = u.get_transform(link, root)
    out[:, :3, 3] *= 1000.0
    return out


def urdf_parity(path: str | Path, model: RobotModel, n: int | None = None) -> Parity:
    """Load the written URDF with yourdfpy and compare its ``tcp`` with the model's tool
    point and tool frame's orientation at random joint sets (root frame)."""
    q = parity_joints(model) if n is None else parity_joints(model, n)
    T = yourdfpy_poses(path, root_link(model), TCP_LINK, urdf_joint_values(model, q))
    # the file's root is the model's base turned by the mount: compare in the base frame
    M = np.linalg.inv(mount_transform(model))
    P = T[:, :3, 3] @ M[:3, :3].T + M[:3, 3]
    R = M[:3, :3] @ T[:, :3, :3]
    max_mm, max_rad = compare(model, q, P, R, tcp=True)
    return Parity(str(path), "yourdfpy", len(q), max_mm, max_rad)


def write_urdf(model: RobotModel, path: str | Path, notes: Sequence[str] = ()) -> Parity:
    """Write the calibrated model as a URDF and check it by yourdfpy (see module doc)."""
    write_atomic(path, urdf_text(model, notes))
    return urdf_parity(path, model)


def mount_note(model: RobotModel) -> list[str]:
    if model.urdf is None or not any(model.urdf.mount_xyz + model.urdf.mount_rpy):
        return []
    return [f"the model's base frame sits at xyz {list(model.urdf.mount_xyz)} mm, rpy "
            f"{[round(v, 9) for v in model.urdf.mount_rpy]} deg in {model.urdf.root!r} "
            "(joint cellcal_mount)"]
