"""A :class:`~calibration.model.robot_model.RobotModel` from the serial chain of a URDF.

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
kinematics agrees with the URDF to rounding), and :mod:`calibration.exports.urdf_export` turns
the calibrated table back into joint origins.

Conversion rules (:mod:`calibration.model.dh_conversion`)
----------------------------------------------------
- The model's base frame is the root link, unless joint 1's axis is not the root's z
  axis; then it is a frame on that axis and ``urdf.mount_xyz``/``mount_rpy`` hold its
  pose in the root link (gravity is turned into that frame).
- Row i follows the common normal from joint i's axis to joint i+1's, x signed so that
  theta_offset is smallest; axes within ~3 deg of parallel take the Hayati form (d = 0,
  tilt in alpha and beta; such a row counts as parallel, so beta is identified).
- The last row turns the flange frame like the tip link; ``tool`` is the tip's origin.
- Joint limits come from ``<limit>`` (continuous joints: +-360 deg); a prismatic
  joint's limits and position are in mm where angles are in deg (see
  :mod:`calibration.model.kinematics`).
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
from typing import Any

import numpy as np

from ..errors import UrdfError
from .dh_conversion import SNAP_MM, SNAP_RAD, dh_from_axes, rot_x, rot_y, rot_z, urdf_rpy
from .robot_model import RobotModel, model_from_dict

_MOVABLE = ("revolute", "continuous", "prismatic")
_KNOWN = (*_MOVABLE, "fixed", "floating", "planar")


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


def _load(path: str) -> Any:  # a yourdfpy.URDF (an untyped library)
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
    links: dict[str, Any]  # name -> yourdfpy Link
    joints: dict[str, Any]  # name -> yourdfpy Joint
    parent_joint: dict[str, Any]  # child link -> joint
    children: dict[str, list[Any]]  # parent link -> [joints]

    @classmethod
    def of(cls, path: str, urdf: Any) -> _Tree:
        links = {l.name: l for l in urdf.robot.links}
        joints: dict[str, Any] = {}
        parent_joint: dict[str, Any] = {}
        children: dict[str, list[Any]] = {}
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

    def subtree(self, top: str) -> list[str]:
        """``top`` and every link below it."""
        out, todo = [], [top]
        while todo:
            link = todo.pop()
            out.append(link)
            todo.extend(j.child for j in self.children.get(link, []))
        return out

    def leaves(self, top: str) -> list[str]:
        return [link for link in self.subtree(top) if not self.children.get(link)]


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
def _mm(T: Any) -> np.ndarray:
    """A URDF transform (m; None = identity) with its translation in mm."""
    T = np.eye(4) if T is None else np.array(T, float)
    T[:3, 3] *= 1000.0
    return T


def _axis(path: str, j: Any) -> np.ndarray:
    u = np.array([1.0, 0.0, 0.0] if j.axis is None else j.axis, float)
    norm = np.linalg.norm(u)
    if not np.isfinite(norm) or norm < 1e-12:
        raise UrdfError(f"{path}: joint {j.name!r}: <axis xyz> is zero or not finite")
    return u / norm


def _poses_at_zero(tree: _Tree, root: str) -> dict[str, np.ndarray]:
    """root_T_link (mm) of every link below ``root`` with every joint at zero."""
    poses, todo = {root: np.eye(4)}, [root]
    while todo:
        link = todo.pop()
        for j in tree.children.get(link, []):
            poses[j.child] = poses[link] @ _mm(j.origin)
            todo.append(j.child)
    return poses


def _mass_model(tree: _Tree, root: str, chain: list, frames: list) -> list[dict] | None:
    """One mass per movable joint from the inertials of every link that moves with it."""
    poses = _poses_at_zero(tree, root)
    movable = [j for j in chain if j.type in _MOVABLE]
    owner = {}
    for k, j in enumerate(movable):  # later joints overwrite: each link gets its own body
        for link in tree.subtree(j.child):
            owner[link] = k
    out: list[dict[str, Any]] = [{"m": 0.0, "mc": np.zeros(3)} for _ in movable]
    for link, k in owner.items():
        inertial = tree.links[link].inertial
        if inertial is None or not inertial.mass:
            continue
        T = poses[link] @ _mm(inertial.origin)
        out[k]["m"] += float(inertial.mass)
        out[k]["mc"] += float(inertial.mass) * T[:3, 3]
    if not any(b["m"] > 0 for b in out):
        return None
    links = []
    for b, (R, p) in zip(out, frames, strict=True):
        com = R.T @ (b["mc"] / b["m"] - p) if b["m"] > 0 else np.zeros(3)
        links.append({"mass_kg": b["m"], "com": [round(_snap(v, SNAP_MM), 9) for v in com]})
    return links


def _snap(v: float, tol: float) -> float:
    return 0.0 if abs(v) < tol else float(v)


def _limits(path: str, j: Any) -> tuple[float, float]:
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
def chain_geometry(spec: str) -> tuple[_Tree, str, str, list[Any], list[Any], np.ndarray,
                                        np.ndarray, np.ndarray]:
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
        T = T @ _mm(j.origin)
        if j.type in _MOVABLE:
            origins.append(T[:3, 3].copy())
            axes.append(T[:3, :3] @ _axis(path, j))
            movable.append(j)
    return tree, root, tip, chain, movable, np.array(origins), np.array(axes), T


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
                 "mount_xyz": [_snap(v, SNAP_MM) for v in mount[:3, 3]],
                 "mount_rpy": [math.degrees(_snap(v, SNAP_RAD)) for v in
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
