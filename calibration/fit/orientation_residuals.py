"""Orientation residuals of a 6-DoF target, weighted by their own uncertainty.

An orientation residual is the rotation vector of ``R_meas · R_predᵀ`` (tracker frame,
rad): the small turn that takes the predicted target frame onto the measured one. Its
exact Jacobian with respect to the parameters is ``-J_r⁻¹(r) W``, W the prediction's
angular-velocity Jacobian (:mod:`calibration.model.orientation_model`) and J_r the right
Jacobian of SO(3) at the residual (``log(exp(r) exp(-w)) = r - J_r⁻¹(r) w + O(w²)``).

Positions and orientations are commensurate through their uncertainties, not through a
fixed factor: an orientation row is multiplied by ``sigma_mm / sigma_rad`` (mm per rad),
so that, divided by the tracker's position uncertainty ``sigma_mm``, every row of the
least-squares problem is a residual over its own standard uncertainty. Position rows
stay in mm, as without orientations: the cost, the residual variance and the covariance
keep their units, and data without orientations give the same numbers as before.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..model.transforms import matrices_to_rotvecs, quat_to_matrix, skew

if TYPE_CHECKING:
    from ..data.dataset import Dataset


def rotation_residuals(R_meas: np.ndarray, R_pred: np.ndarray) -> np.ndarray:
    """Rotation vectors (n, 3), rad, of ``R_meas R_predᵀ`` (both (n, 3, 3))."""
    return matrices_to_rotvecs(R_meas @ np.swapaxes(R_pred, 1, 2))


def inverse_right_jacobians(r: np.ndarray) -> np.ndarray:
    """``J_r⁻¹(r)`` of SO(3) for rotation vectors (n, 3): (n, 3, 3)."""
    th = np.linalg.norm(r, axis=1)
    K = skew(r)
    small = th < 1e-4
    t = np.where(small, 1.0, th)
    coef = np.where(small, 1.0 / 12.0,
                    1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)))
    return np.eye(3) + 0.5 * K + coef[:, None, None] * (K @ K)


def orientation_stats(residuals_rad: np.ndarray | None) -> dict:
    """The JSON keys of docs/formats.md §4 for orientation residuals (n, 3) rad: the RMS,
    mean and largest angle, deg (empty for None)."""
    if residuals_rad is None:
        return {}
    a = np.degrees(np.linalg.norm(np.atleast_2d(residuals_rad), axis=1))
    if a.size == 0:
        return {"orientation_rms_deg": None, "orientation_mean_deg": None,
                "orientation_max_deg": None}
    return {"orientation_rms_deg": float(np.sqrt(np.mean(a**2))),
            "orientation_mean_deg": float(a.mean()), "orientation_max_deg": float(a.max())}


#: starting uncertainties when the data do not give them (then estimated from residuals)
DEFAULT_SIGMA_MM = 0.01
DEFAULT_SIGMA_DEG = 0.01


@dataclass
class OrientationRows:
    """The orientation rows of one data set in a least-squares problem.

    Attributes
    ----------
    R : (n, 3, 3) measured ``tracker_R_target``
    sigma_mm : the position uncertainty per axis the rows are scaled to, mm
    sigma_rad : (n,) each orientation's uncertainty per axis, rad
    estimated : which of ``"mm"``, ``"rad"`` the data did not give (estimated from the
        residuals by :meth:`reweight`)
    """

    R: np.ndarray
    sigma_mm: float
    sigma_rad: np.ndarray
    estimated: tuple[str, ...] = ()

    @classmethod
    def of(cls, data: Dataset) -> OrientationRows:
        """The rows of ``data`` (which has ``quat``), uncertainties from the data."""
        if data.quat is None:
            raise ValueError(f"{data.source}: no orientations (quat columns)")
        s_mm = data.sigma()
        est: tuple[str, ...] = () if s_mm is not None else ("mm",)
        if data.sigma_deg is not None:
            s_rad = np.radians(np.asarray(data.sigma_deg, float))
        else:
            s_rad = np.full(data.n, np.radians(DEFAULT_SIGMA_DEG))
            est += ("rad",)
        return cls(quat_to_matrix(data.quat), s_mm or DEFAULT_SIGMA_MM, s_rad, est)

    @property
    def weight(self) -> np.ndarray:
        """(n,) mm per rad: what an orientation row is multiplied by."""
        return self.sigma_mm / self.sigma_rad

    def residual(self, R_pred: np.ndarray) -> np.ndarray:
        """Weighted residuals (n, 3), mm-equivalent."""
        return rotation_residuals(self.R, R_pred) * self.weight[:, None]

    def residual_and_jacobian(self, R_pred: np.ndarray,
                              W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Weighted residuals (n, 3) and their Jacobian d r / d x (n, 3, p)."""
        r = rotation_residuals(self.R, R_pred)
        Jr = -np.matmul(inverse_right_jacobians(r), W)
        w = self.weight
        return r * w[:, None], Jr * w[:, None, None]

    def reweight(self, position_residuals: np.ndarray, R_pred: np.ndarray) -> None:
        """Re-estimate the uncertainties the data did not give from the residuals (the
        RMS per axis of each kind: a variance-component estimate)."""
        if "mm" in self.estimated and position_residuals.size:
            self.sigma_mm = float(np.sqrt(np.mean(position_residuals**2))) or self.sigma_mm
        if "rad" in self.estimated:
            r = rotation_residuals(self.R, R_pred)
            s = float(np.sqrt(np.mean(r**2)))
            if s > 0:
                self.sigma_rad = np.full(len(r), s)
