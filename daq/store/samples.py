"""A run's measurements as the store holds them: a sample as the executor hands it over
(:class:`Sample`), a reading that was not accepted (:class:`Reading`) and a run's samples
as named columns (:class:`Samples`). Plain data, no database (:mod:`daq.store`).

Every field is a quantity of the column table (:mod:`calibration.data.columns`), named as
there: the table says how each is stored, stacked into a run's column and taken back
(:meth:`Samples.from_records`, :meth:`Samples.sample`), and
``tests/daq/test_column_table.py`` checks that these classes, the schema and the table
agree.

Units: joints rad, lengths mm, covariances mm², times epoch s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.data.columns import RECORD


@dataclass
class Sample:
    """One measured point, as the executor hands it to :meth:`RunStore.add_sample`.

    ``q`` joints read (rad, (N,)), ``tracker_p_smr`` the reflector measured (mm, tracker
    frame), ``std_mm`` per-axis std reported by the tracker (mm), ``n_averaged`` samples
    averaged, ``t_s`` measurement time (epoch s), ``cmd`` the controller's nominal TCP
    (mm, base frame) or None, ``dirs`` approach direction per joint (-1/0/+1) or None;
    ``reflector`` the reflector measured, ``face`` the tracker face (1 or 2) and
    ``cov_mm2`` the (3, 3) covariance of ``tracker_p_smr`` (mm²), each None when the
    tracker did not say.
    """

    point_index: int
    q: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n_averaged: int
    t_s: float
    pose_id: str = ""
    set_name: str = "calib"
    target: dict | None = None
    temp_c: float | None = None
    pressure_hpa: float | None = None
    humidity_pct: float | None = None
    cmd: np.ndarray | None = None
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
    joint_temp: np.ndarray | None = None
    #: a 6-DoF target's orientation: unit quaternion (w, x, y, z) of the target frame in the
    #: tracker frame, and its standard uncertainty (deg); None: a position-only reading
    quat: np.ndarray | None = None
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
    """Every sample of a run ordered by point index, as named columns (``n`` rows): one
    per field of :class:`Sample`, stacked as the column table's kind says.

    Attributes
    ----------
    point_index : (n,) int
    pose_id, set_name : list of str (``set_name`` ``calib``, ``valid`` or ``drift``)
    q : (n, N) rad, the joints read
    tracker_p_smr : (n, 3) mm, the reflector measured in the tracker frame
    std_mm : (n, 3) mm, the tracker's per-axis std
    n_averaged : (n,) int, samples the tracker averaged
    t_s : (n,) epoch s, the measurement times
    temp_c, pressure_hpa, humidity_pct : (n,), NaN where unknown
    cmd : (n, 3) mm, the controller's nominal TCP (base frame), NaN where unknown
    dirs : (n, N) int approach directions, or None unless every sample has them
    target : list of dict (the plan's targets, JSON) or None
    attempts : (n,) int, tries each point took
    joints_t : (n,) epoch s, when the joints were read, NaN where unknown
    reflector : list of str or None (None where unknown)
    face : (n,) int, the tracker face (1 or 2), 0 where unknown
    cov_mm2 : (n, 3, 3) mm², the covariance of ``tracker_p_smr``, NaN where unknown
    verdict : list of str or None, how each reading was judged (:data:`daq.remeasure.VERDICTS`)
    remeasures : (n,) int, re-measurements made at each point
    model_residual_mm, model_threshold_mm : (n,) mm, NaN where not judged
    joint_temp : (n, N) °C, the joints' temperatures, or None unless every sample has them
    quat : (n, 4) unit quaternions of a 6-DoF target (tracker frame), NaN where not
        measured
    sigma_deg : (n,) deg, the orientation's standard uncertainty, NaN where unknown
    tool_id : list of str or None, the tool target measured (None: the one)
    """

    point_index: np.ndarray
    q: np.ndarray
    tracker_p_smr: np.ndarray
    std_mm: np.ndarray
    n_averaged: np.ndarray
    t_s: np.ndarray
    pose_id: list[str]
    set_name: list[str]
    target: list[dict | None]
    temp_c: np.ndarray
    pressure_hpa: np.ndarray
    humidity_pct: np.ndarray
    cmd: np.ndarray
    dirs: np.ndarray | None
    attempts: np.ndarray
    joints_t: np.ndarray
    reflector: list[str | None]
    face: np.ndarray
    cov_mm2: np.ndarray
    verdict: list[str | None]
    remeasures: np.ndarray
    model_residual_mm: np.ndarray
    model_threshold_mm: np.ndarray
    joint_temp: np.ndarray | None
    quat: np.ndarray
    sigma_deg: np.ndarray
    tool_id: list[str | None]

    @classmethod
    def from_records(cls, rows: list[Sample]) -> Samples:
        """The columns of ``rows`` (in order), each stacked as its kind says."""
        return cls(**{c.name: c.kind.stack([getattr(r, c.name) for r in rows])
                      for c in RECORD})

    def __len__(self) -> int:
        return len(self.point_index)

    def sample(self, i: int) -> Sample:
        """Row ``i`` as a :class:`Sample` (what a column holds for "unknown" as None)."""
        return Sample(**{c.name: c.kind.unstack(getattr(self, c.name), i) for c in RECORD})
