"""The nominal robot: :class:`RobotModel`, loaded from the model YAML (docs/formats.md §2).

Files hold millimetres and degrees; the model keeps them as written and offers
radian views (``dh_table()``, ``limits_rad()``) for the numerical code. A prismatic joint
(``type: prismatic``) holds its limits in mm where a revolute one holds degrees (see
:mod:`calibration.model.kinematics`). :func:`calibration.model.model_loading.load_model`
loads one by name, path or a URDF's serial chain (``robot.urdf#root:tip``,
:mod:`calibration.model.urdf_model`).

The schema is strict: every number must be a finite number (not ``true``, not a
string, not ``.nan``) of a plausible magnitude (a link shorter than 20 m, an angle
within ±360°, limits within ±3600° (a prismatic joint's within ±100 m), masses
0-10 000 kg, gravity within ±100 m/s²); a key given twice, an unknown key or a file
that is not UTF-8 is refused. Errors name the file and the field, in one line.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Callable
from importlib import resources
from typing import Annotated, Any, Literal, TypeVar

import numpy as np
import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from ..errors import ModelError

#: the largest model YAML read (bytes)
MAX_MODEL_BYTES = 1 << 20


#: a number YAML 1.1 reads as a string (``1e300``: an exponent without a dot)
_EXP_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


def number_only(v: Any) -> Any:
    """Only numbers: YAML's true/false and strings are refused (no silent coercion); a
    number YAML 1.1 leaves as a string (``1e3``) is read as the number it is."""
    if isinstance(v, str) and _EXP_NUMBER.match(v.strip()):
        return float(v)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        shown = str(v).lower() if isinstance(v, bool) else repr(v)
        raise ValueError(f"{shown[:40]} is not a number")
    return v


def _within(limit: float, unit: str, what: str) -> Callable[[float], float]:
    """The check of a finite float with |value| <= limit."""
    def check(v: float) -> float:
        if not math.isfinite(v):
            raise ValueError(f"{v} is not a finite number")
        if abs(v) > limit:
            raise ValueError(f"{v:g} {unit} is not a plausible {what} "
                             f"(|value| <= {limit:g} {unit})")
        return v
    return check


# a finite number (no bool, no string) with |value| <= its limit
Length = Annotated[float, BeforeValidator(number_only),
                   AfterValidator(_within(20000.0, "mm", "length"))]
Angle = Annotated[float, BeforeValidator(number_only),
                  AfterValidator(_within(360.0, "deg", "angle"))]
Limit = 3600.0  # deg: |limit| of a revolute joint
#: a joint limit: deg, or mm for a prismatic joint (JointRow checks the revolute bound)
Travel = Annotated[float, BeforeValidator(number_only),
                   AfterValidator(_within(100000.0, "deg or mm", "joint limit"))]
Offset = Annotated[float, BeforeValidator(number_only),
                   AfterValidator(_within(10000.0, "mm", "offset"))]
Acceleration = Annotated[float, BeforeValidator(number_only),
                         AfterValidator(_within(100.0, "m/s^2", "acceleration"))]
Mass = Annotated[float, BeforeValidator(number_only),
                 AfterValidator(lambda v: _mass(v))]


def _mass(v: float) -> float:
    if not (math.isfinite(v) and 0.0 <= v <= 10000.0):
        raise ValueError(f"{v:g} kg is not a mass (0 to 10000 kg)")
    return v

#: columns of the per-joint parameter table, in this order
DH_COLUMNS = ("theta_offset", "d", "a", "alpha", "beta")
#: whether each column is a length (mm) or an angle (rad inside, deg in files)
DH_IS_ANGLE = (True, False, False, True, True)


class JointRow(BaseModel):
    """One row of the DH/MDH table (mm, deg); in an mdh row a, alpha are a_{i-1}, alpha_{i-1}."""

    model_config = ConfigDict(extra="forbid")
    a: Length
    alpha: Angle
    d: Length
    theta_offset: Angle = 0.0
    beta: Angle = 0.0
    min: Travel = Field(description="lower joint limit, deg (prismatic: mm)")
    max: Travel = Field(description="upper joint limit, deg (prismatic: mm)")
    type: Literal["revolute", "prismatic"] | None = Field(
        default=None, description="joint type; absent = revolute")
    link_radius: float | None = Field(
        default=None, ge=0.0, le=5000.0,
        description="radius of the link this row moves, as capsules around its d and a "
        "segments, mm (the tracker's line of sight); absent: 0, the link is not checked")

    @model_validator(mode="after")
    def _limits(self) -> JointRow:
        if self.type != "prismatic" and max(abs(self.min), abs(self.max)) > Limit:
            bad = self.min if abs(self.min) > Limit else self.max
            raise ValueError(f"{bad:g} deg is not a plausible joint limit (|value| <= "
                             f"{Limit:g} deg)")
        if self.min > self.max:
            raise ValueError(f"min ({self.min}) > max ({self.max})")
        return self


class MassPoint(BaseModel):
    """A mass (kg) with its centre (mm) in some frame."""

    model_config = ConfigDict(extra="forbid")
    mass_kg: Mass
    com: tuple[Offset, Offset, Offset] = (0.0, 0.0, 0.0)


class UrdfSource(BaseModel):
    """Where a model read from a URDF came from (:mod:`calibration.model.urdf_model`).

    ``mount_xyz`` (mm) and ``mount_rpy`` (deg, URDF roll-pitch-yaw) are the pose of the
    model's base frame in the ``root`` link; identity unless joint 1's axis is not the
    root's z axis. ``joints`` are the URDF names of the chain's movable joints.
    """

    model_config = ConfigDict(extra="forbid")
    file: str
    root: str
    tip: str
    joints: list[str]
    mount_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    mount_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


class RobotModel(BaseModel):
    """A robot's nominal kinematics and (optionally) its mass model, as in the model YAML."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str = Field(min_length=1, max_length=200, pattern=r"^[^\n\r]*$")
    convention: Literal["dh", "mdh"]
    joints: list[JointRow] = Field(min_length=1, max_length=20)
    tool: tuple[Offset, Offset, Offset] = (0.0, 0.0, 0.0)
    #: the tool frame's orientation in the flange frame, URDF roll, pitch, yaw (deg,
    #: R = Rz(yaw) Ry(pitch) Rx(roll)); absent: the tool frame is the flange's, turned not
    tool_rpy_deg: tuple[Angle, Angle, Angle] | None = None
    payload: MassPoint | None = None
    links: list[MassPoint] | None = None
    gravity: tuple[Acceleration, Acceleration, Acceleration] = (0.0, 0.0, -9.81)
    urdf: UrdfSource | None = None

    @field_validator("links")
    @classmethod
    def _links_len(cls, v: list[MassPoint] | None,
                   info: ValidationInfo) -> list[MassPoint] | None:
        joints = info.data.get("joints")
        if v is not None and joints is not None and len(v) != len(joints):
            raise ValueError(f"has {len(v)} entries but the model has {len(joints)} joints")
        return v

    # ---- numerical views -------------------------------------------------
    @property
    def n_joints(self) -> int:
        return len(self.joints)

    def dh_table(self) -> np.ndarray:
        """Nominal parameters, shape (n_joints, 5): theta_offset, d, a, alpha, beta (rad, mm)."""
        t = np.array([[getattr(j, c) for c in DH_COLUMNS] for j in self.joints], dtype=float)
        t[:, np.array(DH_IS_ANGLE)] = np.radians(t[:, np.array(DH_IS_ANGLE)])
        return t

    def limits_rad(self) -> np.ndarray:
        """Joint limits, shape (n_joints, 2), rad."""
        return np.radians([[j.min, j.max] for j in self.joints])

    def sampling_limits_rad(self, max_abs_deg: float = 180.0) -> np.ndarray:
        """Joint limits for drawing poses, (n_joints, 2): revolute joints clipped to
        +-max_abs_deg (rad), prismatic joints' full travel (internal units)."""
        lim = self.limits_rad()
        clipped = np.clip(lim, -np.radians(max_abs_deg), np.radians(max_abs_deg))
        mask = self.prismatic_mask()
        return clipped if mask is None else np.where(mask[:, None], lim, clipped)

    def tool_mm(self) -> np.ndarray:
        return np.array(self.tool, dtype=float)

    def tool_R(self) -> np.ndarray:
        """(3, 3) the tool frame's orientation in the flange frame (identity without
        ``tool_rpy_deg``)."""
        if self.tool_rpy_deg is None:
            return np.eye(3)
        r, p, y = np.radians(self.tool_rpy_deg)
        cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
        Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
        return Rz @ Ry @ Rx

    def prismatic_mask(self) -> np.ndarray | None:
        """(n_joints,) bool, the prismatic joints; None when every joint is revolute."""
        mask = np.array([j.type == "prismatic" for j in self.joints])
        return mask if mask.any() else None

    def link_radii(self) -> np.ndarray:
        """Capsule radius of each row's link, shape (n_joints,), mm (0 where not given)."""
        return np.array([j.link_radius or 0.0 for j in self.joints], dtype=float)

    def parallel_rows(self, tol_deg: float = 1e-6) -> list[int]:
        """0-based rows whose two neighbouring joint axes are (nominally) parallel.

        These rows carry the Hayati tilt beta: for dh row i (alpha_i between axes i and
        i+1) every row but the last; for mdh row i (alpha_{i-1} between axes i-1 and i)
        every row but the first. A row written in Hayati form (nominal beta, e.g. nearly
        parallel axes of a URDF) counts as parallel too.
        """
        rows = [i for i, j in enumerate(self.joints)
                if abs(np.sin(np.radians(j.alpha))) < tol_deg or j.beta != 0.0]
        last = self.n_joints - 1
        return [i for i in rows if i != (last if self.convention == "dh" else 0)]

    def definition_hash(self) -> str:
        """sha256 of the model's canonical JSON: two models with the same hash have the same
        kinematics, limits and masses (recorded in params.json, checked on reading)."""
        canon = json.dumps(self.model_dump(mode="json", exclude_none=True), sort_keys=True,
                           separators=(",", ":"))
        return hashlib.sha256(canon.encode()).hexdigest()

    def with_changes(self, **changes: Any) -> RobotModel:
        """A copy with some top-level fields replaced (validated)."""
        data = self.model_dump()
        data.update(changes)
        return RobotModel.model_validate(data)

    def to_yaml(self) -> str:
        data = self.model_dump(exclude_none=True)
        data["tool"] = list(data["tool"])
        if "tool_rpy_deg" in data:
            data["tool_rpy_deg"] = list(data["tool_rpy_deg"])
        data["gravity"] = list(data["gravity"])
        for key in ("payload",):
            if key in data:
                data[key]["com"] = list(data[key]["com"])
        if "urdf" in data:
            for key in ("mount_xyz", "mount_rpy"):
                data["urdf"][key] = list(data["urdf"][key])
        if "links" in data:
            for link in data["links"]:
                link["com"] = list(link["com"])
        return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


def builtin_models() -> list[str]:
    """Names of the built-in models."""
    folder = resources.files("calibration.model") / "builtin"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def format_validation(err: ValidationError, source: str, limit: int = 3) -> str:
    """A pydantic error as one line: ``source: field.path: message; ...`` (the first
    ``limit`` problems, and how many more)."""
    parts = []
    errors = err.errors()
    for e in errors[:limit]:
        loc = ".".join(str(x) for x in e["loc"]) or "(top level)"
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "missing":
            msg = "missing field"
        elif e["type"] == "extra_forbidden":
            msg = "unknown field"
        parts.append(f"{loc}: {msg}")
    more = f" (and {len(errors) - limit} more)" if len(errors) > limit else ""
    return f"{source}: " + "; ".join(parts) + more


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a mapping key given twice (YAML keeps the last one)."""


def _mapping(loader: _UniqueKeyLoader, node: yaml.MappingNode,
             deep: bool = False) -> dict[Any, Any]:
    seen = set()
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            line = key_node.start_mark.line + 1
            raise yaml.constructor.ConstructorError(
                None, None, f"key {key!r} given twice (line {line})", key_node.start_mark)
        seen.add(key)
    return loader.construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping)


def parse_yaml(text: str, source: str, error: type[Exception]) -> Any:
    """YAML text to Python data (safe, duplicate keys refused); ``error`` in one line."""
    try:
        return yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 - a SafeLoader
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f"line {mark.line + 1}: " if mark is not None else ""
        what = getattr(e, "problem", None) or str(e)
        raise error(f"{source}: not valid YAML: {where}{' '.join(str(what).split())}") from None


_Schema = TypeVar("_Schema", bound=BaseModel)


def validate_file_mapping(cls: type[_Schema], data: object, source: str,
                          error: type[ValueError], what: str) -> _Schema:
    """``cls.model_validate(data)`` for the mapping read from a file: ``error`` naming
    ``source`` and the field (``what``: "a model file", for the message)."""
    if not isinstance(data, dict):
        got = "an empty file" if data is None else type(data).__name__
        raise error(f"{source}: {what} must be a mapping (docs/formats.md), got {got}")
    try:
        return cls.model_validate(data)
    except ValidationError as e:
        raise error(format_validation(e, source)) from None


def model_from_dict(data: dict[str, Any], source: str = "<model>") -> RobotModel:
    """Validate a model mapping; errors name ``source`` and the field."""
    return validate_file_mapping(RobotModel, data, source, ModelError, "a model file")
