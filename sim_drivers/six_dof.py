"""A 6-DoF target (a T-Mac) on the simulated robot's tool, and how the simulated tracker
measures it.

:class:`SixDofTarget` is the target as it really is: its frame in the flange frame
(``flange_R_target``; its origin, the reflector's centre, is the true robot's tool
point, so its position is what the tracker measures of an SMR there), its acceptance
cone about its z axis (the side that must face the tracker, ±45° for a T-Mac), the
tracker's orientation noise (σ 0.01° per axis, a T-Mac's typical figure) and the
longest distance the tracker measures 6D at. :meth:`SixDofTarget.on_tool` puts one on
the tool at a nominal orientation turned by a hidden mounting error.

:class:`SixDofMeasuring` gives :class:`~sim_drivers.cell.SimCell` its 6D measurement,
with the same honesty as for positions: the cell's line of sight uses the target's own
axis and cone (a T-Mac turned away from the tracker breaks the beam like an SMR), the
6D range is limited, and 6D is measured in face 1 only. The measured orientation is
``exp([n]x) · C · tracker_R_flange · flange_R_target``: the true flange orientation
(:meth:`~sim_drivers.model_truth.ModelTruth.true_flange_rotation`), the tracker's
two-face collimation turn ``C`` (as for positions) and a noise rotation ``n`` drawn per
axis from its own seeded generator, so a cell without a 6-DoF target draws exactly
what it drew before.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calibration.model.transforms import matrix_to_quat, rotvec_to_matrix
from sim_drivers.refusals import CellRefused

#: the simulated T-Mac: name, internal probe id, serial number
TMAC_NAME, TMAC_ID, TMAC_SERIAL = "T-Mac TMC30-F", 1, 391001


def _rotation(values) -> tuple[tuple[float, ...], ...]:
    R = np.asarray(values, float)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or (
            np.linalg.det(R) < 0):
        raise ValueError("flange_R_target must be a proper 3x3 rotation matrix")
    return tuple(tuple(float(v) for v in row) for row in R)


@dataclass(frozen=True)
class SixDofTarget:
    """A 6-DoF target as it really is on the tool (see the module docstring).

    Attributes
    ----------
    flange_R_target : 3x3 rotation (nested tuples), the target frame in the flange frame
    nominal_rotvec_deg : the orientation the user thinks it has (rotation vector, deg)
    acceptance_deg : half-angle of the cone about the target's z axis that must hold
        the tracker
    sigma_deg : the tracker's orientation noise, per axis, deg
    max_range_mm : the longest distance of a 6D measurement
    """

    flange_R_target: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    nominal_rotvec_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    acceptance_deg: float = 45.0
    sigma_deg: float = 0.01
    max_range_mm: float = 20000.0
    name: str = TMAC_NAME
    probe_id: int = TMAC_ID
    serial: int = TMAC_SERIAL

    def __post_init__(self) -> None:
        object.__setattr__(self, "flange_R_target", _rotation(self.flange_R_target))
        if not (self.sigma_deg > 0 and 0 < self.acceptance_deg <= 180):
            raise ValueError("sigma_deg must be > 0 and acceptance_deg in (0, 180]")

    @classmethod
    def on_tool(cls, rotvec_deg=(0.0, 0.0, 0.0), seed: int = 0, hidden_deg: float = 0.2,
                **kw) -> SixDofTarget:
        """A target mounted at the nominal orientation ``rotvec_deg`` (flange frame), turned
        by a hidden mounting error of ``hidden_deg`` per axis (std, seeded)."""
        nominal = rotvec_to_matrix(np.radians(np.asarray(rotvec_deg, float)))
        tilt = np.random.default_rng([seed, 0x7AC]).normal(0.0, np.radians(hidden_deg), 3)
        return cls(flange_R_target=nominal @ rotvec_to_matrix(tilt),
                   nominal_rotvec_deg=tuple(float(v) for v in rotvec_deg), **kw)

    @property
    def R(self) -> np.ndarray:
        """``flange_R_target`` as an array (3, 3)."""
        return np.array(self.flange_R_target)

    @property
    def facing_axis(self) -> np.ndarray:
        """The target's z axis in the flange frame: the side that must face the tracker."""
        return self.R[:, 2].copy()


@dataclass(frozen=True, kw_only=True)
class PoseReading:
    """One simulated 6D measurement: the position reading (a ``TrackerReading``) and the
    orientation, ``quat`` (w, x, y, z) of the target frame in the tracker frame, with the
    per-axis standard deviations ``std_deg`` and the target's name and probe id."""

    reading: object
    quat: np.ndarray
    std_deg: np.ndarray
    target: str
    probe_id: int


class SixDofMeasuring:
    """The 6D part of :class:`~sim_drivers.cell.SimCell` (uses its lock, clock, truth)."""

    six_dof: SixDofTarget | None

    def _init_six_dof(self, six_dof: SixDofTarget | None, seed: int) -> None:
        self.six_dof = six_dof
        self._pose_rng = np.random.default_rng([seed, 0x6D])

    def true_orientation(self) -> np.ndarray:
        """The 6-DoF target's true orientation now, ``tracker_R_target`` (3, 3)."""
        rotation = getattr(self.truth, "true_flange_rotation", None)
        if self.six_dof is None or rotation is None:
            raise CellRefused("NO_6DOF_TARGET", "no 6-DoF target on the tool")
        with self._lock:
            q = self._current_q(self.now())
            return np.asarray(rotation(q, self.pose_context()), float) @ self.six_dof.R

    def tracker_measure_pose(self, duration_s: float = 0.5) -> PoseReading:
        """Measure the 6-DoF target: :meth:`tracker_measure` of its reflector plus its
        orientation. Refuses (``CellRefused``) ``NO_6DOF_TARGET`` without one, ``FACE2_6D``
        in face 2, ``NO_TARGET`` beyond the 6D range, and whatever a position refuses."""
        with self._lock:
            R_true = self.true_orientation()
            if self.tracker_face != 1:
                raise CellRefused("FACE2_6D", "6-DoF targets are measured in face 1 only")
            dist = float(np.linalg.norm(self.true_point()))
            if dist > self.six_dof.max_range_mm:
                raise CellRefused("NO_TARGET", f"6-DoF target at {dist:.0f} mm, beyond the "
                                  f"6D range {self.six_dof.max_range_mm:.0f} mm")
            c = self.tracker_collimation_rad * (1 if self.tracker_face == 1 else -1)
            sigma = np.radians(self.six_dof.sigma_deg)
            noise = self._pose_rng.normal(0.0, sigma, 3)
            std = self.six_dof.sigma_deg * (1.0 + 0.05 * self._pose_rng.standard_normal(3))
        reading = self.tracker_measure(duration_s)
        R = rotvec_to_matrix(noise) @ rotvec_to_matrix(np.array([0.0, 0.0, c])) @ R_true
        return PoseReading(reading=reading, quat=matrix_to_quat(R), std_deg=std.clip(0.5 * (
            self.six_dof.sigma_deg)), target=self.six_dof.name, probe_id=self.six_dof.probe_id)
