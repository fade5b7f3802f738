"""The cell around the robot as the tracker's line of sight needs it: the cell YAML (FORMATS §7).

:class:`CellSpec` holds where the tracker stands (robot base frame, mm), which way the
SMR opens on the flange and how wide it accepts the beam (from the reflector type),
the margins a plan keeps, and the fixtures (boxes, cylinders) that break the beam.
Files hold millimetres and degrees; :meth:`CellSpec.acceptance_rad` and friends give
radians for the numerical code (:mod:`calibration.cell.visibility`).

::

    tracker: {position: [-2500, 0, 500]}   # tracker head, robot base frame, mm (rough is fine)
    smr:
      axis: [0, 0, 1]                      # the SMR's opening direction, flange frame
      reflector: RRR 1.5in                 # acceptance half-angle from the reflector type
    margins: {facing_deg: 5, clearance_mm: 20}
    fixtures:
      - {name: table, box: {centre: [-900, 0, -420], size: [1200, 800, 800]}}
      - {name: column, cylinder: {start: [0, 1500, -800], end: [0, 1500, 2000], radius: 150}}
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import numpy.typing as npt
import yaml
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..errors import CellError
from ..model.robot_model import validate_file_mapping

#: acceptance half-angle (deg) of each reflector type the tools know, by name: the
#: planner's and the simulator's defaults (a datasheet's value goes in ``acceptance_deg``)
REFLECTOR_ACCEPTANCE_DEG = {
    "RRR 1.5in": 30.0,
    "BRR 1.5in": 30.0,
    "RRR 7/8in": 30.0,
    "RRR 0.5in": 40.0,
    "TBR 0.5in": 40.0,
    "CatsEye 3in": 60.0,
    "360": 180.0,  # a 360-degree reflector: no facing limit
}

#: a finite coordinate, mm (or an angle, deg): within a kilometre of the robot
Coord = Annotated[float, Field(allow_inf_nan=False, ge=-1e6, le=1e6)]
Vec3 = tuple[Coord, Coord, Coord]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Box(_Strict):
    """A box: ``centre`` and edge lengths ``size`` (mm, base frame), turned by ``rpy``
    (roll, pitch, yaw about the base x, y, z axes, deg) about its centre."""

    centre: Vec3
    size: Vec3
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("size")
    @classmethod
    def _positive(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if min(v) <= 0:
            raise ValueError("every edge must be > 0 mm")
        return v

    def rotation(self) -> np.ndarray:
        """The box's axes in the base frame (columns), 3x3."""
        r, p, y = np.radians(self.rpy)
        cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        return (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
                @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
                @ np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))


class Cylinder(_Strict):
    """A cylinder between the centres of its two end faces ``start`` and ``end`` (mm, base
    frame) with ``radius`` (mm)."""

    start: Vec3
    end: Vec3
    radius: float = Field(gt=0.0, le=1e6, allow_inf_nan=False)

    @model_validator(mode="after")
    def _length(self) -> Cylinder:
        if np.allclose(self.start, self.end):
            raise ValueError("start and end are the same point")
        return self


class Fixture(_Strict):
    """Something fixed in the cell that breaks the beam: exactly one of ``box``, ``cylinder``."""

    name: str
    box: Box | None = None
    cylinder: Cylinder | None = None

    @model_validator(mode="after")
    def _one_shape(self) -> Fixture:
        if (self.box is None) == (self.cylinder is None):
            raise ValueError(f"fixture {self.name!r}: give exactly one of box, cylinder")
        return self


class TrackerPlacement(_Strict):
    """Where the tracker head stands: ``position`` (mm, robot base frame)."""

    position: Vec3


class Smr(_Strict):
    """The reflector on the robot: its opening direction ``axis`` in the flange frame (any
    length), its ``reflector`` type and, optionally, its acceptance half-angle (deg)."""

    axis: Vec3 = (0.0, 0.0, 1.0)
    reflector: str = "RRR 1.5in"
    acceptance_deg: float | None = Field(default=None, gt=0.0, le=180.0, allow_inf_nan=False)

    @field_validator("axis")
    @classmethod
    def _nonzero(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        if float(np.linalg.norm(v)) < 1e-9:
            raise ValueError("the axis must not be zero")
        return v

    @model_validator(mode="after")
    def _known(self) -> Smr:
        if self.acceptance_deg is None and self.reflector not in REFLECTOR_ACCEPTANCE_DEG:
            raise ValueError(f"unknown reflector {self.reflector!r} (known: "
                             f"{', '.join(REFLECTOR_ACCEPTANCE_DEG)}); give acceptance_deg")
        return self

    @property
    def half_angle_deg(self) -> float:
        """The acceptance half-angle, deg."""
        if self.acceptance_deg is not None:
            return float(self.acceptance_deg)
        return REFLECTOR_ACCEPTANCE_DEG[self.reflector]

    def axis_unit(self) -> np.ndarray:
        a = np.asarray(self.axis, float)
        return a / np.linalg.norm(a)


class Margins(_Strict):
    """What a plan keeps in hand: the SMR faces the tracker within the half-angle minus
    ``facing_deg``, and the beam passes every link and fixture by ``clearance_mm``."""

    facing_deg: float = Field(default=5.0, ge=0.0, le=180.0, allow_inf_nan=False)
    clearance_mm: float = Field(default=20.0, ge=0.0, le=1e4, allow_inf_nan=False)


class CellSpec(_Strict):
    """The cell: tracker placement (None: unknown), SMR, margins, fixtures.

    ``tracker_source`` says where the tracker position came from (``cell file``,
    ``--tracker-at``, ``frame run N``); it is not read from a file.
    """

    tracker: TrackerPlacement | None = None
    smr: Smr = Field(default_factory=Smr)
    margins: Margins = Field(default_factory=Margins)
    fixtures: tuple[Fixture, ...] = ()
    tracker_source: str = Field(default="cell file", exclude=True)

    @property
    def tracker_mm(self) -> np.ndarray | None:
        """The tracker head in the robot base frame, (3,) mm, or None."""
        return None if self.tracker is None else np.asarray(self.tracker.position, float)

    def with_tracker(self, position_mm: npt.ArrayLike, source: str) -> CellSpec:
        """A copy with the tracker at ``position_mm`` (robot base frame, mm)."""
        p = tuple(float(v) for v in np.asarray(position_mm, float).ravel())
        if len(p) != 3 or not np.all(np.isfinite(p)):
            raise CellError(f"{source}: the tracker position needs 3 finite values, got {p}")
        return self.model_copy(update={"tracker": TrackerPlacement(position=p),
                                       "tracker_source": source})

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json", exclude_none=True), sort_keys=False,
                              default_flow_style=None)


def tracker_in_base(tracker_T_base: npt.ArrayLike) -> np.ndarray:
    """The tracker origin in the robot base frame (mm) from the measurement frame
    ``tracker_T_base`` (4x4): ``-Rᵀ t``."""
    T = np.asarray(tracker_T_base, float)
    return -T[:3, :3].T @ T[:3, 3]


def cell_from_dict(data: object, source: str = "<cell>") -> CellSpec:
    """Validate a cell mapping; errors name ``source`` and the field."""
    return validate_file_mapping(CellSpec, {} if data is None else data, source, CellError,
                                 "a cell file")


def load_cell(path: str | Path) -> CellSpec:
    """Read a cell YAML file (docs/formats.md §7)."""
    from ..files import read_text
    from ..model.robot_model import parse_yaml

    text = read_text(path, CellError, "cell file", 10 << 20)
    return cell_from_dict(parse_yaml(text, str(path), CellError), str(path))
