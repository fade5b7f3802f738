"""A :class:`~calibration.robot_model.RobotModel` from the serial chain of a URDF.

``load_model("robot.urdf#base_link:tool0")`` (and ``"robot.urdf"`` alone when the chain
is unambiguous) parses the file with yourdfpy, takes the chain of joints from the root
link to the tip link, folds the fixed joints in and converts the chain, exactly, into a
standard Denavit–Hartenberg table with the Hayati tilt beta where neighbouring axes are
parallel — the same table every built-in model has.

Parameterisation (the design decision)
--------------------------------------
Error parameters are expressed on that DH/Hayati table, not on the URDF's own joint
origins (xyz + rpy per joint). A joint origin has six numbers, but a revolute axis in
space has four independent ones (two for a prismatic joint): the other two per joint
(a turn about and a slide along the axis) are exact redundancies with the neighbouring
origins that identification would have to detect and freeze every time, and the
numbers identified for them would depend on arbitrary choices of link frames. The DH
table with beta is minimal and its parameters mean the same thing for every robot:
d, a, alpha, theta_offset per joint, beta where axes are (nearly) parallel and the
common normal is ill-defined. It is also what every other part of cellcal already
works with — identification, identifiability, diagnosis, compensation and the UR
exports — so a URDF robot needs no new code path. The conversion is exact (forward
kinematics agrees with the URDF to rounding), and :mod:`calibration.urdf_export` turns
the calibrated table back into joint origins.

Conversion rules
----------------
- The model's base frame is the root link, unless joint 1's axis is not the root's z
  axis; then it is a frame on that axis and ``urdf.mount_xyz``/``mount_rpy`` hold its
  pose in the root link (gravity is turned into that frame).
- Row i goes from joint i's axis to joint i+1's along their common normal, its x axis
  signed so that theta_offset is smallest (a may be negative, as in UR's tables). Axes
  within ``PARALLEL_SIN`` (~3 deg) of parallel use the Hayati form instead: d = 0, the
  normal in the plane through the previous origin, the small tilt in alpha and beta (such
  a row counts as parallel: the geometric effect identifies its beta).
- The last row points the flange frame like the tip link (a = 0; theta, alpha, beta
  are the rotation) and puts its origin on the last axis level with the tip; ``tool``
  is the tip's origin in that frame.
- Joint limits come from ``<limit>`` (continuous joints: +-360 deg); a prismatic
  joint's limits and position are in mm where angles are in deg (see
  :mod:`calibration.kinematics`).
- The mass model comes from the ``<inertial>`` elements: every link that moves with
  joint k (fixed children and side branches at their zero position included) is one
  mass at its combined centre, in that joint's DH frame; links before joint 1 do not
  move and are left out. No inertial anywhere: no mass model.

Lengths mm and angles rad inside; URDF files are in metres and radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .robot_model import ModelError, RobotModel, model_from_dict

#: sin of the angle below which two neighbouring axes use the Hayati (beta) form: within
#: ~3 deg their common normal is far away (>= 20 x the axes' distance) and ill-conditioned
PARALLEL_SIN = 0.05
#: lengths (mm) and angles (rad) smaller than this are rounding and written as 0
_SNAP_MM, _SNAP_RAD = 1e-9, 1e-12
_MOVABLE = ("revolute", "continuous", "prismatic")
_KNOWN = (*_MOVABLE, "fixed", "floating", "planar")


class UrdfError(ModelError):
    """A URDF (or a chain in it) that cannot be used; the message names the element."""


def is_urdf_spec(text: str) -> bool:
    """True for ``path.urdf`` and ``path.urdf#root:tip``."""
    return str(text).split("#", 1)[0].lower().endswith(".urdf")


def parse_spec(text: str) -> tuple[str, str | None, str | None]:
    """``"robot.urdf#base_link:tool0"`` -> (path, root, tip); missing parts are None."""
    path, _, chain = str(text).partition("#")
    root, _, tip = chain.partition(":")
    return path, root or None, tip or None


# ---- reading the file -------------------------------------------------------------------
def _check_xml(path: str) -> None:
    """Strict XML parse and the structure yourdfpy needs; errors name line and element."""
    from lxml import etree

    try:
        root = etree.parse(path, etree.XMLParser(remove_blank_text=True)).getroot()
    except etree.XMLSyntaxError as e:
        raise UrdfError(f"{path}: line {e.lineno}: malformed XML: {e.msg}") from None
    except OSError as e:
        raise UrdfError(f"{path}: cannot be read: {e}") from None
    if root.tag != "robot":
        raise UrdfError(f"{path}: line {root.sourceline}: the root element is <{root.tag}>, "
                        "not <robot>")
    for el in root.iter("link", "joint"):
        where = f"{path}: line {el.sourceline}: <{el.tag}>"
        if not el.get("name"):
            raise UrdfError(f"{where} has no name")
        if el.tag == "joint":
            where = f"{path}: line {el.sourceline}: joint {el.get('name')!r}"
            if el.get("type") not in _KNOWN:
                raise UrdfError(f"{where}: type {el.get('type')!r} is not one of "
                                f"{', '.join(_KNOWN)}")
            for tag in ("parent", "child"):
                sub = el.find(tag)
                if sub is None or not sub.get("link"):
                    raise UrdfError(f"{where} has no <{tag} link=...>")


def _load(path: str):
    if not Path(path).is_file():
        raise UrdfError(f"{path}: no such URDF file")
    _check_xml(path)
    import yourdfpy

    try:
        return yourdfpy.URDF.load(path, build_scene_graph=False, load_meshes=False,
                                  build_collision_scene_graph=False,
                                  load_collision_meshes=False)
    except Exception as e:  # yourdfpy raises bare ValueErrors, KeyErrors...
        raise UrdfError(f"{path}: not a usable URDF: {type(e).__name__}: {e}") from None


@dataclass
class _Tree:
    """The kinematic tree of a URDF: joints by child link, children by parent link."""

    path: str
    name: str
    links: dict
    joints: dict  # name -> yourdfpy Joint
    parent_joint: dict  # child link -> joint
    children: dict  # parent link -> [joints]

    @classmethod
    def of(cls, path: str, urdf) -> _Tree:
        links = {l.name: l for l in urdf.robot.links}
        joints, parent_joint, children = {}, {}, {}
        for j in urdf.robot.joints:
            for role, link in (("parent", j.parent), ("child", j.child)):
                if link not in links:
                    raise UrdfError(f"{path}: joint {j.name!r} names {role} link {link!r}, "
                                    "which is not declared (missing <link>)")
            if j.child in parent_joint:
                raise UrdfError(f"{path}: link {j.child!r} is the child of joints "
                                f"{parent_joint[j.child].name!r} and {j.name!r}: a loop, "
                                "not a tree")
            joints[j.name] = j
            parent_joint[j.child] = j
            children.setdefault(j.parent, []).append(j)
        name = urdf.robot.name or Path(path).stem
        tree = cls(path, name, links, joints, parent_joint, children)
        for name in links:  # every link must reach a root: otherwise it sits on a cycle
            tree.path_up(name)
        return tree

    def path_up(self, link: str, stop: str | None = None) -> list:
        """Joints from the root (or ``stop``) down to ``link``."""
        out, seen = [], {link}
        while link != stop and link in self.parent_joint:
            j = self.parent_joint[link]
            out.append(j)
            link = j.parent
            if link in seen:
                raise UrdfError(f"{self.path}: joint {j.name!r} closes a loop through link "
                                f"{link!r}: not a tree")
            seen.add(link)
        return out[::-1]

    def roots(self) -> list[str]:
        return [n for n in self.links if n not in self.parent_joint]

    def leaves(self, top: str) -> list[str]:
        out, todo = [], [top]
        while todo:
            link = todo.pop()
            kids = self.children.get(link, [])
            if not kids:
                out.append(link)
            todo.extend(j.child for j in kids)
        return out


def _pick_chain(tree: _Tree, root: str | None, tip: str | None) -> tuple[str, str, list]:
    path = tree.path
    for name, what in ((root, "root"), (tip, "tip")):
        if name is not None and name not in tree.links:
            known = ", ".join(sorted(tree.links)[:12])
            raise UrdfError(f"{path}: no {what} link {name!r} (links: {known}"
                            f"{', ...' if len(tree.links) > 12 else ''})")
    if root is None:
        roots = tree.roots()
        if len(roots) != 1:
            raise UrdfError(f"{path}: {len(roots)} root links ({', '.join(roots)}): "
                            "give the chain as FILE.urdf#ROOT:TIP")
        root = roots[0]
    if tip is None:
        moving = {}
        for leaf in tree.leaves(root):
            js = [j.name for j in tree.path_up(leaf, root) if j.type != "fixed"]
            if js:
                moving[leaf] = js
        if not moving:
            raise UrdfError(f"{path}: no movable joint below link {root!r}")
        sets = {tuple(v) for v in moving.values()}
        if len(sets) > 1:
            raise UrdfError(f"{path}: the chain below {root!r} is ambiguous (tips: "
                            f"{', '.join(sorted(moving))}): give FILE.urdf#{root}:TIP")
        # every leaf shares the movable joints: the tip is where their paths part
        paths = [[j.child for j in tree.path_up(leaf, root)] for leaf in moving]
        common = [links[0] for links in zip(*paths, strict=False) if len(set(links)) == 1]
        tip = common[-1]
    chain = tree.path_up(tip, root)
    if not chain or chain[0].parent != root:
        raise UrdfError(f"{path}: no chain from link {root!r} down to link {tip!r}")
    for j in chain:
        if j.type in ("floating", "planar"):
            raise UrdfError(f"{path}: joint {j.name!r} is {j.type}: a serial chain takes "
                            "only revolute, continuous, prismatic and fixed joints")
        if j.type in _MOVABLE and j.mimic is not None:
            raise UrdfError(f"{path}: joint {j.name!r} mimics {j.mimic.joint!r}: mimic "
                            "joints are not supported in the chain")
    if not any(j.type in _MOVABLE for j in chain):
        raise UrdfError(f"{path}: no movable joint between {root!r} and {tip!r}")
    return root, tip, chain


# ---- geometry ---------------------------------------------------------------------------
def _origin_mm(j) -> np.ndarray:
    T = np.eye(4) if j.origin is None else np.array(j.origin, float)
    T[:3, 3] *= 1000.0
    return T


def _axis(path: str, j) -> np.ndarray:
    u = np.array([1.0, 0.0, 0.0] if j.axis is None else j.axis, float)
    norm = np.linalg.norm(u)
    if not np.isfinite(norm) or norm < 1e-12:
        raise UrdfError(f"{path}: joint {j.name!r}: <axis xyz> is zero or not finite")
    return u / norm


def rot_z(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _signed_x(x_xy: np.ndarray) -> tuple[np.ndarray, float]:
    """(x, theta): the unit direction ±x_xy (in the xy plane) nearest the current x axis."""
    x = np.array([x_xy[0], x_xy[1], 0.0])
    x /= np.linalg.norm(x)
    if x[0] < -1e-12 or (abs(x[0]) <= 1e-12 and x[1] < 0):
        x = -x
    return x, math.atan2(x[1], x[0])


def _dh_row(R: np.ndarray, p: np.ndarray, o_next: np.ndarray, u_next: np.ndarray):
    """One standard-DH row from the current frame (z on this joint's axis) to the next axis.

    Returns (theta, d, a, alpha, beta) and the next frame (R, p).
    """
    u = R.T @ u_next
    o = R.T @ (o_next - p)
    s2 = u[0] * u[0] + u[1] * u[1]
    if math.sqrt(s2) > PARALLEL_SIN:  # common normal
        t2 = -(o[0] * u[0] + o[1] * u[1]) / s2
        d = o[2] + t2 * u[2]
        foot = o + t2 * u
        x, theta = _signed_x(np.array([-u[1], u[0]]))
        a = float(foot @ x)
        alpha = math.atan2(-u[1] * x[0] + u[0] * x[1], u[2])
        beta = 0.0
    else:  # Hayati: d = 0, the next axis met in the plane z = 0
        d = 0.0
        foot = o - (o[2] / u[2]) * u
        r = math.hypot(foot[0], foot[1])
        if r > _SNAP_MM:
            x, theta = _signed_x(foot[:2])
        else:
            x, theta = np.array([1.0, 0.0, 0.0]), 0.0
        a = float(foot @ x)
        v = rot_z(theta).T @ u
        beta = math.asin(max(-1.0, min(1.0, v[0])))
        alpha = math.atan2(-v[1], v[2])
    R_next = R @ rot_z(theta) @ rot_x(alpha) @ rot_y(beta)
    p_next = p + R @ np.array([0.0, 0.0, d]) + a * (R @ np.array([math.cos(theta),
                                                                  math.sin(theta), 0.0]))
    return (theta, d, a, alpha, beta), R_next, p_next


def _last_row(R: np.ndarray, p: np.ndarray, tip_T: np.ndarray):
    """The last row: flange frame turned like the tip, origin on the last axis level with it.

    Returns (theta, d, a, alpha, beta), the flange frame (R, p) and the tool point in it.
    """
    Rt = R.T @ tip_T[:3, :3]
    pt = R.T @ (tip_T[:3, 3] - p)
    d = float(pt[2])
    alpha = math.asin(max(-1.0, min(1.0, Rt[2, 1])))
    if abs(math.cos(alpha)) > 1e-9:
        beta = math.atan2(-Rt[2, 0], Rt[2, 2])
        theta = math.atan2(-Rt[0, 1], Rt[1, 1])
    else:
        beta, theta = 0.0, math.atan2(Rt[1, 0], Rt[0, 0])
    R_n = R @ rot_z(theta) @ rot_x(alpha) @ rot_y(beta)
    p_n = p + d * R[:, 2]
    return (theta, d, 0.0, alpha, beta), R_n, p_n, R_n.T @ (tip_T[:3, 3] - p_n)


def _base_frame(o1: np.ndarray, u1: np.ndarray) -> np.ndarray:
    """root_T_base: identity when joint 1's axis is the root z axis, else a frame on it."""
    T = np.eye(4)
    if np.linalg.norm(u1 - [0.0, 0.0, 1.0]) < 1e-12 and math.hypot(o1[0], o1[1]) < _SNAP_MM:
        return T
    z = u1
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - z[1] * z
    x /= np.linalg.norm(x)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = o1 - (o1 @ z) * z
    return T


def urdf_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (rad) of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.asin(max(-1.0, min(1.0, -R[2, 0]))) + 0.0  # + 0.0: no "-0.0" in files
    if abs(math.cos(pitch)) > 1e-9:
        return math.atan2(R[2, 1], R[2, 2]) + 0.0, pitch, math.atan2(R[1, 0], R[0, 0]) + 0.0
    return 0.0, pitch, math.atan2(-R[0, 1], R[1, 1]) + 0.0


def _poses_at_zero(tree: _Tree, root: str) -> dict[str, np.ndarray]:
    """root_T_link (mm) of every link below ``root`` with every joint at zero."""
    poses, todo = {root: np.eye(4)}, [root]
    while todo:
        link = todo.pop()
        for j in tree.children.get(link, []):
            poses[j.child] = poses[link] @ _origin_mm(j)
            todo.append(j.child)
    return poses


def _mass_model(tree: _Tree, root: str, chain: list, frames: list) -> list[dict] | None:
    """One mass per movable joint from the inertials of every link that moves with it."""
    poses = _poses_at_zero(tree, root)
    movable = [j for j in chain if j.type in _MOVABLE]
    owner = {}
    for k, j in enumerate(movable):  # later joints overwrite: each link gets its own body
        for link in _subtree(tree, j.child):
            owner[link] = k
    out = [{"m": 0.0, "mc": np.zeros(3)} for _ in movable]
    for link, k in owner.items():
        inertial = tree.links[link].inertial
        if inertial is None or not inertial.mass:
            continue
        T = poses[link] @ (np.eye(4) if inertial.origin is None else _scaled(inertial.origin))
        out[k]["m"] += float(inertial.mass)
        out[k]["mc"] += float(inertial.mass) * T[:3, 3]
    if not any(b["m"] > 0 for b in out):
        return None
    links = []
    for b, (R, p) in zip(out, frames, strict=True):
        com = R.T @ (b["mc"] / b["m"] - p) if b["m"] > 0 else np.zeros(3)
        links.append({"mass_kg": b["m"], "com": [round(_snap(v, _SNAP_MM), 9) for v in com]})
    return links


def _subtree(tree: _Tree, top: str) -> list[str]:
    out, todo = [], [top]
    while todo:
        link = todo.pop()
        out.append(link)
        todo.extend(j.child for j in tree.children.get(link, []))
    return out


def _scaled(T) -> np.ndarray:
    T = np.array(T, float)
    T[:3, 3] *= 1000.0
    return T


def _snap(v: float, tol: float) -> float:
    return 0.0 if abs(v) < tol else float(v)


def _limits(path: str, j) -> tuple[float, float]:
    """(min, max) in deg, or mm for a prismatic joint."""
    if j.type == "continuous":
        return -360.0, 360.0
    lim = j.limit
    if lim is None or lim.lower is None or lim.upper is None:
        raise UrdfError(f"{path}: joint {j.name!r} ({j.type}) has no <limit lower=... "
                        "upper=...>")
    lo, hi = float(lim.lower), float(lim.upper)
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo > hi:
        raise UrdfError(f"{path}: joint {j.name!r}: <limit> lower {lo} > upper {hi}")
    if j.type == "prismatic":
        return lo * 1000.0, hi * 1000.0
    return math.degrees(lo), math.degrees(hi)


# ---- the model ---------------------------------------------------------------------------
def chain_geometry(spec: str):
    """The chain of a URDF at zero joint positions, in the root frame (mm).

    Returns
    -------
    tree, root, tip, chain (yourdfpy joints, fixed ones included), movable (joints),
    origins (N, 3), axes (N, 3), tip_T (4, 4)
    """
    path, root, tip = parse_spec(spec)
    tree = _Tree.of(path, _load(path))
    root, tip, chain = _pick_chain(tree, root, tip)
    T = np.eye(4)
    origins, axes, movable = [], [], []
    for j in chain:
        T = T @ _origin_mm(j)
        if j.type in _MOVABLE:
            origins.append(T[:3, 3].copy())
            axes.append(T[:3, :3] @ _axis(path, j))
            movable.append(j)
    return tree, root, tip, chain, movable, np.array(origins), np.array(axes), T


def dh_from_axes(origins: np.ndarray, axes: np.ndarray, tip_T: np.ndarray):
    """The standard-DH/Hayati table of a chain given by its joint axes (mm, any frame F).

    Parameters
    ----------
    origins, axes : (N, 3) a point on each joint axis and its unit direction (sense of
        positive motion), at zero joint positions
    tip_T : (4, 4) F_T_tip, the frame the flange is turned like; its origin is the tool point

    Returns
    -------
    mount : (4, 4) F_T_base, identity when joint 1's axis is F's z axis
    table : (N, 5) theta_offset, d, a, alpha, beta (rad, mm), rounding snapped to 0
    frames : N (R, p), the frame after each row, in F
    tool : (3,) the tip's origin in the flange frame, mm
    """
    mount = _base_frame(origins[0], axes[0])
    R, p = mount[:3, :3].copy(), mount[:3, 3].copy()
    rows, frames = [], []
    for i in range(len(origins) - 1):
        row, R, p = _dh_row(R, p, origins[i + 1], axes[i + 1])
        rows.append(row)
        frames.append((R, p))
    row, R, p, tool = _last_row(R, p, tip_T)
    rows.append(row)
    frames.append((R, p))
    tol = np.array([_SNAP_RAD, _SNAP_MM, _SNAP_MM, _SNAP_RAD, _SNAP_RAD])
    table = np.array(rows, float)
    table[np.abs(table) < tol] = 0.0
    return mount, table, frames, np.array([_snap(v, _SNAP_MM) for v in tool])


def load_urdf_model(spec: str) -> RobotModel:
    """A RobotModel from ``path.urdf[#root[:tip]]`` (see the module docstring)."""
    path = parse_spec(spec)[0]
    tree, root, tip, chain, movable, origins, axes, tip_T = chain_geometry(spec)
    mount, table, frames, tool = dh_from_axes(origins, axes, tip_T)
    joints = []
    for (theta, d, a, alpha, beta), j in zip(table, movable, strict=True):
        lo, hi = _limits(path, j)
        row = {"a": a, "alpha": math.degrees(alpha), "d": d, "theta_offset": math.degrees(theta),
               "beta": math.degrees(beta), "min": lo, "max": hi}
        if j.type == "prismatic":
            row["type"] = "prismatic"
        joints.append(row)
    g = mount[:3, :3].T @ np.array([0.0, 0.0, -9.81])
    data = {
        "name": tree.name,
        "convention": "dh",
        "joints": joints,
        "tool": [float(v) for v in tool],
        "gravity": [_snap(v, 1e-12) for v in g],
        "urdf": {"file": path, "root": root, "tip": tip, "joints": [j.name for j in movable],
                 "mount_xyz": [_snap(v, _SNAP_MM) for v in mount[:3, 3]],
                 "mount_rpy": [math.degrees(_snap(v, _SNAP_RAD)) for v in
                               urdf_rpy(mount[:3, :3])]},
    }
    links = _mass_model(tree, root, chain, frames)
    if links is not None:
        data["links"] = links
    return model_from_dict(data, spec)


def mount_transform(model: RobotModel) -> np.ndarray:
    """root_T_base (4, 4, mm) of a model read from a URDF; identity for other models."""
    T = np.eye(4)
    if model.urdf is None:
        return T
    roll, pitch, yaw = np.radians(model.urdf.mount_rpy)
    T[:3, :3] = rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    T[:3, 3] = model.urdf.mount_xyz
    return T
