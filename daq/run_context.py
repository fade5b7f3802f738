"""What a run was started with: the typed, versioned run context stored with every run.

:class:`RunContext` replaces the loose ``options`` dict of store schema 2: the routine,
the model and the controller's tool, the devices' URLs, the seed, the executor's
settings (:class:`ExecutorOptions`), the routine's acquisition options (``acquire``:
zero20's closed loop, validated by the routine's own model), when a frame run
preceded the run, that run's id and the measurement frame ``tracker_T_base``, and the
tracker's setup (:class:`TrackerSetup`: air by hand, reflector, two-face tolerance) with
what its checks found before the run was stored (:class:`TrackerCheck`,
:mod:`daq.tracker_checks`).

The context is JSON in the store (``runs.context_json``) and carries its own
:data:`CONTEXT_VERSION`; the store upgrades older files (schema 2's ``options_json``
becomes a version-1 context, :mod:`daq.store.schema`).

Units: mm, rad, s; air in °C, hPa, %RH.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from .motion_guard import MotionLimits

#: the fastest joint speed a run may ask for (rad/s): 180 deg/s, a UR's fastest joint
MAX_JOINT_SPEED_RAD_S = float(np.pi)
#: the fastest linear TCP speed a run may ask for (mm/s)
MAX_LINEAR_SPEED_MM_S = 1000.0

#: version of the run-context JSON (``RunContext.version``)
CONTEXT_VERSION = 1

Matrix4 = tuple[tuple[float, float, float, float], tuple[float, float, float, float],
                tuple[float, float, float, float], tuple[float, float, float, float]]


class ExecutorOptions(BaseModel):
    """Motion, measurement and retry settings of the executor (rad/s, mm/s, s, mm).

    Checked when made (before a run exists): finite; speeds above 0 and at most
    :data:`MAX_JOINT_SPEED_RAD_S` / :data:`MAX_LINEAR_SPEED_MM_S`; timeouts and the
    measuring time above 0; counts, waits and thresholds not negative.
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    speed_rad_s: float = Field(0.5, gt=0, le=MAX_JOINT_SPEED_RAD_S)
    speed_mm_s: float = Field(100.0, gt=0, le=MAX_LINEAR_SPEED_MM_S)
    move_timeout_s: float = Field(120.0, gt=0)
    io_timeout_s: float = Field(1.0, gt=0)
    connect_timeout_s: float = Field(5.0, gt=0)
    dwell_s: float = Field(0.0, ge=0)
    measure_s: float = Field(0.5, gt=0)
    measure_timeout_s: float = Field(10.0, gt=0)
    max_std_mm: float = Field(0.05, gt=0)
    max_remeasure: int = Field(3, ge=1)
    max_retries: int = Field(8, ge=0)
    backoff_s: float = Field(0.02, ge=0)
    backoff_max_s: float = Field(1.0, ge=0)
    #: a joint moved by less than this (rad) approached with direction 0
    dir_deadband_rad: float = Field(1e-6, ge=0)
    #: re-measurements of a reading out of line with the running model (0: no model
    #: check), :mod:`daq.remeasure`; ``max_remeasure`` is the tracker's own std check
    remeasure: int = Field(2, ge=0)
    #: the running model is refitted after this many new calibration rows (or 10 %)
    remeasure_refit_every: int = Field(10, ge=1)
    #: a suspect's move away and back: this retract per joint (rad)
    remeasure_retract_rad: float = Field(0.01, gt=0)
    #: a lost run store connection (a PostgreSQL server restarting): how long the executor
    #: waits for it, holding the robot, before it pauses the run
    store_wait_s: float = Field(30.0, ge=0)
    #: measure a 6-DoF target's pose (a SixDof tracker): each sample keeps its orientation
    six_dof: bool = False


#: plausible air for ``--meteo``: (°C, hPa, %RH) ranges
METEO_RANGES = ((-40.0, 60.0), (500.0, 1200.0), (0.0, 100.0))


class TrackerSetup(BaseModel):
    """How the tracker is set up and checked before a run (:mod:`daq.tracker_checks`).

    ``meteo``: the air (°C, hPa, %RH) to give a tracker without a weather station;
    ``reflector``: the reflector to select by name; ``two_face_check``: measure the
    robot's current point in both faces before the run; ``two_face_tol_mm``: the largest
    two-face difference accepted beyond the measurements' own noise (mm).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    meteo: tuple[float, float, float] | None = None
    reflector: str | None = None
    two_face_check: bool = True
    two_face_tol_mm: float = Field(0.05, gt=0)

    @field_validator("meteo")
    @classmethod
    def _plausible_air(cls, v):
        if v is not None:
            for x, (lo, hi), what in zip(v, METEO_RANGES, ("°C", "hPa", "%RH"), strict=True):
                if not (np.isfinite(x) and lo <= x <= hi):
                    raise ValueError(f"--meteo: {x:g} {what} is outside [{lo:g}, {hi:g}] "
                                     "(expected T,P,H in °C, hPa, %RH)")
        return v

    @field_validator("reflector")
    @classmethod
    def _named(cls, v):
        if v is not None and not v.strip():
            raise ValueError("--reflector: empty name")
        return v


class TwoFaceCheck(BaseModel):
    """One point measured in both faces: their distance ``diff_mm``, what was allowed
    (``tol_mm`` + ``noise_mm``, the difference's 2σ from the measurements' std) and the
    point's distance from the tracker (mm)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    diff_mm: float
    tol_mm: float
    noise_mm: float
    distance_mm: float

    @property
    def allowed_mm(self) -> float:
        return self.tol_mm + self.noise_mm

    @property
    def ok(self) -> bool:
        return self.diff_mm <= self.allowed_mm


class TrackerCheck(BaseModel):
    """What the tracker's checks found before the run (None: the tracker lacks that
    capability, or the check was not asked for).

    ``ready``: the ready gate passed (initialised, warmed up, air known, target);
    ``temp_c``, ``pressure_hpa``, ``humidity_pct`` and ``air_source`` (``station`` or
    ``manual``): the air the tracker corrects with; ``reflector``: the one selected;
    ``face``: the face measured in; ``two_face``: the two-face check.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    ready: bool | None = None
    temp_c: float | None = None
    pressure_hpa: float | None = None
    humidity_pct: float | None = None
    air_source: str | None = None
    reflector: str | None = None
    face: int | None = None
    two_face: TwoFaceCheck | None = None


class RunContext(BaseModel):
    """Everything a run was started with, besides its plan.

    Attributes
    ----------
    version : 1
        :data:`CONTEXT_VERSION`.
    routine : str
        The routine (also the plan's).
    model : str or None
        The robot model as given: a built-in name or a YAML path.
    tool_mm : (3,) mm or None
        The controller's TCP in the flange frame (the model's tool unless ``--tool-mm``
        overrode it; None only in contexts upgraded from schema 2 without one).
    smr_radius_mm : float or None
        Radius of the SMR measured (``--smr-radius-mm``, else the surface offset of the
        reflector the tracker reports, when it reports one).
    reflector : str or None
        The reflector's name, when the tracker reports it.
    robot_url, tracker_url : str or None
        Where the devices were reached (a resume may move them: the store updates them).
    seed : int or None
        The random seed given for the plan.
    frame_run : int or None
        The frame run whose measurement frame the run uses.
    tracker_T_base : 4x4 (mm) or None
        That frame: the robot base in the tracker frame.
    executor : ExecutorOptions
    acquire : dict
        The routine's acquisition options (its ``ACQUIRE_OPTIONS`` model, dumped); empty for
        routines without adaptive acquisition.
    tracker : TrackerSetup
        The tracker's setup asked for (runs stored before it: the defaults).
    tracker_check : TrackerCheck or None
        What the tracker's checks found before the run was stored.
    motion : MotionLimits
        What every move of the run must respect (floor, reach, keep-out boxes, read-back
        tolerances, deviation of adaptive moves): :mod:`daq.motion_guard`. The store's
        upgrade to schema 5 gives the runs made before it no floor (none was recorded).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    version: Literal[1] = CONTEXT_VERSION
    routine: str
    model: str | None = None
    tool_mm: tuple[float, float, float] | None = None
    smr_radius_mm: float | None = Field(default=None, gt=0)
    reflector: str | None = None
    robot_url: str | None = None
    tracker_url: str | None = None
    seed: int | None = None
    frame_run: int | None = None
    tracker_T_base: Matrix4 | None = None
    executor: ExecutorOptions = Field(default_factory=ExecutorOptions)
    acquire: dict[str, Any] = Field(default_factory=dict)
    tracker: TrackerSetup = Field(default_factory=TrackerSetup)
    tracker_check: TrackerCheck | None = None
    motion: MotionLimits = Field(default_factory=MotionLimits)

    @field_validator("tracker_T_base")
    @classmethod
    def _rigid(cls, v):
        if v is not None:
            T = np.asarray(v, float)
            if not np.all(np.isfinite(T)) or not np.allclose(T[3], [0, 0, 0, 1]):
                raise ValueError("tracker_T_base must be a finite homogeneous 4x4 transform")
        return v

    @property
    def tracker_T_base_matrix(self) -> np.ndarray | None:
        """``tracker_T_base`` as a (4, 4) array, or None when the run has no frame."""
        return None if self.tracker_T_base is None else np.asarray(self.tracker_T_base, float)

    def to_json(self) -> str:
        return self.model_dump_json()

    @classmethod
    def from_json(cls, text: str) -> RunContext:
        return cls.model_validate_json(text)
