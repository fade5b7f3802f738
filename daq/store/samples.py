"""A run's measurements as the store holds them: a sample as the executor hands it over
(:class:`Sample`), a reading that was not accepted (:class:`Reading`) and a run's samples
as named columns (:class:`Samples`). Plain data, no database (:mod:`daq.store`).

Units: joints rad, lengths mm, covariances mm², times epoch s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    #: how the reading was judged (:data:`daq.remeasure.VERDICTS`); None: not judged
    verdict: str | None = None
    #: re-measurements made at the point (the readings not accepted are :class:`Reading`)
    remeasures: int = 0
    #: 3-D distance from the running model's prediction and the threshold there (mm)
    model_residual_mm: float | None = None
    model_threshold_mm: float | None = None
    #: the joints' temperatures as the controller reported them (°C, (N,)); None: not read
    joint_temp_c: np.ndarray | None = None
    #: a 6-DoF target's orientation: unit quaternion (w, x, y, z) of the target frame in the
    #: tracker frame, and its standard uncertainty (deg); None: a position-only reading
    quat_wxyz: np.ndarray | None = None
    sigma_deg: float | None = None
    #: which target on the tool was measured (when a pose measures several); None: the one
    tool_id: str | None = None


@dataclass
class Reading:
    """A reading of a point that was not accepted (the ``readings`` table): the sample it
    would have been (its joints, measurement, distance from the model) and why not."""

    sample: Sample
    reason: str


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
    verdict : list of str or None, how each reading was judged (:data:`daq.remeasure.VERDICTS`)
    remeasures : (n,) int, re-measurements made at each point
    joint_temp_c : (n, N) °C, the joints' temperatures, or None unless every sample has them
    quat_wxyz : (n, 4) unit quaternions of a 6-DoF target (tracker frame), NaN where not
        measured
    sigma_deg : (n,) deg, the orientation's standard uncertainty, NaN where unknown
    tool_id : list of str or None, the tool target measured (None: the one)
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
    verdict: list[str | None]
    remeasures: np.ndarray
    joint_temp_c: np.ndarray | None = None
    quat_wxyz: np.ndarray | None = None
    sigma_deg: np.ndarray | None = None
    tool_id: list[str | None] | None = None

    def __len__(self) -> int:
        return len(self.point_index)

    def sample(self, i: int) -> Sample:
        """Row ``i`` as a :class:`Sample` (NaN columns as None)."""
        def opt(a: np.ndarray) -> float | None:
            v = float(a[i])
            return None if np.isnan(v) else v

        cmd = self.base_p_tcp_cmd[i]
        return Sample(
            point_index=int(self.point_index[i]), joints_rad=self.joints_rad[i].copy(),
            tracker_p_smr=self.tracker_p_smr[i].copy(), std_mm=self.std_mm[i].copy(),
            n=int(np.nan_to_num(self.n_averaged[i])), t=float(self.t[i]),
            pose_id=self.pose_id[i],
            set_name=self.set_name[i], target=self.targets[i], temp_c=opt(self.temp_c),
            pressure_hpa=opt(self.pressure_hpa), humidity_pct=opt(self.humidity_pct),
            base_p_tcp_cmd=None if np.isnan(cmd).any() else cmd.copy(),
            dirs=None if self.dirs is None else self.dirs[i].copy(),
            reflector=self.reflector[i], face=int(self.face[i]) or None,
            cov_mm2=None if np.isnan(self.cov_mm2[i]).all() else self.cov_mm2[i].copy(),
            verdict=self.verdict[i], remeasures=int(self.remeasures[i]),
            joint_temp_c=None if self.joint_temp_c is None else self.joint_temp_c[i].copy(),
            quat_wxyz=(None if self.quat_wxyz is None or np.isnan(self.quat_wxyz[i]).any()
                       else self.quat_wxyz[i].copy()),
            sigma_deg=None if self.sigma_deg is None else opt(self.sigma_deg),
            tool_id=None if self.tool_id is None else self.tool_id[i])
