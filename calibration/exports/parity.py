"""Parity checks of exported kinematics: the exported file, read back by its own reader,
against cellcal's calibrated model at random joint sets.

Every export (calibrated URDF, UR ``calibration.conf``, UR ROS kinematics YAML, DH/MDH
CSV) is read back from disk and its forward kinematics compared with the calibrated
model's: the largest distance of the tool point (mm) and, where the file carries the
orientation, the largest angle between the flange orientations (rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fit.simulate import random_joints
from ..model.kinematics import run_chain
from ..model.model_loading import load_model
from ..model.robot_model import RobotModel

#: joint sets per check, and their seed
N_JOINT_SETS = 1000
SEED = 0


@dataclass
class Parity:
    """Result of one parity check."""

    file: str
    reader: str
    n: int
    max_mm: float
    max_rad: float | None = None

    def line(self) -> str:
        rot = "" if self.max_rad is None else f", orientation {self.max_rad:.1e} rad"
        return (f"parity    {self.file}: {self.reader} vs cellcal at {self.n} random joint "
                f"sets: max {self.max_mm:.1e} mm{rot}")

    def as_dict(self) -> dict:
        return {"file": self.file, "reader": self.reader, "n": self.n,
                "max_mm": self.max_mm, "max_rad": self.max_rad}


def parity_joints(model: RobotModel, n: int = N_JOINT_SETS, seed: int = SEED) -> np.ndarray:
    """Random joint sets within the model's limits (internal units), (n, N)."""
    return random_joints(model, n, np.random.default_rng(seed))


def model_poses(model: RobotModel, q: np.ndarray,
                tcp: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(tool points (n, 3) mm, orientations (n, 3, 3)) of the model, base frame: of the
    flange, or with ``tcp`` of the tool frame (the flange turned by ``tool_rpy_deg``)."""
    r = run_chain(model.convention, model.dh_table(), q, model.tool_mm(), jacobian=False,
                  prismatic=model.prismatic_mask())
    return r.base_p_tcp, r.base_R_flange @ model.tool_R() if tcp else r.base_R_flange


def model_file_parity(path: str | Path, model: RobotModel) -> Parity:
    """A written model YAML read back by :func:`calibration.model.model_loading.load_model`."""
    q = parity_joints(model)
    max_mm, max_rad = compare(model, q, *model_poses(load_model(path), q, tcp=True), tcp=True)
    return Parity(str(path), "cellcal model YAML", len(q), max_mm, max_rad)


def compare(model: RobotModel, q: np.ndarray, points: np.ndarray,
            rotations: np.ndarray | None = None, tcp: bool = False) -> tuple[float, float | None]:
    """Largest point distance (mm) and orientation angle (rad) between the model and a
    reader's forward kinematics at joints q; ``tcp``: the rotations are the tool frame's
    (a file that carries the tool's orientation), else the flange's."""
    P, R = model_poses(model, q, tcp)
    max_mm = float(np.linalg.norm(points - P, axis=1).max())
    if rotations is None:
        return max_mm, None
    M = np.swapaxes(R, 1, 2) @ rotations
    c = np.clip((np.trace(M, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    # arccos is inaccurate near 0: use the skew part's norm there
    w = np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], 1)
    angle = np.where(c > 0.5, np.arcsin(np.clip(np.linalg.norm(w, axis=1) / 2, 0, 1)),
                     np.arccos(c))
    return max_mm, float(angle.max())
