"""Synthetic measurements with a known truth: the basis of every physical test.

``realistic_truth`` draws hidden errors of the size real robots have;
``simulate`` measures a "true" robot with a noisy tracker; ``add_blunders`` spoils some
readings as a real tracker does now and then (see :func:`blunder_offsets`);
``warmup_temperatures`` gives the joint temperatures of a robot that works from cold.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from ..data.dataset import Dataset
from ..effects import JointEffect
from ..model.robot_model import RobotModel
from ..model.transforms import (
    matrix_to_quat,
    matrix_to_rotvec,
    random_rotation,
    rotvecs_to_matrices,
)
from .error_model import ErrorModel


def random_joints(
    model: RobotModel, n: int, rng: np.random.Generator, max_abs_deg: float = 180.0
) -> np.ndarray:
    """Joint positions uniform within the model's limits (revolute ones clipped to
    +-max_abs_deg), (n, N) rad (prismatic: internal units)."""
    lim = model.sampling_limits_rad(max_abs_deg)
    return rng.uniform(lim[:, 0], lim[:, 1], size=(n, model.n_joints))


def realistic_truth(
    error_model: ErrorModel,
    rng: np.random.Generator,
    *,
    length_mm: float = 0.3,
    angle_deg: float = 0.03,
    base_distance_mm: tuple[float, float] = (2000.0, 3000.0),
    tool_error_mm: float = 1.0,
    only: np.ndarray | None = None,
) -> np.ndarray:
    """A hidden parameter vector: geometric errors ~N(0, length_mm / angle_deg), the base
    2-3 m from the tracker in a uniformly random orientation, the tool off by ~tool_error_mm,
    other effects at their own typical sizes (``Effect.typical``, else their scales).

    ``only`` (bool mask over parameters) limits the geometric/effect errors to those
    parameters (the base and tool are always set).
    """
    x = np.zeros(error_model.n_params)
    for e, sl in zip(error_model.effects, error_model.slices, strict=True):
        if e.family == "base":
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            t = direction * rng.uniform(*base_distance_mm)
            x[sl] = np.concatenate([t, matrix_to_rotvec(random_rotation(rng))])
        elif e.family == "tool":
            x[sl] = (np.tile(e.model.tool_mm(), e.n_params // 3)  # one point per SMR nest
                     + rng.normal(0, tool_error_mm, e.n_params))
        elif e.family == "geometric":
            sig = np.where(np.array(e.units) == "rad", np.radians(angle_deg), length_mm)
            x[sl] = rng.normal(0, 1, e.n_params) * sig
        elif hasattr(e, "typical"):
            x[sl] = e.typical(rng)
        else:
            x[sl] = rng.normal(0, 1, e.n_params) * e.scales
    if only is not None:
        keep = only.copy()
        for e, sl in zip(error_model.effects, error_model.slices, strict=True):
            if e.family in ("base", "tool"):
                keep[sl] = True
        x[~keep] = 0.0
    return x


def simulate(
    error_model: ErrorModel,
    x_true: np.ndarray,
    q: np.ndarray,
    sigma_mm: float,
    rng: np.random.Generator,
    sigma_deg: float | None = None,
    **columns: Any,
) -> Dataset:
    """Measure the true robot at joints ``q`` (rad, (n, N)) with Gaussian tracker noise.

    ``columns`` are passed to :class:`Dataset` (``temp_c``, ``dirs``, ``is_valid``...); the
    result carries ``tracker_sigma_mm`` metadata so the noise floor is known. With
    ``sigma_deg`` a 6-DoF target is measured too: the true ``tracker_R_target`` turned by
    a noise rotation of ``sigma_deg`` per axis (drawn after the positions' noise), and
    the ``sigma_deg`` column.
    """
    data = Dataset(q=q, tracker_p_smr=np.zeros((len(q), 3)), source="simulated", **columns)
    P, _, R, _ = error_model.evaluate_pose(x_true, error_model.bind(data), jacobian=False)
    data.tracker_p_smr = P + rng.normal(0.0, sigma_mm, P.shape)
    if sigma_deg is not None:
        noise = rotvecs_to_matrices(rng.normal(0.0, np.radians(sigma_deg), (len(q), 3)))
        data.quat = matrix_to_quat(noise @ R)
        data.sigma_deg = np.full(len(q), float(sigma_deg))
    data.meta = {"tracker_sigma_mm": repr(float(sigma_mm)), **data.meta}
    return data


#: each joint's temperature rise (K) over the air when the robot works continuously, for a
#: six-joint arm (large base/shoulder/elbow drives warm more than the wrist's); published
#: joint temperatures of collaborative arms rise 10-20 K over their first hour of work
WARM_RISE_K = (12.0, 16.0, 14.0, 9.0, 9.0, 8.0)
#: each joint's thermal time constant (s): tens of minutes (drive, gear and link masses)
WARMUP_TAU_S = (1800.0, 2100.0, 1800.0, 1200.0, 1200.0, 1200.0)


def per_joint(values: npt.ArrayLike, n_joints: int) -> np.ndarray:
    """A six-joint default for ``n_joints`` joints (the last value repeated beyond six)."""
    v = np.asarray(values, float)
    return v[np.minimum(np.arange(n_joints), v.size - 1)]


def warmup_temperatures(t_s: np.ndarray, n_joints: int, *, ambient_c: float = 20.0,
                        start_s: float | None = 0.0, rise_k: npt.ArrayLike = WARM_RISE_K,
                        tau_s: npt.ArrayLike = WARMUP_TAU_S) -> np.ndarray:
    """Joint temperatures (°C, (n, N)) at times ``t_s`` of a robot working continuously
    since ``start_s`` from cold (first order: ambient + rise · (1 - exp(-(t - start)/τ)));
    ``start_s=None``: a robot that has long been warm (ambient + rise)."""
    t = np.asarray(t_s, float)[:, None]
    rise, tau = per_joint(rise_k, n_joints), per_joint(tau_s, n_joints)
    if start_s is None:
        return np.broadcast_to(ambient_c + rise, (t.shape[0], n_joints)).copy()
    return ambient_c + rise * (1.0 - np.exp(-np.maximum(t - start_s, 0.0) / tau))


class Bump(JointEffect):
    """A hidden local error of one joint for simulations (not a candidate family):
    Δθ_J = a · exp(-½ ((θ_J - centre) / width)²), a bump ``width_deg`` wide (one standard
    deviation) at ``centre_deg`` — a damaged stretch of gear or encoder. Parameter ``a``
    (rad); ``typical`` draws 0.1-0.3 mm at 1 m."""

    family = "bump"
    summary = "a local joint error a few degrees wide (simulation only)"

    def __init__(self, model: RobotModel, joint: int, centre_deg: float, width_deg: float) -> None:
        super().__init__(model, joint)
        self.centre, self.width = np.radians(centre_deg), np.radians(width_deg)
        self.param_names, self.units, self.scales = ["a"], ["rad"], np.array([1e-4])

    @property
    def label(self) -> str:
        return f"bump:{self.joint}@{np.degrees(self.centre):g}"

    @property
    def prefix(self) -> str:
        return f"bump.j{self.joint}@{np.degrees(self.centre):g}"

    def bind(self, data: Dataset, nominal: Any) -> np.ndarray:
        u = (data.q[:, self.joint - 1] - self.centre) / self.width
        return np.exp(-0.5 * u**2)

    def delta(self, p: np.ndarray, data: Dataset, shape: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * shape, shape[:, None]

    def typical(self, rng: np.random.Generator) -> np.ndarray:
        return np.array([rng.uniform(1e-4, 3e-4) * rng.choice([-1.0, 1.0])])


#: size of a simulated blunder, mm (uniform)
BLUNDER_MM = (0.5, 5.0)


def blunder_offsets(
    xyz: np.ndarray, rng: np.random.Generator, size_mm: tuple[float, float] = BLUNDER_MM,
    along_fraction: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Displacements of blunders at measured points ``xyz`` (tracker frame, (k, 3) mm).

    Each is ``size_mm`` long (uniform), along the line of sight from the tracker at the
    origin (a wrong return, a re-seated SMR: a range error, either sign) with probability
    ``along_fraction``, else in a uniformly random direction (the robot not yet still,
    the beam clipped). Returns (offsets (k, 3) mm, along_beam (k,) bool).
    """
    xyz = np.atleast_2d(np.asarray(xyz, float))
    k: int = xyz.shape[0]
    along = rng.random(k) < along_fraction
    size = rng.uniform(size_mm[0], size_mm[1], k)
    random_dir = rng.normal(size=(k, 3))
    random_dir /= np.linalg.norm(random_dir, axis=1, keepdims=True)
    beam = xyz / np.maximum(np.linalg.norm(xyz, axis=1, keepdims=True), 1e-300)
    sign = np.where(rng.random(k) < 0.5, -1.0, 1.0)[:, None]
    direction = np.where(along[:, None], sign * beam, random_dir)
    return direction * size[:, None], along


@dataclass
class BlunderTruth:
    """Which readings :func:`add_blunders` spoiled and how."""

    index: np.ndarray  # (k,) rows of the data set
    pose_id: list[str]
    offset_mm: np.ndarray  # (k, 3) displacement added to the reading
    along_beam: np.ndarray  # (k,) bool

    def to_json(self) -> list[dict]:
        return [{"pose_id": p, "offset_mm": [float(v) for v in o],
                 "size_mm": float(np.linalg.norm(o)), "along_beam": bool(a)}
                for p, o, a in zip(self.pose_id, self.offset_mm, self.along_beam, strict=True)]


def add_blunders(
    data: Dataset, rate: float, rng: np.random.Generator, *,
    rows: np.ndarray | None = None, size_mm: tuple[float, float] = BLUNDER_MM,
    along_fraction: float = 0.5,
) -> tuple[Dataset, BlunderTruth]:
    """A copy of ``data`` in which each reading is, with probability ``rate``, a blunder
    (see :func:`blunder_offsets`); ``rows`` (bool (n,)) limits them to those rows (e.g.
    the calibration rows, to keep a clean validation set). Returns (data, truth)."""
    if not 0.0 <= rate <= 1.0:
        raise ValueError(f"blunder rate must be in [0, 1], not {rate}")
    hit = rng.random(data.n) < rate
    if rows is not None:
        hit &= np.asarray(rows, bool)
    idx = np.flatnonzero(hit)
    offsets, along = blunder_offsets(data.tracker_p_smr[idx], rng, size_mm, along_fraction)
    xyz = data.tracker_p_smr.copy()
    xyz[idx] += offsets
    truth = BlunderTruth(idx, [data.pose_id[i] for i in idx], offsets, along)
    return replace(data, tracker_p_smr=xyz), truth
