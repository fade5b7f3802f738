"""Reader for the Jacobi UR5 laser-tracker data set in ../shared/data (tests only)."""

from __future__ import annotations

import csv

import numpy as np

from calibration import Dataset, load_model
from tests.shared_data import shared_file

FOLDER = "jacobi_ur5_lasertracker"
GRID = "3D_UR5_uncalibrated_grid_cleaned.csv"
RANDOM = "3D_UR5_uncalibrated_random_cleaned.csv"


def ur5_with_smr():
    """The nominal UR5 (CB3) with the 1.5" SMR 31 mm along the flange z axis."""
    return load_model("ur5").with_changes(tool=(0.0, 0.0, 31.0))


def load(name: str, valid: bool = False) -> tuple[Dataset, np.ndarray]:
    """(dataset, commanded targets). Measured = target - dif (the sign is undocumented;
    the other sign fits equally well)."""
    path = shared_file(FOLDER, name)
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    q = np.radians([[float(r[f"joint_{j}"]) for j in range(1, 7)] for r in rows])
    target = np.array([[float(r[c]) for c in ("x_t", "y_t", "z_t")] for r in rows])
    dif = np.array([[float(r[c]) for c in ("x_dif", "y_dif", "z_dif")] for r in rows])
    data = Dataset(q=q, tracker_p_smr=target - dif, cmd=target,
                   pose_id=[r["step_order"] for r in rows], is_valid=np.full(len(rows), valid),
                   source=str(path), lines=np.arange(2, len(rows) + 2))
    return data, target
