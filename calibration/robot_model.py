"""The nominal robot: :class:`RobotModel`, loaded from the model YAML (docs/formats.md §2).

Files hold millimetres and degrees; the model keeps them as written and offers
radian views (``dh_table()``, ``limits_rad()``) for the numerical code. A prismatic joint
(``type: prismatic``) holds its limits in mm where a revolute one holds degrees (see
:mod:`calibration.kinematics`). ``load_model`` also reads a URDF's serial chain
(``robot.urdf#root:tip``, :mod:`calibration.urdf_model`).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

#: columns of the per-joint parameter table, in this order
DH_COLUMNS = ("theta_offset", "d", "a", "alpha", "beta")
#: whether each column is a length (mm) or an angle (rad inside, deg in files)
DH_IS_ANGLE = (True, False, False, True, True)


class ModelError(ValueError):
    """A model file or name that cannot be used; the message names the file and field."""


class JointRow(BaseModel):
    """One row of the DH/MDH table (mm, deg); in an mdh row a, alpha are a_{i-1}, alpha_{i-1}."""

    model_config = ConfigDict(extra="forbid")
    a: float
    alpha: float
    d: float
    theta_offset: float = 0.0
    beta: float = 0.0
    min: float = Field(description="lower joint limit, deg (prismatic: mm)")
    max: float = Field(description="upper joint limit, deg (prismatic: mm)")
    type: Literal["revolute", "prismatic"] | None = Field(
        default=None, description="joint type; absent = revolute")
    link_radius: float | None = Field(
        default=None, ge=0.0,
        description="radius of the link this row moves, as capsules around its d and a "
        "segments, mm (the tracker's line of sight); absent: 0, the link is not checked")

    @model_validator(mode="after")
    def _limits(self) -> JointRow:
        if self.min > self.max:
            raise ValueError(f"min ({self.min}) > max ({self.max})")
        return self


class MassPoint(BaseModel):
    """A mass (kg) with its centre (mm) in some frame."""

    model_config = ConfigDict(extra="forbid")
    mass_kg: float = Field(ge=0.0)
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)


class UrdfSource(BaseModel):
    """Where a model read from a URDF came from (:mod:`calibration.urdf_model`).

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
    name: str
    convention: Literal["dh", "mdh"]
    joints: list[JointRow] = Field(min_length=1)
    tool: tuple[float, float, float] = (0.0, 0.0, 0.0)
    payload: MassPoint | None = None
    links: list[MassPoint] | None = None
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    urdf: UrdfSource | None = None

    @field_validator("links")
    @classmethod
    def _links_len(cls, v, info):
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

    def with_changes(self, **changes) -> RobotModel:
        """A copy with some top-level fields replaced (validated)."""
        data = self.model_dump()
        data.update(changes)
        return RobotModel.model_validate(data)

    def to_yaml(self) -> str:
        data = self.model_dump(exclude_none=True)
        data["tool"] = list(data["tool"])
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
    folder = resources.files("calibration") / "models"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def _format_validation(err: ValidationError, source: str) -> str:
    lines = []
    for e in err.errors():
        loc = ".".join(str(x) for x in e["loc"]) or "(top level)"
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "missing":
            msg = "missing field"
        elif e["type"] == "extra_forbidden":
            msg = "unknown field"
        lines.append(f"{source}: {loc}: {msg}")
    return "\n".join(lines)


def validate_file_mapping(cls, data, source: str, error: type[ValueError], what: str):
    """``cls.model_validate(data)`` for the mapping read from a file: ``error`` naming
    ``source`` and the field (``what``: "a model file", for the message)."""
    if not isinstance(data, dict):
        raise error(f"{source}: {what} must be a mapping, got {type(data).__name__}")
    try:
        return cls.model_validate(data)
    except ValidationError as e:
        raise error(_format_validation(e, source)) from None


def model_from_dict(data: dict, source: str = "<model>") -> RobotModel:
    """Validate a model mapping; errors name ``source`` and the field."""
    return validate_file_mapping(RobotModel, data, source, ModelError, "a model file")


def load_model(name_or_path: str | Path) -> RobotModel:
    """Load a built-in model by name (``"ur10e"``), a model YAML by path, or the serial chain
    of a URDF (``"robot.urdf#base_link:tool0"``, or ``"robot.urdf"`` when unambiguous)."""
    text_source = str(name_or_path)
    from .urdf_model import is_urdf_spec, load_urdf_model

    if is_urdf_spec(text_source):
        return load_urdf_model(text_source)
    path = Path(text_source)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if not path.is_file():
            raise ModelError(f"{path}: no such model file")
        text = path.read_text()
    else:
        names = builtin_models()
        if text_source not in names:
            raise ModelError(
                f"unknown model {text_source!r}: built-in models are {', '.join(names)}; "
                "or give the path of a model YAML file"
            )
        text = (resources.files("calibration") / "models" / f"{text_source}.yaml").read_text()
        text_source = f"built-in model {text_source}"
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ModelError(f"{text_source}: not valid YAML: {e}") from None
    return model_from_dict(data, text_source)
