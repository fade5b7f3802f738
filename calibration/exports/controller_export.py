"""Controller-side exports of a calibrated model, each read back and checked for parity:

- the UR ROS driver's kinematics YAML (``ur_description``'s ``default_kinematics.yaml``
  format, as ``ur_calibration`` writes it): ``kinematics: {shoulder: {x, y, z, roll,
  pitch, yaw}, upper_arm, forearm, wrist_1, wrist_2, wrist_3, hash}``. Each entry is the
  origin of one joint (m, URDF rpy in rad) in ur_description's chain ``base_link_inertia ->
  shoulder_link -> ... -> wrist_3_link``; ``tool0`` is ``wrist_3_link`` itself. ``hash``
  is the checksum the UR driver computes from the controller's DH parameters
  (``calib_`` + libstdc++'s ``std::hash`` of the values printed with 6 significant
  digits); it is computed for the pure-DH form of the calibrated chain, i.e. for a
  controller that carries the matching ``calibration.conf``, so the driver's check
  passes there.
- DH/MDH tables as CSV (``theta_offset_deg, d_mm, a_mm, alpha_deg, beta_deg``...), the
  convention, its formula and the tool point in ``#`` comment lines.
- the parity line for UR ``calibration.conf`` (:mod:`calibration.exports.ur_conf` writes it).

Parity readers: the kinematics YAML is assembled the way ur_description's xacro does
(joint origins from the YAML, ``wrist_3 -> flange -> tool0`` fixed joints) into a URDF and
evaluated by yourdfpy; the CSV and calibration.conf are parsed back into a table and
evaluated by :func:`calibration.model.kinematics.run_chain` from those numbers alone.
"""

from __future__ import annotations

import csv
import io
import math
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..errors import ExportError
from ..model.dh_conversion import dh_from_axes, rot_z, urdf_rpy
from ..model.kinematics import ALPHA, BETA, THETA, A, D, forward, run_chain
from ..model.robot_model import RobotModel
from ..model.urdf_model import mount_transform
from .parity import Parity, compare, parity_joints
from .ur_conf import read_calibration_conf, table_from_deltas, to_pure_dh
from .urdf_export import _T, chain_origins, write_atomic, yourdfpy_poses

#: link names of the UR kinematics YAML, base to wrist 3
UR_LINKS = ("shoulder", "upper_arm", "forearm", "wrist_1", "wrist_2", "wrist_3")


# ---- the UR driver's hash -----------------------------------------------------------------
_MASK = (1 << 64) - 1


def _shift_mix(v: int) -> int:
    return v ^ (v >> 47)


def libstdcxx_hash(data: bytes, seed: int = 0xC70F6907) -> int:
    """``std::hash<std::string>`` of GCC's libstdc++ on 64-bit (``_Hash_bytes``,
    MurmurHash64A-style)."""
    mul = (0xC6A4A793 << 32) + 0x5BD1E995
    n = len(data)
    h = (seed ^ (n * mul)) & _MASK
    aligned = n & ~7
    for k in range(0, aligned, 8):
        word = int.from_bytes(data[k:k + 8], "little")
        h ^= (_shift_mix((word * mul) & _MASK) * mul) & _MASK
        h = (h * mul) & _MASK
    if n & 7:
        h ^= int.from_bytes(data[aligned:], "little")
        h = (h * mul) & _MASK
    h = (_shift_mix(h) * mul) & _MASK
    return _shift_mix(h)


def ur_kinematics_hash(table: np.ndarray) -> str:
    """The UR driver's ``calib_...`` checksum of a pure-DH table (rad, mm): per joint
    theta, d, a, alpha in m and rad, each printed like a C++ stream (``%g``)."""
    t = np.asarray(table, float)
    text = "".join(f"{t[i, THETA]:g}{t[i, D] / 1000.0:g}{t[i, A] / 1000.0:g}{t[i, ALPHA]:g}"
                   for i in range(6))
    return f"calib_{libstdcxx_hash(text.encode())}"


# ---- the UR kinematics YAML -------------------------------------------------------------------
def ur_base_transform(model: RobotModel) -> np.ndarray:
    """base_link_inertia_T_base (4, 4, mm): where ur_description's chain starts, seen from the
    model's base frame. A standard UR model's base is the controller's base, which is
    base_link_inertia; a model read from a UR URDF knows its root."""
    if model.urdf is None or model.urdf.root == "base_link_inertia":
        return mount_transform(model)
    if model.urdf.root == "base_link":  # ur_description: base_link_inertia = base_link . Rz(pi)
        return _T(rot_z(math.pi)).T @ mount_transform(model)
    raise ExportError(f"the UR kinematics YAML starts at base_link_inertia; the model's root "
                      f"is {model.urdf.root!r}: load the URDF as FILE.urdf#base_link:TIP "
                      "or #base_link_inertia:TIP")


def ur_table(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """(table (6, 5) rad mm, tool (3,) mm): the model's chain in a UR controller's own DH
    convention, from base_link_inertia. A built-in (or YAML) UR model already is; a model
    read from a UR URDF has its own frames (e.g. from ``base_link``, turned 180 deg): its
    axes are re-expressed from base_link_inertia by the same conversion as a URDF
    (:func:`calibration.model.urdf_model.dh_from_axes`), which gives UR's table for UR's axes."""
    _check_ur(model)
    if model.urdf is None:
        return model.dh_table(), model.tool_mm()
    F = ur_base_transform(model) @ forward(model, np.zeros(6))[0]  # frames, base_link_inertia
    mount, table, frames, _ = dh_from_axes(F[:-1, :3, 3], F[:-1, :3, 2], F[-1])
    if not np.allclose(mount, np.eye(4), rtol=0, atol=1e-9):
        raise ExportError("joint 1's axis is not base_link_inertia's z axis: the chain has no "
                          "UR DH form")
    R, p = frames[-1]
    tool = R.T @ (F[-1] @ [*model.tool_mm(), 1.0])[:3] - R.T @ p
    return table, tool


def _check_ur(model: RobotModel) -> None:
    if model.n_joints != 6 or model.convention != "dh" or model.prismatic_mask() is not None:
        raise ExportError(f"the UR kinematics YAML needs a 6-joint revolute standard-DH model "
                          f"(model {model.name}: {model.n_joints} joints, {model.convention})")


def ur_model(model: RobotModel) -> RobotModel:
    """The model with its chain in the controller's DH convention (:func:`ur_table`),
    based at base_link_inertia: its link frames are ur_description's."""
    from .ur_conf import model_from_table

    if model.urdf is None:
        _check_ur(model)
        return model
    table, tool = ur_table(model)
    return model_from_table(model, table, tool=tool).with_changes(urdf=None)


def ur_kinematics(model: RobotModel) -> tuple[dict, np.ndarray]:
    """The YAML mapping and the tool point in tool0 (mm).

    The last row's a, alpha, beta (the flange frame seen from the last joint) have no place
    in the YAML: ur_description's tool0 is wrist_3_link's frame; the tool point is
    returned in that frame instead.
    """
    ur = ur_model(model)
    origins, flange = chain_origins(ur)
    kin: dict[str, Any] = {}
    for name, O in zip(UR_LINKS, origins, strict=True):
        roll, pitch, yaw = urdf_rpy(O[:3, :3])
        kin[name] = {"x": float(O[0, 3]) / 1000.0, "y": float(O[1, 3]) / 1000.0,
                     "z": float(O[2, 3]) / 1000.0, "roll": roll, "pitch": pitch, "yaw": yaw}
    kin["hash"] = ur_kinematics_hash(to_pure_dh(ur.dh_table()))
    tool0_p_tcp = (flange @ [*ur.tool_mm(), 1.0])[:3]
    return {"kinematics": kin}, tool0_p_tcp


def ur_kinematics_yaml(model: RobotModel, notes: Sequence[str] = ()) -> tuple[str, np.ndarray]:
    """(YAML text, tool point in tool0 mm)."""
    data, tcp = ur_kinematics(model)
    head = ["kinematics of the calibrated robot for ur_description (kinematics_params_file)",
            f"TCP (the measured point) in tool0: {[round(float(v), 6) for v in tcp]} mm",
            *notes]
    text = "".join(f"# {n}\n" for n in head)
    return text + yaml.safe_dump(data, sort_keys=False), tcp


_UR_TAIL = (
    '<link name="flange"/><link name="tool0"/><link name="tcp"/>'
    '<joint name="wrist_3-flange" type="fixed"><parent link="wrist_3_link"/>'
    '<child link="flange"/><origin xyz="0 0 0" rpy="0 -1.5707963267948966 -1.5707963267948966"/>'
    '</joint><joint name="flange-tool0" type="fixed"><parent link="flange"/>'
    '<child link="tool0"/><origin xyz="0 0 0" rpy="1.5707963267948966 0 1.5707963267948966"/>'
    "</joint>")


def ur_description_urdf(kinematics: dict, tcp_mm: np.ndarray) -> str:
    """A URDF assembled from a kinematics mapping the way ur_description's ur_macro.xacro
    does (chain from base_link_inertia), with a ``tcp`` link at ``tcp_mm`` in tool0."""
    names = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
             "wrist_2_joint", "wrist_3_joint"]
    parts = ['<link name="base_link_inertia"/>']
    parent = "base_link_inertia"
    for joint, link in zip(names, UR_LINKS, strict=True):
        k = kinematics[link]
        parts.append(
            f'<link name="{link}_link"/><joint name="{joint}" type="revolute">'
            f'<parent link="{parent}"/><child link="{link}_link"/>'
            f'<origin xyz="{k["x"]!r} {k["y"]!r} {k["z"]!r}" '
            f'rpy="{k["roll"]!r} {k["pitch"]!r} {k["yaw"]!r}"/><axis xyz="0 0 1"/>'
            '<limit lower="-6.283185307179586" upper="6.283185307179586" effort="1" '
            'velocity="1"/></joint>')
        parent = f"{link}_link"
    tcp = " ".join(repr(float(v) / 1000.0) for v in tcp_mm)
    parts.append(_UR_TAIL + '<joint name="tool0-tcp" type="fixed"><parent link="tool0"/>'
                 f'<child link="tcp"/><origin xyz="{tcp}" rpy="0 0 0"/></joint>')
    return '<?xml version="1.0"?>\n<robot name="ur">' + "".join(parts) + "</robot>\n"


def ur_yaml_parity(path: str | Path, model: RobotModel) -> Parity:
    """Read the YAML back, assemble ur_description's chain and compare by yourdfpy."""
    kin = yaml.safe_load(Path(path).read_text())["kinematics"]
    tcp = ur_kinematics(model)[1]  # the measured point is not part of the YAML
    q = parity_joints(model)
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "ur_description.urdf"
        f.write_text(ur_description_urdf(kin, tcp))
        T = yourdfpy_poses(f, "base_link_inertia", "tcp", q)
    B = np.linalg.inv(ur_base_transform(model))  # back to the model's base frame
    P = T[:, :3, 3] @ B[:3, :3].T + B[:3, 3]
    R = B[:3, :3] @ T[:, :3, :3]
    # tool0 (= wrist_3) is the flange only when the last row has no a, alpha, beta
    _, flange = chain_origins(ur_model(model))
    max_mm, max_rad = compare(model, q, P, R @ flange[:3, :3])
    return Parity(str(path), "ur_description chain (yourdfpy)", len(q), max_mm, max_rad)


def write_ur_kinematics_yaml(model: RobotModel, path: str | Path,
                             notes: Sequence[str] = ()) -> Parity:
    text, _ = ur_kinematics_yaml(model, notes)
    write_atomic(path, text)
    return ur_yaml_parity(path, model)


# ---- DH / MDH tables as CSV -------------------------------------------------------------------
_FORMULA = {"dh": "T_i = Rz(theta_offset + q) Tz(d) Tx(a) Rx(alpha) Ry(beta)",
            "mdh": "T_i = Rx(alpha) Tx(a) Ry(beta) Rz(theta_offset + q) Tz(d); a, alpha are "
                   "a_{i-1}, alpha_{i-1}"}
CSV_COLUMNS = ("joint", "name", "type", "theta_offset_deg", "d_mm", "a_mm", "alpha_deg",
               "beta_deg", "min", "max", "limit_unit")


def table_csv(model: RobotModel, notes: Sequence[str] = ()) -> str:
    """The model's kinematic table as CSV, full precision."""
    t = model.dh_table()
    names = (list(model.urdf.joints) if model.urdf is not None
             else [f"joint{i + 1}" for i in range(model.n_joints)])
    buf = io.StringIO()
    for line in (f"convention: {model.convention}", f"formula: {_FORMULA[model.convention]}",
                 "prismatic joints slide: d + q (mm) instead of turning by q",
                 "tool_mm: " + ", ".join(repr(float(v)) for v in model.tool_mm()),
                 f"model: {model.name}", *notes):
        buf.write(f"# {line}\n")
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for i, (row, j) in enumerate(zip(t, model.joints, strict=True)):
        kind = j.type or "revolute"
        w.writerow([i + 1, names[i], kind, repr(math.degrees(row[THETA])), repr(float(row[D])),
                    repr(float(row[A])), repr(math.degrees(row[ALPHA])),
                    repr(math.degrees(row[BETA])), repr(float(j.min)), repr(float(j.max)),
                    "mm" if kind == "prismatic" else "deg"])
    return buf.getvalue()


def read_table_csv(path: str | Path) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """(convention, table (N, 5) rad mm, tool (3,) mm, prismatic (N,) bool) from a table CSV."""
    lines = Path(path).read_text().splitlines()
    meta = dict(line[2:].split(": ", 1) for line in lines if line.startswith("# ") and ": "
                in line)
    rows = list(csv.DictReader(line for line in lines if not line.startswith("#")))
    table = np.array([[math.radians(float(r["theta_offset_deg"])), float(r["d_mm"]),
                       float(r["a_mm"]), math.radians(float(r["alpha_deg"])),
                       math.radians(float(r["beta_deg"]))] for r in rows])
    tool = np.array([float(v) for v in meta["tool_mm"].split(",")])
    prismatic = np.array([r["type"] == "prismatic" for r in rows])
    return meta["convention"], table, tool, prismatic


def table_parity(path: str | Path, model: RobotModel) -> Parity:
    convention, table, tool, prismatic = read_table_csv(path)
    q = parity_joints(model)
    r = run_chain(convention, table, q, tool, jacobian=False, prismatic=prismatic)
    max_mm, max_rad = compare(model, q, r.base_p_tcp, r.base_R_flange)
    return Parity(str(path), "table CSV", len(q), max_mm, max_rad)


def write_table_csv(model: RobotModel, path: str | Path, notes: Sequence[str] = ()) -> Parity:
    write_atomic(path, table_csv(model, notes))
    return table_parity(path, model)


# ---- UR calibration.conf ----------------------------------------------------------------
def ur_conf_parity(path: str | Path, model: RobotModel, nominal: RobotModel) -> Parity:
    """calibration.conf read back, added to the nominal pure-DH table as a UR controller
    does, against the calibrated model (tool point; flange orientation)."""
    table = table_from_deltas(ur_table(nominal)[0], read_calibration_conf(path))
    q = parity_joints(model)
    r = run_chain("dh", table, q, ur_table(model)[1], jacobian=False)
    B = np.linalg.inv(ur_base_transform(model))  # base_link_inertia -> the model's base
    P = r.base_p_tcp @ B[:3, :3].T + B[:3, 3]
    max_mm, max_rad = compare(model, q, P, B[:3, :3] @ r.base_R_flange)
    return Parity(str(path), "calibration.conf + nominal DH", len(q), max_mm, max_rad)
