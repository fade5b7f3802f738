"""The run store's records: a run as stored (:class:`Run`), a sample as the executor hands it
over (:class:`Sample`), a run's samples as columns (:class:`Samples`) and a recorded
calibration (:class:`Calibration`). Plain data, no database (:mod:`daq.store`)."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from .run_context import RunContext

#: run statuses: ``running`` (or killed while running), ``paused`` (protective stop,
#: retries exhausted: resumable), ``stopped`` (Ctrl-C: resumable), ``completed``,
#: ``failed`` (refused or broken: resumable once the cause is fixed)
STATUSES = ("running", "paused", "stopped", "completed", "failed")


@dataclass
class Run:
    """One row of ``runs``: plan, frame, summary and context decoded.

    ``robot_url``, ``tracker_url``, ``seed`` and ``model`` are the context's;
    ``robot_id`` is who the robot is (the controller's ``MODEL/SERIAL`` or the name given
    with ``--robot-id``; None when neither was known).
    """

    id: int
    routine: str
    plan_json: str
    plan_hash: str
    n_points: int
    robot_desc: str | None
    tracker_desc: str | None
    software: str | None
    started: float | None
    stopped: float | None
    status: str
    reason: str | None
    frame: dict | None
    summary: dict | None
    context: RunContext
    robot_id: str | None = None
    #: who the devices said they were (DeviceIdentity dicts), None when not recorded
    robot_identity: dict | None = None
    tracker_identity: dict | None = None
    #: the run whose plan this run repeats on another cell (``resume --other-cell``)
    source_run: int | None = None

    @property
    def robot_url(self) -> str | None:
        return self.context.robot_url

    @property
    def tracker_url(self) -> str | None:
        return self.context.tracker_url

    @property
    def seed(self) -> int | None:
        return self.context.seed

    @property
    def model(self) -> str | None:
        return self.context.model


@dataclass
class Sample:
    """One measured point, as the executor hands it to :meth:`RunStore.add_sample`.

    ``joints_rad`` joints read (rad, (N,)), ``tracker_p_smr`` the reflector measured (mm,
    tracker frame), ``std_mm`` per-axis std reported by the tracker (mm), ``n`` samples
    averaged, ``t`` measurement time (epoch s), ``base_p_tcp_cmd`` the controller's
    nominal TCP (mm, base frame) or None, ``dirs`` approach direction per joint
    (-1/0/+1) or None; ``reflector`` the reflector measured, ``face`` the tracker face
    (1 or 2) and ``cov_mm2`` the (3, 3) covariance of ``tracker_p_smr`` (mm²), each None
    when the tracker did not say.
    """

    point_index: int
    joints_rad: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n: int
    t: float
    pose_id: str = ""
    set_name: str = "calib"
    target: dict | None = None
    temp_c: float | None = None
    pressure_hpa: float | None = None
    humidity_pct: float | None = None
    base_p_tcp_cmd: np.ndarray | None = None
    dirs: np.ndarray | None = None
    attempts: int = 1
    joints_t: float | None = None
    reflector: str | None = None
    face: int | None = None
    cov_mm2: np.ndarray | None = None


@dataclass(frozen=True)
class Samples:
    """Every sample of a run ordered by point index, as named columns (``n`` rows).

    Attributes
    ----------
    point_index : (n,) int
    pose_id, set_name : list of str (``set_name`` ``calib`` or ``valid``)
    joints_rad : (n, N) rad, the joints read
    tracker_p_smr : (n, 3) mm, the reflector measured in the tracker frame
    std_mm : (n, 3) mm, the tracker's per-axis std
    n_averaged : (n,) samples the tracker averaged
    t : (n,) epoch s, the measurement times
    temp_c, pressure_hpa, humidity_pct : (n,), NaN where unknown
    base_p_tcp_cmd : (n, 3) mm, the controller's nominal TCP (base frame), NaN where unknown
    dirs : (n, N) int approach directions, or None unless every sample has them
    targets : list of dict (the plan's targets, JSON) or None
    reflector : list of str or None (None where unknown)
    face : (n,) int, the tracker face (1 or 2), 0 where unknown
    cov_mm2 : (n, 3, 3) mm², the covariance of ``tracker_p_smr``, NaN where unknown
    """

    point_index: np.ndarray
    pose_id: list[str]
    set_name: list[str]
    joints_rad: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n_averaged: np.ndarray
    t: np.ndarray
    temp_c: np.ndarray
    pressure_hpa: np.ndarray
    humidity_pct: np.ndarray
    base_p_tcp_cmd: np.ndarray
    dirs: np.ndarray | None
    targets: list[dict | None]
    reflector: list[str | None]
    face: np.ndarray
    cov_mm2: np.ndarray

    def __len__(self) -> int:
        return len(self.point_index)


@dataclass(frozen=True)
class Calibration:
    """One row of ``calibrations``: a robot's calibration as its params.json.

    ``t`` when its data were measured (epoch s: the latest ``t_s`` of the data, else when
    it was recorded), ``recorded`` when it was stored, ``source_file`` the measurement
    CSV, ``source_run`` the run it came from (when known), ``software`` the cellcal that
    fitted it.
    """

    id: int
    robot_id: str
    t: float
    recorded: float
    params_json: str
    source_file: str | None
    source_run: int | None
    software: str | None

    @property
    def params(self) -> dict:
        """The params.json document (docs/formats.md)."""
        return json.loads(self.params_json)
