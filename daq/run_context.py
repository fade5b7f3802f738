"""What a run was started with: the typed, versioned run context stored with every run.

:class:`RunContext` replaces the loose ``options`` dict of store schema 2: the routine,
the model and the controller's tool, the devices' URLs, the seed, the executor's
settings (:class:`ExecutorOptions`), the routine's acquisition options (``acquire``:
zero20's closed loop, validated by the routine's own model) and, when a frame run
preceded the run, that run's id and the measurement frame ``tracker_T_base``.

The context is JSON in the store (``runs.context_json``) and carries its own
:data:`CONTEXT_VERSION`; the store upgrades older files (schema 2's ``options_json``
becomes a version-1 context, :mod:`daq.store_schema`).

Units: mm, rad, s.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

#: version of the run-context JSON (``RunContext.version``)
CONTEXT_VERSION = 1

Matrix4 = tuple[tuple[float, float, float, float], tuple[float, float, float, float],
                tuple[float, float, float, float], tuple[float, float, float, float]]


class ExecutorOptions(BaseModel):
    """Motion, measurement and retry settings of the executor (rad/s, mm/s, s, mm)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    speed_rad_s: float = 0.5
    speed_mm_s: float = 100.0
    move_timeout_s: float = 120.0
    io_timeout_s: float = 1.0
    connect_timeout_s: float = 5.0
    dwell_s: float = 0.0
    measure_s: float = 0.5
    measure_timeout_s: float = 10.0
    max_std_mm: float = 0.05
    max_remeasure: int = 3
    max_retries: int = 8
    backoff_s: float = 0.02
    backoff_max_s: float = 1.0
    #: a joint moved by less than this (rad) approached with direction 0
    dir_deadband_rad: float = 1e-6
    #: a lost run store connection (a PostgreSQL server restarting): how long the executor
    #: waits for it, holding the robot, before it pauses the run
    store_wait_s: float = 30.0


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
        The controller's TCP in the flange frame when it overrides the model's tool.
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
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    version: Literal[1] = CONTEXT_VERSION
    routine: str
    model: str | None = None
    tool_mm: tuple[float, float, float] | None = None
    robot_url: str | None = None
    tracker_url: str | None = None
    seed: int | None = None
    frame_run: int | None = None
    tracker_T_base: Matrix4 | None = None
    executor: ExecutorOptions = Field(default_factory=ExecutorOptions)
    acquire: dict[str, Any] = Field(default_factory=dict)

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
